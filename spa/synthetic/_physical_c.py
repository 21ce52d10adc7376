"""The physical test plant in C (``physical_plant.c``), and an exported controller closed on
it: :func:`close_loop_in_c` compiles a ``controller.h`` of :mod:`spa.closedloop.export` with
the plant and runs a set-point staircase; :func:`measure_staircase` measures the run as spa
measures its closed-loop staircases (:mod:`spa.closedloop.metrics`).

Re-exported by :mod:`spa.synthetic.physical`, where the plant lives.
"""

from __future__ import annotations

import math
import re
import subprocess
import tempfile
from collections.abc import Mapping, Sequence
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt
import pandas as pd

__all__ = [
    "c_plant_source",
    "close_loop_in_c",
    "header_setting",
    "measure_staircase",
    "run_plant_in_c",
]

#: Flags every compilation uses: ISO C, no fused multiply-add (the Python kernels have none).
CFLAGS = ("-std=c99", "-O2", "-ffp-contract=off", "-Wall", "-Wextra", "-Wno-unused-function")


def c_plant_source() -> tuple[Path, Path]:
    """The C twin's source and header, shipped with the package.

    Returns
    -------
    source, header : pathlib.Path
        ``physical_plant.c`` and ``physical_plant.h``.

    Examples
    --------
    >>> [p.name for p in c_plant_source()]
    ['physical_plant.c', 'physical_plant.h']
    """
    root = Path(str(resources.files("spa.synthetic")))
    return root / "physical_plant.c", root / "physical_plant.h"


def _build(folder: Path, main: str, cc: str, include: Sequence[Path] = ()) -> Path:
    """Compile ``main`` (source text) with the plant into ``folder/harness``."""
    from spa._cc import build_c

    source, header = c_plant_source()
    src = folder / "harness.c"
    src.write_text(main, encoding="utf-8")
    return build_c(
        [src, source],
        folder / "harness",
        flags=CFLAGS,
        includes=[header.parent, *include],
        cc=cc,
        what="compiling the C harness",
    )


def _constants_line(plant: Any, dt: float) -> str:
    from spa.synthetic._physical_core import _constants, substeps

    return " ".join(repr(float(v)) for v in _constants(plant)) + f" {substeps(plant, dt)}"


_OPEN = r"""#include <stdio.h>
#include "physical_plant.h"
static spa_phys_state s;
int main(void)
{
    long n, k;
    int i, nsub, u;
    double dt, p0, c[SPA_PHYS_N_CONST];
    if (scanf("%ld %lf %lf", &n, &dt, &p0) != 3) return 2;
    for (i = 0; i < SPA_PHYS_N_CONST; ++i) {
        if (scanf("%lf", &c[i]) != 1) return 2;
    }
    if (scanf("%d", &nsub) != 1) return 2;
    for (k = 0; k < n; ++k) {
        if (scanf("%d", &u) != 1) return 2;
        if (k == 0) spa_phys_init(&s, c, dt, nsub, p0, u);
        printf("%.17g %.17g\n", spa_phys_pressure(&s), spa_phys_lagged(&s));
        if (spa_phys_step(&s, u) != 0) return 3;
    }
    return 0;
}
"""


def run_plant_in_c(
    plant: Any, valve: npt.ArrayLike, dt: float, *, p0: float = 0.0, cc: str = "cc"
) -> tuple[np.ndarray, np.ndarray]:
    """Drive the C twin with a valve command: the chamber's and the sensor's lagged gauge
    pressure (bar) at every controller step, as ``simulate_physical``'s ``attrs``.

    Raises
    ------
    FileNotFoundError
        If the compiler ``cc`` is not on PATH.
    """
    from spa.synthetic._physical_core import _check_dt

    dt = _check_dt(plant, dt)
    u = np.asarray(valve).astype(np.int8)
    head = f"{u.size} {dt!r} {float(p0) * 1e5!r} {_constants_line(plant, dt)}\n"
    with tempfile.TemporaryDirectory(prefix="spa-plant-") as tmp:
        exe = _build(Path(tmp), _OPEN, cc)
        out = subprocess.run(
            [str(exe)],
            input=head + "\n".join(str(int(v)) for v in u) + "\n",
            capture_output=True,
            text=True,
            check=True,
        ).stdout
    data = np.loadtxt(out.splitlines(), ndmin=2)
    return data[:, 0] / 1e5, data[:, 1] / 1e5


