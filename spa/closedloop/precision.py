"""How far the single-precision header's loop is from the double-precision one's.

:func:`closed_loops` compiles both headers of one controller
(:func:`spa.closedloop.export.controller_header`, ``precision="double"`` and ``"single"``)
with the system C compiler into one harness that closes each on the model's plant, written
in C as the closed forms of docs/model.md (the hold convention of
:func:`spa.model.plant.simulate`: a run of the valve starts ``t_on``/``t_off`` after its edge
and follows Eq. (1)'s exact segment), drives both with the same set-points and compares the
valve commands and pressures step by step; :func:`precision_agreement` summarises the
comparison. The double loop is the simulation's to 1e-12
(tests/test_export.py); the difference is the single header's rounding alone.
"""

from __future__ import annotations

import shutil
import subprocess
import tempfile
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

from spa.closedloop.controller import PIController
from spa.closedloop.export import c_double, controller_header
from spa.model.params import ValveParams

__all__ = ["PrecisionAgreement", "closed_loops", "precision_agreement"]

_HARNESS = r"""
#include <stdio.h>
#include <stdlib.h>
#include <math.h>
#include "ctrl_double.h"
#include "ctrl_single.h"

#define C1 %(c1)s
#define K2 %(k2)s
#define TAU2 %(tau2)s
#define T_ON %(t_on)s
#define T_OFF %(t_off)s
#define DT %(dt)s
#define P0 %(p0)s

static double seg(int on, double ps, double el)
{
    double e = el > 0.0 ? el : 0.0, root;
    if (on) {
        return exp(-e / TAU2) * (ps - K2) + K2;
    }
    root = sqrt(ps) - e / (2.0 * C1);
    root = root > 0.0 ? root : 0.0;
    return root * root;
}

typedef struct {
    long start;
    int level;
    double ps, hold, p;
} plant;

/* The pressure at step k, then the command u of step k applied. */
static double plant_read(plant *q, long k)
{
    if (k > 0) {
        q->p = seg(q->level == 1, q->ps, (double)k * DT - ((double)q->start * DT + q->hold));
    }
    return q->p;
}

static void plant_apply(plant *q, long k, int u)
{
    if (k == 0) {
        q->level = u;
    } else if (u != q->level) {
        double active = (double)(k - q->start) * DT - q->hold;
        q->ps = seg(q->level == 1, q->ps, active > 0.0 ? active : 0.0);
        q->level = u;
        q->start = k;
        q->hold = u == 1 ? T_ON : T_OFF;
    }
}

int main(void)
{
    long n, k;
    double r;
    plant a = {0, 0, P0, 0.0, P0}, b = {0, 0, P0, 0.0, P0};
    dbl_state sa;
    sgl_state sb;
    dbl_output oa;
    sgl_output ob;
    if (scanf("%%ld", &n) != 1) {
        return 2;
    }
    dbl_init(&sa, 0.0);
    sgl_init(&sb, 0.0f);
    for (k = 0; k < n; ++k) {
        if (scanf("%%lf", &r) != 1) {
            return 2;
        }
        oa = dbl_step(&sa, r, plant_read(&a, k));
        ob = sgl_step(&sb, (float)r, (float)plant_read(&b, k));
        plant_apply(&a, k, oa.valve);
        plant_apply(&b, k, ob.valve);
        printf("%%d %%d %%.17g %%.17g %%.17g %%.9g\n", oa.valve, ob.valve, a.p, b.p, oa.xi,
               (double)ob.xi);
    }
    return 0;
}
"""


@dataclass(frozen=True)
class PrecisionAgreement:
    """The single-precision loop against the double-precision one over one reference.

    Attributes
    ----------
    steps : int
        Controller steps compared.
    mismatches : int
        Steps at which the two headers' valve commands differ.
    max_pressure_difference : float
        Largest ``|p_single - p_double|`` over the run, bar.
    max_xi_difference : float
        Largest ``|xi_single - xi_double|``, input fraction.
    """

    steps: int
    mismatches: int
    max_pressure_difference: float
    max_xi_difference: float

    def to_dict(self) -> dict[str, Any]:
        """Plain numbers (YAML/JSON-ready): the fields, in order."""
        return asdict(self)


