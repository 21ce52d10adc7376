"""A verification session: the runs that test what spa predicted for a dataset, and the
page that puts each prediction beside its measurement.

:func:`design_verification` plans, on the identified valve, the recommended setting's
staircases and sine (with the identification runs at the start and end as a drift check).
:func:`staircase_predictions` predicts each level's pressure and the staircase's FIT with a
95 % band: the planned command (open loop: the same on any plant) simulated at every corner
of the identification's 95 % box, widened by the sensor noise on the level's mean.
:func:`compare` measures a recorded staircase the same way and says, for each prediction,
"kept" (inside its band) or "broken by ..." with the amount.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Mapping
from typing import Any

import numpy as np
import numpy.typing as npt
import pandas as pd

from spa.model.modulators import Modulator
from spa.model.params import ValveParams
from spa.plan.design import SessionDesign, design_session
from spa.plan.limits import Limits
from spa.plan.session import PlannedRun, run_commands, run_xi

__all__ = [
    "compare",
    "corners",
    "design_verification",
    "level_means",
    "staircase_predictions",
    "verdict",
    "verification_page",
]

_NAMES = ("c1", "k2", "tau2", "t_on", "t_off")


def design_verification(
    params: ValveParams,
    recommended: Modulator,
    limits: Limits,
    *,
    dt: float = 0.002,
    levels: int = 11,
    replicates: int = 3,
    seed: int = 0,
) -> SessionDesign:
    """The verification session: the recommended setting only, on the identified valve."""
    return design_session(
        params,
        limits,
        dt=dt,
        levels=levels,
        replicates=replicates,
        seed=seed,
        settings=[],
        recommended=recommended.bind(params),
        precondition=1,
        margin=1.0,
    )


def corners(params: ValveParams, intervals: Mapping[str, tuple[float, float]]) -> list[ValveParams]:
    """The valve at every corner of the 95 % box (parameters without an interval keep
    their value)."""
    axes = [
        sorted({float(intervals[n][0]), float(intervals[n][1])})
        if n in intervals
        else [float(getattr(params, n))]
        for n in _NAMES
    ]
    return [
        ValveParams(**dict(zip(_NAMES, combo, strict=True)), delay=params.delay)
        for combo in itertools.product(*axes)
    ]


def level_means(
    t: npt.ArrayLike, p: npt.ArrayLike, hold: float, n_levels: int
) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.int64]]:
    """The mean pressure over the second half of each level (``hold`` s each), and the
    samples each mean is over."""
    t = np.asarray(t, dtype=np.float64)
    p = np.asarray(p, dtype=np.float64)
    means, counts = [], []
    for i in range(n_levels):
        inside = (t >= (i + 0.5) * hold - 1e-9) & (t < (i + 1) * hold - 1e-9)
        counts.append(int(inside.sum()))
        means.append(float(p[inside].mean()) if inside.any() else math.nan)
    return np.asarray(means), np.asarray(counts)


def _fit(xi: np.ndarray, p: np.ndarray) -> float:
    from spa.openloop.levels import linear_fit_metrics

    return float(linear_fit_metrics(xi, p)["fit"])


def staircase_predictions(
    run: PlannedRun,
    dt: float,
    params: ValveParams,
    intervals: Mapping[str, tuple[float, float]],
    noise: float,
    quantum: float,
) -> dict[str, Any]:
    """Each level's predicted pressure and the FIT, with 95 % bands.

    Returns
    -------
    dict
        ``xi`` (levels), ``hold`` (s), ``p`` (predicted on the identified valve),
        ``lo``/``hi`` (the band: over the box's corners, widened by ``1.96 noise/sqrt(n)``
        and half the ADC step), and ``fit`` with ``fit_lo``/``fit_hi``.
    """
    from spa import simulate

    seg = run.segments[0]
    hold_ticks = int(seg.c)
    n = run.ticks // hold_ticks
    xi = run_xi(run)
    assert xi is not None
    levels = xi[::hold_ticks][:n]
    u = run_commands(run, dt)
    t = np.arange(u.size) * dt
    hold = hold_ticks * dt
    nominal, count = level_means(t, simulate(u, dt, params), hold, n)
    box = np.array(
        [level_means(t, simulate(u, dt, c), hold, n)[0] for c in corners(params, intervals)]
    )
    widen = 1.96 * noise / np.sqrt(np.maximum(count, 1)) + 0.5 * quantum
    fits = [_fit(levels, row) for row in box] + [_fit(levels, nominal)]
    return {
        "xi": levels.tolist(),
        "hold": hold,
        "p": nominal.tolist(),
        "lo": (box.min(axis=0) - widen).tolist(),
        "hi": (box.max(axis=0) + widen).tolist(),
        "fit": _fit(levels, nominal),
        "fit_lo": min(fits) - 0.5,
        "fit_hi": max(fits) + 0.5,
    }


def verdict(measured: float, lo: float, hi: float, unit: str, scale: float = 1.0) -> str:
    """``kept`` when ``measured`` lies in ``[lo, hi]``, else ``broken by <amount> <unit>``.

    Examples
    --------
    >>> verdict(0.5, 0.4, 0.6, "bar"), verdict(0.7, 0.4, 0.6, "mbar", 1e3)
    ('kept', 'broken by +100 mbar')
    """
    if not math.isfinite(measured):
        return "not measured"
    if lo <= measured <= hi:
        return "kept"
    off = measured - hi if measured > hi else measured - lo
    return f"broken by {off * scale:+.3g} {unit}"


def compare(prediction: Mapping[str, Any], run: pd.DataFrame) -> pd.DataFrame:
    """A recorded staircase (``t`` s, ``p`` bar) against its prediction: one row per level
    and one for the FIT, each ``kept`` or ``broken by ...``."""
    xi = np.asarray(prediction["xi"])
    means, _ = level_means(run["t"], run["p"], float(prediction["hold"]), xi.size)
    rows = []
    for i, x in enumerate(xi):
        lo, hi = prediction["lo"][i], prediction["hi"][i]
        rows.append(
            {
                "prediction": f"level xi = {x:.2f}",
                "predicted": prediction["p"][i],
                "band": f"{lo:.4g} to {hi:.4g} bar",
                "measured": means[i],
                "verdict": verdict(means[i], lo, hi, "mbar", 1e3),
            }
        )
    fit = _fit(xi, means) if np.isfinite(means).all() else math.nan
    rows.append(
        {
            "prediction": "FIT %",
            "predicted": prediction["fit"],
            "band": f"{prediction['fit_lo']:.3g} to {prediction['fit_hi']:.3g} %",
            "measured": fit,
            "verdict": verdict(fit, prediction["fit_lo"], prediction["fit_hi"], "points"),
        }
    )
    return pd.DataFrame(rows)


def verification_page(title: str, tables: Mapping[str, pd.DataFrame]) -> str:
    """The comparison as a markdown page: one table per recorded staircase."""
    lines = [f"# {title}: predictions against the bench", ""]
    for run_id, table in tables.items():
        kept = int((table["verdict"] == "kept").sum())
        lines += [
            f"## {run_id}: {kept} of {len(table)} kept",
            "",
            "| prediction | predicted | 95 % band | measured | verdict |",
            "|---|---|---|---|---|",
        ]
        for r in table.itertuples():
            cells = [r.prediction, f"{r.predicted:.4g}", r.band, f"{r.measured:.4g}", r.verdict]
            lines.append("| " + " | ".join(cells) + " |")
        lines.append("")
    return "\n".join(lines)