_LOOP = r"""#include <math.h>
#include <stdio.h>
#include "%(header)s"
#include "physical_plant.h"
static spa_phys_state s;
int main(void)
{
    long n, k;
    int i, nsub;
    double dt, p0, i0, quantum, mains, freq, phase, c[SPA_PHYS_N_CONST], r, noise, y, t;
    %(p)s_state ctrl;
    %(p)s_output o;
    if (scanf("%%ld %%lf %%lf %%lf %%lf %%lf %%lf %%lf", &n, &dt, &p0, &i0, &quantum, &mains,
              &freq, &phase) != 8) return 2;
    for (i = 0; i < SPA_PHYS_N_CONST; ++i) {
        if (scanf("%%lf", &c[i]) != 1) return 2;
    }
    if (scanf("%%d", &nsub) != 1) return 2;
    spa_phys_init(&s, c, dt, nsub, p0, 0);
    %(p)s_init(&ctrl, i0);
    for (k = 0; k < n; ++k) {
        if (scanf("%%lf %%lf", &r, &noise) != 2) return 2;
        t = k * dt;
        y = spa_phys_lagged(&s) / 1e5;
        if (mains > 0.0) y = y + mains * sin(2.0 * %(pi)s * freq * t + phase);
        y = y + noise;
        if (quantum > 0.0) y = rint(y / quantum) * quantum;
        o = %(p)s_step(&ctrl, r, y);
        printf("%%d %%.17g %%.17g %%.17g\n", o.valve, o.xi, y, spa_phys_pressure(&s) / 1e5);
        if (spa_phys_step(&s, o.valve) != 0) return 3;
    }
    return 0;
}
"""


def _header_prefix(text: str) -> tuple[str, float]:
    """The prefix and the step ``dt`` of an exported controller header."""
    m = re.search(r"static\s+(?:inline\s+)?(\w+)_output\s+(\w+)_step\s*\(", text)
    if m is None or m.group(1) != m.group(2):
        raise ValueError("not a spa controller header: no '<prefix>_output <prefix>_step(' in it")
    prefix = m.group(1)
    d = re.search(rf"#define\s+{prefix.upper()}_DT\s+(\S+)", text)
    if d is None:
        raise ValueError(f"controller header: no {prefix.upper()}_DT")
    return prefix, float(d.group(1))


def header_setting(header_path: str | Path) -> dict[str, Any]:
    """The modulator setting an exported header records (its ``Setting:`` comment line).

    With :func:`spa.closedloop.experiments.cycle_period` it gives the window
    :func:`measure_staircase` needs, e.g. ``1/f_w`` for PWM.

    Raises
    ------
    ValueError
        If the header has no readable ``Setting:`` line.
    """
    import ast

    text = Path(header_path).read_text(encoding="utf-8")
    m = re.search(r"^\s*\*\s*Setting:\s*(\{.*\})\s*$", text, flags=re.MULTILINE)
    if m is None:
        raise ValueError(f"{header_path}: no 'Setting: {{...}}' line in its comment")
    try:
        setting = ast.literal_eval(m.group(1))
    except (ValueError, SyntaxError):
        raise ValueError(f"{header_path}: unreadable setting {m.group(1)!r}") from None
    if not isinstance(setting, dict) or "type" not in setting:
        raise ValueError(f"{header_path}: the setting {setting!r} has no type")
    return setting


def close_loop_in_c(
    header_path: str | Path,
    plant: Any,
    setpoints: Sequence[float],
    hold: float,
    dt: float | None = None,
    *,
    lead: float = 0.0,
    integral0: float = 0.0,
    rng: np.random.Generator | None = None,
    cc: str = "cc",
) -> pd.DataFrame:
    """Close an exported controller header on the physical plant in C over a staircase.

    The set-points go up through ``setpoints`` and back down (each held ``hold`` s, as
    :func:`spa.closedloop.experiments.staircase_reference`), from rest at 0 bar with the
    exhaust open, after ``lead`` s at the first set-point (to start the staircase settled,
    as spa's closed-loop stage does: measure with ``measure_staircase(run, period,
    skip=lead, r_initial=setpoints[0])``). Every controller step ``k``: the sensor is read
    at ``t_k`` (the lagged pressure, the mains pickup, noise from ``rng``, the ADC step),
    ``<prefix>_step`` gives the command, the plant integrates over the step with it.

    Parameters
    ----------
    header_path : str or pathlib.Path
        A header of :func:`spa.closedloop.export.write_controller` (any prefix).
    plant : PhysicalPlant
        The plant.
    setpoints : sequence of float
        The staircase's levels, bar gauge (at least one).
    hold : float
        Seconds at each level.
    lead : float, default 0
        Seconds at the first level before the staircase (its time stamps start at 0 s).
    dt : float, optional
        Controller step, s; must equal the header's ``<PREFIX>_DT`` (its value by default).
    integral0 : float, default 0
        The controller's integrator at start (``<prefix>_init``).
    rng : numpy.random.Generator, optional
        Sensor noise (``plant.noise``); None: none.
    cc : str, default "cc"
        The C compiler.

    Returns
    -------
    pandas.DataFrame
        ``t`` (s), ``r`` (bar), ``p`` (bar gauge, what the controller read), ``valve``
        (int8), ``u`` (the controller's ``xi``) and ``p_true`` (the chamber's gauge pressure,
        bar), one row per controller step.

    Raises
    ------
    FileNotFoundError
        If the header or the compiler is missing.
    ValueError
        For a header that is not spa's, a ``dt`` that is not the header's, or bad levels.
    RuntimeError
        If compiling fails.
    """
    from spa.closedloop.experiments import staircase_reference
    from spa.synthetic._physical_core import _check_dt

    header = Path(header_path)
    if not header.is_file():
        raise FileNotFoundError(f"controller header {header} does not exist")
    prefix, header_dt = _header_prefix(header.read_text(encoding="utf-8"))
    dt = header_dt if dt is None else float(dt)
    if not math.isclose(dt, header_dt, rel_tol=1e-12):
        raise ValueError(f"dt = {dt:g} s but {header.name} steps every {header_dt:g} s")
    dt = _check_dt(plant, dt)
    levels = [float(v) for v in setpoints]
    if not levels or not all(math.isfinite(v) and v >= 0 for v in levels):
        raise ValueError(f"setpoints: finite levels >= 0 bar, got {list(setpoints)}")
    if not (math.isfinite(hold) and hold >= 2 * dt):
        raise ValueError(f"hold = {hold!r} s: at least two controller steps")
    if not (math.isfinite(lead) and lead >= 0):
        raise ValueError(f"lead = {lead!r} s: finite and >= 0")
    first = np.full(round(lead / dt), levels[0])
    r = np.concatenate([first, staircase_reference(levels, float(hold), dt)])
    n = r.size
    noise = (
        rng.normal(0.0, plant.noise, n) if (rng is not None and plant.noise > 0) else np.zeros(n)
    )
    head = (
        f"{n} {dt!r} 0.0 {float(integral0)!r} {plant.quantum!r} {plant.mains!r} "
        f"{plant.mains_frequency!r} {plant.mains_phase!r} {_constants_line(plant, dt)}\n"
    )
    body = "\n".join(f"{a!r} {b!r}" for a, b in zip(r.tolist(), noise.tolist(), strict=True))
    main = _LOOP % {"header": header.name, "p": prefix, "pi": repr(math.pi)}
    with tempfile.TemporaryDirectory(prefix="spa-loop-") as tmp:
        exe = _build(Path(tmp), main, cc, include=[header.resolve().parent])
        res = subprocess.run(
            [str(exe)], input=head + body + "\n", capture_output=True, text=True, check=False
        )
    if res.returncode != 0:
        raise RuntimeError(f"the closed-loop harness failed (exit {res.returncode}): {res.stderr}")
    data = np.loadtxt(res.stdout.splitlines(), ndmin=2)
    return pd.DataFrame(
        {
            "t": np.arange(n) * dt,
            "r": r,
            "p": data[:, 2],
            "valve": data[:, 0].astype(np.int8),
            "u": data[:, 1],
            "p_true": data[:, 3],
        }
    )