def closed_loops(
    modulator: Any,
    controller: PIController,
    params: ValveParams,
    reference: np.ndarray,
    dt: float,
    *,
    p0: float = 0.0,
    cc: str | None = None,
) -> np.ndarray:
    """Close both precisions' headers on the model's plant and run them step by step.

    Parameters
    ----------
    modulator : Modulator or mapping
        The setting.
    controller : PIController
        The designed PI.
    params : ValveParams
        The valve the loops are closed on (in C, the closed forms of its five constants;
        the headers take its laws where the modulator reads them).
    reference : numpy.ndarray
        The set-point at every controller step, bar (e.g.
        :func:`spa.closedloop.experiments.staircase_reference`).
    dt : float
        The controller step, s.
    p0 : float, optional
        The starting pressure, bar.
    cc : str, optional
        The C compiler (default ``cc`` on the PATH).

    Returns
    -------
    numpy.ndarray
        Shape ``(n, 6)``: the valve command of the double and single header, the pressure
        of each loop (bar, read before the step's command) and the ``xi`` of each.

    Raises
    ------
    RuntimeError
        When no C compiler is found or the harness does not compile or run.
    """
    compiler = cc or shutil.which("cc")
    if compiler is None:
        raise RuntimeError("precision_agreement: no C compiler (`cc` is not on the PATH)")
    r = np.asarray(reference, dtype=np.float64)
    with tempfile.TemporaryDirectory(prefix="spa-precision-") as tmp:
        folder = Path(tmp)
        for prefix, precision in (("dbl", "double"), ("sgl", "single")):
            text = controller_header(
                modulator, controller, dt, prefix=prefix, precision=precision, params=params
            )
            (folder / f"ctrl_{precision}.h").write_text(text, encoding="utf-8")
        consts = {
            "c1": params.c1,
            "k2": params.k2,
            "tau2": params.tau2,
            "t_on": params.t_on,
            "t_off": params.t_off,
            "dt": dt,
            "p0": p0,
        }
        src = folder / "harness.c"
        src.write_text(_HARNESS % {k: c_double(v) for k, v in consts.items()}, encoding="utf-8")
        exe = folder / "harness"
        cmd = [compiler, "-std=c99", "-O2", "-Wall", "-Wextra", "-pedantic", "-Werror",
               str(src), "-o", str(exe), "-lm"]  # fmt: skip
        built = subprocess.run(cmd, capture_output=True, text=True, check=False)
        if built.returncode != 0:
            raise RuntimeError(
                f"precision_agreement: the harness does not compile:\n{built.stderr}"
            )
        body = f"{r.size}\n" + "\n".join(repr(float(v)) for v in r) + "\n"
        ran = subprocess.run([str(exe)], input=body, capture_output=True, text=True, check=False)
        if ran.returncode != 0:
            raise RuntimeError(f"precision_agreement: the harness failed: {ran.stderr}")
    return np.loadtxt(ran.stdout.splitlines(), ndmin=2)


def precision_agreement(loops: np.ndarray) -> PrecisionAgreement:
    """How far the single-precision loop is from the double-precision one.

    Parameters
    ----------
    loops : numpy.ndarray
        :func:`closed_loops`' run, shape ``(n, 6)``.

    Returns
    -------
    PrecisionAgreement

    Examples
    --------
    >>> out = np.array([[1, 1, 0.0, 0.0, 0.5, 0.5], [0, 1, 0.5, 0.25, 0.75, 0.25]])
    >>> precision_agreement(out).to_dict()
    {'steps': 2, 'mismatches': 1, 'max_pressure_difference': 0.25, 'max_xi_difference': 0.5}
    """
    return PrecisionAgreement(
        steps=int(loops.shape[0]),
        mismatches=int(np.count_nonzero(loops[:, 0] != loops[:, 1])),
        max_pressure_difference=float(np.max(np.abs(loops[:, 3] - loops[:, 2]))),
        max_xi_difference=float(np.max(np.abs(loops[:, 5] - loops[:, 4]))),
    )
