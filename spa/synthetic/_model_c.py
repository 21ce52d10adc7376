"""spa's model plant in C (``model_plant.c``): :func:`spa.simulate` of a valve, stepped one
controller tick at a time, so that a C program can close a loop on the model the way
:mod:`spa.synthetic._physical_c` closes one on the physical plant (the plan's player,
:func:`spa.plan.host.play_on_model`).

The paper's laws only: a valve with its own laws (``ValveParams(laws=...)``) is refused
(:func:`model_constants` says so), as its time maps are not in C.
"""

from __future__ import annotations

import subprocess
import tempfile
from importlib import resources
from pathlib import Path

import numpy as np
import numpy.typing as npt

from spa._cc import build_c
from spa.model.params import ValveParams

__all__ = ["MODEL_CFLAGS", "model_constants", "model_plant_source", "run_model_in_c"]

#: The flags the model twin builds under: strict ISO C, no fused multiply-add.
MODEL_CFLAGS = (
    "-std=c99", "-Wall", "-Wextra", "-pedantic", "-Werror", "-O2", "-ffp-contract=off",
)  # fmt: skip


def model_plant_source() -> tuple[Path, Path]:
    """The model twin's source and header, shipped with the package.

    Examples
    --------
    >>> [p.name for p in model_plant_source()]
    ['model_plant.c', 'model_plant.h']
    """
    root = Path(str(resources.files("spa.synthetic")))
    return root / "model_plant.c", root / "model_plant.h"


def model_constants(params: ValveParams) -> list[float]:
    """The twin's constants of a valve: ``c1, k2, tau2, t_on, t_off`` and its delay
    convention (0 hold, 1 transport).

    Raises
    ------
    TypeError
        If ``params`` is not a ValveParams.
    ValueError
        If the valve carries its own laws: the C twin steps the paper's two laws only.

    Examples
    --------
    >>> model_constants(ValveParams(delay="transport"))
    [0.533, 0.837, 0.826, 0.003, 0.01, 1.0]
    """
    if not isinstance(params, ValveParams):
        raise TypeError(f"the model's C twin needs a ValveParams, got {type(params).__name__}")
    if params.laws is not None:
        raise ValueError(
            "the model's C twin steps the paper's two laws only (Eqs. 1-2): this valve carries "
            "its own laws (ValveParams.laws), whose time maps are not in C; play it on "
            "spa.simulate (spa.plan.host.play_session, open-loop runs only) or drop its laws"
        )
    fields = (params.c1, params.k2, params.tau2, params.t_on, params.t_off)
    return [float(v) for v in fields] + [1.0 if params.delay == "transport" else 0.0]


_OPEN = r"""#include <stdio.h>
#include "model_plant.h"
static spa_model_state s;
int main(void)
{
    long n, k;
    int i, u;
    double dt, p0, c[SPA_MODEL_N_CONST];
    if (scanf("%ld %lf %lf", &n, &dt, &p0) != 3) return 2;
    for (i = 0; i < SPA_MODEL_N_CONST; ++i) {
        if (scanf("%lf", &c[i]) != 1) return 2;
    }
    for (k = 0; k < n; ++k) {
        if (scanf("%d", &u) != 1) return 2;
        if (k == 0) spa_model_init(&s, c, dt, p0, u);
        printf("%.17g\n", spa_model_pressure(&s));
        if (spa_model_step(&s, u) != 0) return 3;
    }
    return 0;
}
"""


def run_model_in_c(
    params: ValveParams, valve: npt.ArrayLike, dt: float, *, p0: float = 0.0, cc: str = "cc"
) -> npt.NDArray[np.float64]:
    """Drive the model twin with a valve command: the pressure (bar) at every controller
    step, as ``spa.simulate(valve, dt, params, p0)`` (the valve settled at ``valve[0]``).

    Raises
    ------
    FileNotFoundError
        If the compiler ``cc`` is not on PATH.
    ValueError
        For a valve with its own laws (:func:`model_constants`).
    RuntimeError
        If the build or the run fails.
    """
    consts = model_constants(params)
    u = np.asarray(valve).astype(np.int8)
    source, header = model_plant_source()
    head = f"{u.size} {float(dt)!r} {float(p0)!r} " + " ".join(map(repr, consts)) + "\n"
    with tempfile.TemporaryDirectory(prefix="spa-model-") as tmp:
        main = Path(tmp) / "open.c"
        main.write_text(_OPEN, encoding="utf-8")
        exe = build_c(
            [main, source],
            Path(tmp) / "open",
            flags=MODEL_CFLAGS,
            includes=[header.parent],
            cc=cc,
            what="building the model twin",
        )
        res = subprocess.run(
            [str(exe)],
            input=head + "\n".join(str(int(v)) for v in u) + "\n",
            capture_output=True,
            text=True,
            check=False,
        )
    if res.returncode != 0:
        raise RuntimeError(f"the model twin failed (exit {res.returncode}): {res.stderr}")
    return np.loadtxt(res.stdout.splitlines(), ndmin=1, dtype=np.float64)