def measure_staircase(
    run: pd.DataFrame,
    period: float | Mapping[float, float],
    *,
    column: str = "p",
    r_initial: float = 0.0,
    skip: float = 0.0,
) -> tuple[pd.DataFrame, dict[str, float]]:
    """Measure a closed-loop staircase as spa measures its own (:mod:`spa.closedloop.metrics`).

    Parameters
    ----------
    run : pandas.DataFrame
        ``t``, ``r``, ``valve`` and the pressure ``column`` (bar): a :func:`close_loop_in_c`
        run, or a bench recording.
    period : float or mapping
        Window of the cycle-mean pressure, s: the modulator's pulse period, or
        ``set-point -> window`` (:func:`spa.closedloop.experiments.step_periods`, as spa
        measures its own staircases).
    column : str, default "p"
        Which pressure: ``p`` (what the sensor logged) or ``p_true``.
    r_initial : float, default 0
        The pressure before the first step (0: from rest).
    skip : float, default 0
        Seconds left out at the start (a ``lead`` of :func:`close_loop_in_c`).

    Returns
    -------
    steps : pandas.DataFrame
        :func:`spa.closedloop.metrics.step_metrics` of every step: overshoot (%), rise and
        settling time (s, NaN when not within 2 % by the end of the step), steady-state
        error and ripple over the last quarter of each step (bar), ...
    summary : dict
        ``worst_overshoot`` (%), ``unsettled`` (steps whose cycle-mean is outside 2 % of the
        step at its end), ``worst_error`` (largest ``|steady-state error|`` in % of its
        step), ``worst_ripple_pp`` (bar), ``worst_settling_time`` (s, of the settled steps;
        0 when none), ``steps``.
    """
    from spa.closedloop.metrics import step_metrics

    if column not in run:
        raise ValueError(f"run has no column {column!r}")
    table = run[["t", "r", "valve"]].assign(p=run[column].to_numpy(np.float64))
    table = table[table["t"] >= table["t"].iloc[0] + skip - 1e-12].reset_index(drop=True)
    steps = step_metrics(table, period, r_initial=r_initial)
    size = (steps["r1"] - steps["r0"]).abs()
    err = 100.0 * steps["steady_state_error"].abs() / size
    settled = steps["settling_time"].dropna()
    summary = {
        "steps": len(steps),
        "worst_overshoot": float(steps["overshoot"].max()) if len(steps) else 0.0,
        "unsettled": int(steps["settling_time"].isna().sum()),
        "worst_error": float(err.max()) if len(steps) else 0.0,
        "worst_ripple_pp": float(steps["ripple_pp"].max()) if len(steps) else 0.0,
        "worst_settling_time": float(settled.max()) if len(settled) else 0.0,
    }
    return steps, summary
