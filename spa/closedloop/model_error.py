"""The identified model's error measured on the dataset, as a set of plants to design against.

Per staircase level of every recorded open-loop staircase, the measured mean pressure over
the last part of the level is compared with the identified model's (the exact model driven
by the recorded valve command): the *equilibrium error* ``p_meas/p_model - 1`` per level and
the *gain error* per step between levels, the measured slope ``dp/dxi`` over the model's at
the same pressure, less 1 (:func:`level_errors`). The equilibrium error shifts the input
that holds a pressure, which the PI's integrator removes; the gain error changes the loop
gain. :func:`error_intervals` turns them into ranges: the extreme gain errors into a factor
on the loop gain (``gain``), and, for a loop with the averaged model's feed-forward, the
extreme equilibrium errors into a range of the supply ``k2``. :func:`widen` merges the
latter with the identification's 95 % box; the closed loop's promise is the worst over the
merged box and the estimate's loop at the gain factor's ends
(:func:`spa.closedloop.robust.box_worst_case`).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
import pandas as pd

from spa.model.params import ValveParams

__all__ = [
    "GAIN_TOLERANCE",
    "LEVEL_COLUMNS",
    "MAX_RELATIVE_ERROR",
    "dataset_error",
    "error_intervals",
    "level_errors",
    "same_pressure_gain_error",
    "widen",
]

#: Columns of :func:`level_errors`' table.
LEVEL_COLUMNS = ("run", "xi", "p_meas", "p_model", "error", "rel_error", "gain_error")

#: Largest relative error of ``k2`` taken as model error (a model off by more is not a model
#: of this valve: the adequacy verdict says so).
MAX_RELATIVE_ERROR = 0.5

#: Gain errors within this share are no model error for the promise: a PI's loop changes
#: less with them than between the box's corners, and each factor costs a run of every
#: corner (the slope of a recorded staircase step carries about this much noise).
GAIN_TOLERANCE = 0.05

#: Levels whose predicted pressure is below this fraction of ``k2`` give no relative error,
#: steps whose predicted change is below it no gain error (a ratio of two small numbers).
MIN_FRACTION = 0.05

#: Levels whose predicted pressure is below this fraction of ``k2`` give no relative
#: equilibrium error (near 0 bar a few mbar of offset is a large ratio the integrator removes).
MIN_LEVEL_FRACTION = 0.2


def level_errors(
    run: pd.DataFrame, params: ValveParams, *, settle: float = 0.4, name: str = ""
) -> pd.DataFrame:
    """Measured against predicted mean pressure per level of one staircase run.

    Parameters
    ----------
    run : pandas.DataFrame
        The canonical run table: ``t`` (s, uniform), ``p`` (bar), ``valve`` (0/1) and ``u``
        (the input fraction, constant per level).
    params : ValveParams
        The identified valve.
    settle : float, default 0.4
        The last ``settle`` share of each level is averaged (its equilibrium).
    name : str, optional
        The run's id, copied into the table.

    Returns
    -------
    pandas.DataFrame
        :data:`LEVEL_COLUMNS`, one row per level: ``xi``, the measured and predicted mean
        pressure (bar), ``error = p_meas - p_model`` (bar), ``rel_error = p_meas/p_model - 1``
        (NaN where ``p_model < 0.2 k2``) and ``gain_error``, the measured slope
        ``dp/dxi`` from the previous level over the model's slope at the same pressure, less
        1 (:func:`same_pressure_gain_error`; NaN for the first level and small steps).

    Examples
    --------
    >>> from spa.model.plant import simulate
    >>> dt = 1e-3
    >>> u = np.repeat([0.3, 0.6], 3000)
    >>> valve = (np.arange(u.size) % 50 < 50 * u).astype(np.int8)
    >>> p = simulate(valve, dt, ValveParams())
    >>> run = pd.DataFrame({"t": np.arange(u.size) * dt, "p": p, "valve": valve, "u": u})
    >>> e = level_errors(run, ValveParams())
    >>> bool(np.allclose(e["error"], 0.0))
    True
    """
    from spa.model.plant import simulate

    t = run["t"].to_numpy(np.float64)
    p = run["p"].to_numpy(np.float64)
    valve = run["valve"].to_numpy(np.int8)
    u = run["u"].to_numpy(np.float64)
    if t.size < 2:
        return pd.DataFrame(columns=list(LEVEL_COLUMNS))
    dt = float(np.median(np.diff(t)))
    model = np.asarray(simulate(valve, dt, params, p0=max(float(p[0]), 0.0)), dtype=np.float64)
    starts = np.concatenate(([0], np.flatnonzero(u[1:] != u[:-1]) + 1))
    stops = np.append(starts[1:], u.size)
    rows = []
    for a, b in zip(starts.tolist(), stops.tolist(), strict=True):
        lo = b - max(round(settle * (b - a)), 1)
        rows.append(
            {
                "run": name,
                "xi": float(u[a]),
                "p_meas": float(np.mean(p[lo:b])),
                "p_model": float(np.mean(model[lo:b])),
            }
        )
    out = pd.DataFrame(rows, columns=["run", "xi", "p_meas", "p_model"])
    floor = MIN_FRACTION * params.k2
    pm, pp = out["p_meas"].to_numpy(), out["p_model"].to_numpy()
    out["error"] = pm - pp
    with np.errstate(divide="ignore", invalid="ignore"):
        level_floor = MIN_LEVEL_FRACTION * params.k2
        out["rel_error"] = np.where(pp >= level_floor, pm / pp - 1.0, np.nan)
    gain = same_pressure_gain_error(out["xi"].to_numpy(np.float64), pm, pp, floor)
    # Only steps between two levels the model holds above MIN_LEVEL_FRACTION*k2: below it the
    # modulator's own dead zone (IIPFM, a delay longer than the pulse) dominates the slope, a
    # ratio of two small differences, and the loop's set-points do not go there.
    held = np.concatenate(([False], (pp[1:] >= level_floor) & (pp[:-1] >= level_floor)))
    out["gain_error"] = np.where(held, gain, np.nan)
    return out[list(LEVEL_COLUMNS)]


def same_pressure_gain_error(
    xi: np.ndarray, p_meas: np.ndarray, p_model: np.ndarray, floor: float
) -> np.ndarray:
    """The static gain's error where the loop works: at the same pressure, not the same
    input.

    For level ``i`` (after level ``i - 1``), the measured slope
    ``(p_meas[i] - p_meas[i-1])/(xi[i] - xi[i-1])`` is compared with the model's slope on the
    segment of its own curve ``(xi, p_model)`` that contains the step's middle pressure
    (a loop holding that pressure sees the model's gain there, whatever input it takes).

    Parameters
    ----------
    xi, p_meas, p_model : numpy.ndarray
        The levels' input fractions and mean pressures, in the run's order.
    floor : float
        Steps (measured, and the model's segment) smaller than this, bar, give NaN.

    Returns
    -------
    numpy.ndarray
        ``slope_meas/slope_model - 1`` per level; NaN where undefined.

    Examples
    --------
    >>> xi = np.array([0.2, 0.4, 0.6, 0.8])
    >>> same_pressure_gain_error(xi, 0.5 * xi + 0.2, xi, 0.01).round(6).tolist()  # half as steep
    [nan, -0.5, -0.5, -0.5]
    >>> bool(np.allclose(same_pressure_gain_error(xi, xi + 0.1, xi, 0.01)[1:3], 0.0))  # offset
    True
    """
    out = np.full(xi.size, np.nan)
    order = np.argsort(xi, kind="stable")
    x_m, p_m = xi[order], p_model[order]
    rising = np.concatenate(([True], np.diff(p_m) > 0.0))
    x_m, p_m = x_m[rising], p_m[rising]
    for i in range(1, xi.size):
        dx, dpm = xi[i] - xi[i - 1], p_meas[i] - p_meas[i - 1]
        if dx == 0.0 or abs(dpm) < floor:
            continue
        mid = 0.5 * (p_meas[i] + p_meas[i - 1])
        k = int(np.searchsorted(p_m, mid))
        if k <= 0 or k >= p_m.size:
            continue  # the model never reaches that pressure: no slope to compare
        seg = p_m[k] - p_m[k - 1]
        if seg < floor:
            continue
        out[i] = (dpm / dx) / (seg / (x_m[k] - x_m[k - 1])) - 1.0
    return out


def error_intervals(
    levels: pd.DataFrame,
    params: ValveParams,
    *,
    equilibrium: bool = False,
) -> dict[str, tuple[float, float]]:
    """The measured model error as ranges: the loop gain's factor and, for a feed-forward
    loop, the supply ``k2``.

    Parameters
    ----------
    levels : pandas.DataFrame
        :func:`level_errors` of every staircase run (concatenated; may be empty).
    params : ValveParams
        The identified valve.
    equilibrium : bool, default False
        Also widen ``k2`` by the relative equilibrium errors: for a loop with the averaged
        model's feed-forward, whose input then holds a different pressure.

    Returns
    -------
    dict
        ``gain -> (1 + g_lo, 1 + g_hi)``, ``g`` over every finite gain error and 0 (clipped
        to ±:data:`MAX_RELATIVE_ERROR`; left out when both are within
        :data:`GAIN_TOLERANCE`): the factor on the loop gain of a plant whose slope
        ``dP_eq/dxi`` differs from the model's where the loop works; with ``equilibrium``,
        ``k2 -> (k2*(1 + e_lo), k2*(1 + e_hi))``, ``e`` over every finite equilibrium error
        and 0. Entries without error are left out.

    Notes
    -----
    A gain error is a local property: the measured slope differs from the model's at the
    same pressure while the equilibrium itself may be close. Scaling ``k2`` by it would move
    the whole equilibrium curve (and the set-points each plant holds) by the extreme slope
    error; it is carried instead as a factor on the loop gain, which is what a slope error
    does to the loop (the PI's gains times ``1 + g`` close the same linear loop as a plant
    ``1 + g`` times steeper). The delays' uncertainty is the identification's interval (the
    refinement on every run, widened to the spread between runs).

    Examples
    --------
    >>> lv = pd.DataFrame({"rel_error": [0.05, -0.02], "gain_error": [np.nan, 0.1]})
    >>> error_intervals(lv, ValveParams(k2=1.0))
    {'gain': (1.0, 1.1)}
    >>> error_intervals(lv, ValveParams(k2=1.0), equilibrium=True)["k2"]
    (0.98, 1.05)
    """

    def extremes(column: str) -> tuple[float, float] | None:
        if column not in levels.columns:
            return None
        errs = levels[column].to_numpy(np.float64)
        errs = np.clip(errs[np.isfinite(errs)], -MAX_RELATIVE_ERROR, MAX_RELATIVE_ERROR)
        errs = np.where(np.abs(errs) < 1e-6, 0.0, errs)  # rounding, not model error
        if not errs.size:
            return None
        lo, hi = min(float(errs.min()), 0.0), max(float(errs.max()), 0.0)
        return (lo, hi) if hi > lo else None

    out: dict[str, tuple[float, float]] = {}
    gain = extremes("gain_error")
    if gain is not None and max(-gain[0], gain[1]) >= GAIN_TOLERANCE:
        out["gain"] = (1.0 + gain[0], 1.0 + gain[1])
    if equilibrium and (eq := extremes("rel_error")) is not None:
        out["k2"] = (params.k2 * (1.0 + eq[0]), params.k2 * (1.0 + eq[1]))
    return out


def widen(
    box: Mapping[str, tuple[float, float]] | None, extra: Mapping[str, tuple[float, float]]
) -> dict[str, tuple[float, float]]:
    """The smallest intervals holding both ``box`` and ``extra`` per parameter.

    Examples
    --------
    >>> widen({"k2": (0.9, 1.1), "c1": (0.4, 0.5)}, {"k2": (0.8, 1.0)})
    {'k2': (0.8, 1.1), 'c1': (0.4, 0.5)}
    """
    out = {k: (float(v[0]), float(v[1])) for k, v in (box or {}).items()}
    for k, (lo, hi) in extra.items():
        if k in out:
            out[k] = (min(out[k][0], float(lo)), max(out[k][1], float(hi)))
        else:
            out[k] = (float(lo), float(hi))
    return out


def dataset_error(
    runs: Mapping[str, pd.DataFrame],
    metas: Mapping[str, Mapping[str, Any]],
    params: ValveParams,
    *,
    equilibrium: bool = False,
) -> dict[str, tuple[float, float]]:
    """:func:`error_intervals` over every ``staircase`` run of a dataset.

    Parameters
    ----------
    runs, metas : mapping
        Run id -> run table and metadata (:func:`spa.datasets.read_runs`).
    params : ValveParams
        The identified valve.
    equilibrium : bool, default False
        As :func:`error_intervals`.

    Returns
    -------
    dict
        The parameter ranges; empty when nothing was measured.
    """
    tables = [
        level_errors(runs[rid], params, name=rid)
        for rid, meta in sorted(metas.items())
        if meta.get("kind") == "staircase" and rid in runs
    ]
    frame = pd.concat(tables, ignore_index=True) if tables else pd.DataFrame()
    return error_intervals(frame, params, equilibrium=equilibrium)
