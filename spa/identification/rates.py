"""The pressure rate dP/dt of a run (Savitzky-Golay on a uniform grid) and the segments of a
charge or discharge run it is fitted on."""

from __future__ import annotations

import logging
import math
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt
import pandas as pd

from spa._signal import savgol_filter
from spa.identification.results import FloatArray, IdentificationError, Runs
from spa.model.plant import edge_indices

__all__ = ["pressure_rate"]

_LOG = logging.getLogger("spa.identification")

# --------------------------------------------------------------------------------------------
# Run tables and derivatives
# --------------------------------------------------------------------------------------------


def _as_runs(runs: Runs | None, kind: str) -> list[tuple[str, pd.DataFrame]]:
    """Normalise ``runs`` to a list of ``(id, table)``; ids of a sequence are ``kind[i]``."""
    if runs is None:
        return []
    if isinstance(runs, pd.DataFrame):
        raise ValueError(f"{kind} must be a mapping of run id to table or a list of tables")
    if isinstance(runs, Mapping):
        items = [(str(k), v) for k, v in runs.items()]
    else:
        items = [(str(v.attrs.get("run_id", f"{kind}[{i}]")), v) for i, v in enumerate(runs)]
    for rid, table in items:
        if not isinstance(table, pd.DataFrame):
            raise ValueError(f"{kind} run {rid!r} must be a DataFrame, got {type(table).__name__}")
        for col in ("t", "p"):
            if col not in table.columns:
                raise ValueError(f"{kind} run {rid!r} has no {col!r} column")
    return items


def _arrays(table: pd.DataFrame, rid: str) -> tuple[FloatArray, FloatArray, np.ndarray | None]:
    """``t``, ``p`` and ``valve`` (or None) of a run, checked."""
    t = table["t"].to_numpy(dtype=np.float64)
    p = table["p"].to_numpy(dtype=np.float64)
    if t.size < 10:
        raise IdentificationError(f"run {rid!r} has only {t.size} samples")
    if not (np.all(np.isfinite(t)) and np.all(np.isfinite(p))):
        raise ValueError(f"run {rid!r}: columns 't' and 'p' must be finite")
    if np.any(np.diff(t) <= 0):
        raise ValueError(f"run {rid!r}: column 't' must be strictly increasing")
    valve = None
    if "valve" in table.columns:
        valve = table["valve"].to_numpy()
        if not np.all((valve == 0) | (valve == 1)):
            raise ValueError(f"run {rid!r}: column 'valve' must hold only 0 and 1")
        valve = valve.astype(np.int8)
    return t, p, valve


def _uniform(
    t: FloatArray, p: FloatArray, valve: np.ndarray | None
) -> tuple[FloatArray, FloatArray, np.ndarray | None, float]:
    """Resample onto a uniform grid at the median step (unchanged if already uniform)."""
    dt = float(np.median(np.diff(t)))
    if np.max(np.abs(np.diff(t) - dt)) <= 1e-6 * dt:
        return t, p, valve, dt
    n = math.floor((t[-1] - t[0]) / dt + 1e-9) + 1
    grid = t[0] + dt * np.arange(n)
    pg = np.interp(grid, t, p)
    vg = None
    if valve is not None:
        idx = np.searchsorted(t, grid + 1e-9 * dt, side="right") - 1
        vg = valve[np.clip(idx, 0, t.size - 1)]
    return grid, pg, vg, dt


def _window_samples(window: float, polyorder: int, dt: float, n: int | None = None) -> int:
    """Odd Savitzky–Golay window length in samples closest to ``window`` seconds."""
    if not (isinstance(polyorder, int | np.integer) and polyorder >= 1):
        raise ValueError(f"polyorder must be an integer >= 1, got {polyorder!r}")
    if not (math.isfinite(window) and window > 0):
        raise ValueError(f"window must be finite and > 0 s, got {window!r}")
    w = 2 * math.floor(window / (2.0 * dt) + 0.5) + 1
    if w <= polyorder + 1:
        raise ValueError(
            f"window = {window:g} s is {w} samples at dt = {dt:g} s; it must span more than "
            f"polyorder + 1 = {polyorder + 1} samples"
        )
    if n is not None and w > n:
        raise IdentificationError(
            f"window = {window:g} s ({w} samples) is longer than the run ({n} samples)"
        )
    return w


def _savgol(
    p: npt.ArrayLike, w: int, polyorder: int, dt: float, deriv: int = 0
) -> npt.NDArray[np.float64]:
    return savgol_filter(p, w, polyorder, deriv=deriv, delta=dt)


def pressure_rate(table: pd.DataFrame, window: float, polyorder: int) -> pd.DataFrame:
    """Smoothed pressure and its time derivative (Savitzky–Golay) on a uniform grid.

    Parameters
    ----------
    table : pandas.DataFrame
        Run table with ``t`` (s) and ``p`` (bar).
    window : float
        Savitzky–Golay window in s (rounded to the nearest odd number of samples).
    polyorder : int
        Polynomial order (>= 1).

    Returns
    -------
    pandas.DataFrame
        ``t`` (uniform grid at the median step), ``p`` (interpolated measurement),
        ``p_smooth`` (bar) and ``dpdt`` (bar/s).

    Raises
    ------
    ValueError
        If ``window`` spans no more than ``polyorder + 1`` samples or ``polyorder < 1``.

    Examples
    --------
    >>> import numpy as np, pandas as pd
    >>> t = np.arange(200) * 1e-3
    >>> out = pressure_rate(pd.DataFrame({"t": t, "p": 0.5 * t**2}), 0.021, 2)
    >>> bool(np.allclose(out["dpdt"], t))
    True
    """
    t, p, _ = _arrays(table, "table")
    tg, pg, _, dt = _uniform(t, p, None)
    w = _window_samples(window, polyorder, dt, tg.size)
    return pd.DataFrame(
        {
            "t": tg,
            "p": pg,
            "p_smooth": _savgol(pg, w, polyorder, dt),
            "dpdt": _savgol(pg, w, polyorder, dt, deriv=1),
        }
    )


# --------------------------------------------------------------------------------------------
# Experiments 1 and 2: the span of the fits, and the derivative for the line and the figure
# --------------------------------------------------------------------------------------------


@dataclass
class _Segment:
    """The usable part of one charge/discharge run on its uniform grid."""

    rid: str
    t: FloatArray  # grid times of the derivative region
    ps: FloatArray  # smoothed pressure over the region
    d: FloatArray  # derivative over the region
    p: FloatArray  # measured pressure over the region
    w: int  # Savitzky-Golay window, samples
    dt: float  # grid step, s
    used: npt.NDArray[np.bool_]  # points of the region that enter the fit
    points: pd.DataFrame  # all points after the edge, for the figure
    shortened: bool = False  # w is shorter than the configured window (a short run)
    tf: FloatArray = field(default_factory=lambda: np.empty(0))  # fit span (no trims): times
    pf: FloatArray = field(default_factory=lambda: np.empty(0))  # ... and measured pressure
    raw: bool = False  # too few samples for Savitzky-Golay: finite differences, raw samples


def _select_edge(valve: np.ndarray | None, rising: bool, rid: str, kind: str) -> tuple[int, int]:
    """Index of the first edge of the wanted direction and of the end of that command run."""
    n = 0 if valve is None else valve.size
    if valve is None:
        return 0, -1
    target = 1 if rising else 0
    k = edge_indices(valve)
    k = k[valve[k] == target]
    if k.size:
        start = int(k[0])
    elif valve[0] == target:
        start = 0
    else:
        state = "opens" if rising else "closes"
        raise IdentificationError(f"{kind} run {rid!r}: the valve never {state}")
    after = np.flatnonzero(valve[start:] != target)
    end = start + int(after[0]) - 1 if after.size else n - 1
    return start, end


def _segment(
    rid: str,
    table: pd.DataFrame,
    kind: str,
    window: float,
    polyorder: int,
    skip: float,
    onset_fraction: float,
    tail_fraction: float,
) -> _Segment:
    """Locate the response after the valve edge and compute smoothed pressure and rate.

    The Savitzky–Golay window is ``window`` unless the run's fit span is too short for it:
    a point enters the fit only when its whole window lies inside the response, and the fit
    needs at least ``max(2*w, 20)`` such points, i.e. a span of about ``3*w``. A shorter span
    (a small actuator that empties in 0.1 s) gets the largest odd window ``w`` that meets this
    (about a third of the span), never fewer than ``polyorder + 2`` samples; the window used
    is :attr:`_Segment.w` and is logged. Below that the run is refused with
    :class:`IdentificationError`.
    """
    t, p, valve = _arrays(table, rid)
    tg, pg, vg, dt = _uniform(t, p, valve)
    w = w_asked = _window_samples(window, polyorder, dt, None)
    w_min = polyorder + 2 + (polyorder + 1) % 2  # the smallest odd window > polyorder + 1
    if tg.size < w_min:
        raise IdentificationError(
            f"{kind} run {rid!r} has {tg.size} samples; the derivative needs {w_min}"
        )
    rising = kind == "charge"
    k_edge, k_end = _select_edge(vg, rising, rid, kind)
    k_end = tg.size - 1 if k_end < 0 else k_end
    w_first = w = min(w, tg.size if tg.size % 2 else tg.size - 1)
    for _ in range(8):
        seg, span = _segment_at(
            rid, kind, tg, pg, dt, w, polyorder, k_edge, k_end, rising, skip,
            onset_fraction, tail_fraction,
        )  # fmt: skip
        if seg is not None:
            seg.shortened = w < w_asked
            if w < w_first:
                _LOG.info(
                    "%s run %r: Savitzky-Golay window shortened from %d to %d samples (%.3g s), "
                    "a third of the %d-sample fit span",
                    kind, rid, w_first, w, w * dt, span,
                )  # fmt: skip
            return seg
        # The largest odd window with span >= 3 w and at least 20 points after the trims.
        fits = max(2 * math.floor((min(span / 3.0, span - 19.0) - 1.0) / 2.0) + 1, w_min)
        if fits >= w or (w == w_min):
            break
        w = fits
    # Too few samples for a smoothed derivative (a coarse log: 20-50 Hz, a response of a few
    # dozen samples): the closed-form fits need none. The derivative of Fig. 2 and the start
    # line then come from finite differences of the samples themselves.
    return _segment_raw(
        rid, kind, tg, pg, dt, k_edge, k_end, rising, skip, onset_fraction, tail_fraction
    )


#: Fewest samples of a run's fit span for the closed-form fits on raw samples (a coarse log):
#: the run's own amplitude or start and the shared parameters leave at least two degrees of
#: freedom.
MIN_RAW_SPAN = 4


def _segment_raw(
    rid: str,
    kind: str,
    tg: FloatArray,
    pg: FloatArray,
    dt: float,
    k_edge: int,
    k_end: int,
    rising: bool,
    skip: float,
    onset_fraction: float,
    tail_fraction: float,
) -> _Segment:
    """:func:`_segment` for a run too short for the Savitzky–Golay derivative: the fit span
    from the samples themselves, and finite differences for the figure and the start line.

    The span starts at the first sample that has moved ``onset_fraction`` of the change (and
    ``skip`` after the edge), so that the hold before the response stays out: the run's own
    amplitude (charge) or start (discharge) of the closed form then absorbs the response's
    unknown onset, a nuisance parameter, whether or not the log shows the valve's edge.
    """
    seg_p = pg[k_edge : k_end + 1]
    head = max(1, min(3, seg_p.size // 10))
    p_a = float(seg_p[:head].mean()) if rising else float(seg_p[:head].max())
    p_b = float(seg_p[-head:].mean())
    change = (p_b - p_a) if rising else (p_a - p_b)
    noise = float(np.std(np.diff(seg_p, 2))) / math.sqrt(6.0) if seg_p.size > 3 else 0.0
    if change <= max(10.0 * noise, 1e-6):
        what = "rise" if rising else "fall"
        raise IdentificationError(
            f"{kind} run {rid!r}: the pressure does not {what} after the valve edge "
            f"({p_a:.4g} -> {p_b:.4g} bar)"
        )
    moved = (seg_p - p_a) if rising else (p_a - seg_p)
    crossed = np.flatnonzero(moved >= max(onset_fraction * change, 3.0 * noise))
    k_onset = k_edge + (int(crossed[0]) if crossed.size else 0)
    _, _, in_span = _fit_span(
        tg, pg, dt, (k_edge, k_onset, k_end), rising, skip, tail_fraction * p_a
    )
    span = int(np.sum(in_span))
    if span < MIN_RAW_SPAN:
        raise IdentificationError(
            f"{kind} run {rid!r}: only {span} sample(s) at {1.0 / dt:.3g} Hz between the "
            f"response start and {'the end of the run' if rising else 'the near-zero tail'}; "
            f"the closed-form fit needs at least {MIN_RAW_SPAN}: log at least "
            f"{math.ceil(MIN_RAW_SPAN / max(span, 1)) * 1.0 / dt:.3g} Hz"
        )
    d = np.gradient(pg, dt)
    used = in_span.copy()
    points = _points(rid, tg, pg, d, used, k_edge, k_end)
    seg = _Segment(
        rid=rid,
        t=tg[in_span],
        ps=pg[in_span],
        d=d[in_span],
        p=pg[in_span],
        w=1,
        dt=dt,
        used=np.ones(span, dtype=bool),
        points=points,
        tf=tg[in_span],
        pf=pg[in_span],
    )
    seg.shortened = True
    seg.raw = True
    return seg


def _segment_at(
    rid: str,
    kind: str,
    tg: FloatArray,
    pg: FloatArray,
    dt: float,
    w: int,
    polyorder: int,
    k_edge: int,
    k_end: int,
    rising: bool,
    skip: float,
    onset_fraction: float,
    tail_fraction: float,
) -> tuple[_Segment | None, int]:
    """:func:`_segment` at a window of ``w`` samples: the segment (None when too few points
    fit) and the number of samples in the fit span before the half-window trims."""
    half = w // 2
    ps = _savgol(pg, w, polyorder, dt)
    d = _savgol(pg, w, polyorder, dt, deriv=1)
    # Level at the edge (mean of the half window before it, or the first samples) and at the
    # end of the command run (mean of its last half window).
    before = pg[max(k_edge - half, 0) : k_edge + 1]
    p_a = float(before.mean())
    p_b = float(pg[max(k_end - half, k_edge) : k_end + 1].mean())
    change = (p_b - p_a) if rising else (p_a - p_b)
    tail = slice(max(k_end - w, k_edge), k_end + 1)
    noise = float(np.std(pg[tail] - ps[tail]))
    if change <= max(10.0 * noise, 1e-6):
        what = "rise" if rising else "fall"
        raise IdentificationError(
            f"{kind} run {rid!r}: the pressure does not {what} after the valve edge "
            f"({p_a:.4g} -> {p_b:.4g} bar)"
        )
    moved = (ps[k_edge:] - p_a) if rising else (p_a - ps[k_edge:])
    crossed = np.flatnonzero(moved >= onset_fraction * change)
    k_onset = k_edge + (int(crossed[0]) if crossed.size else 0)
    t_first, t_last, in_span = _fit_span(
        tg, ps, dt, (k_edge, k_onset, k_end), rising, skip, tail_fraction * p_a
    )
    span = int(np.sum(in_span))
    t_start, t_stop = t_first + half * dt, t_last - half * dt
    used_all = (tg >= t_start - 1e-9 * dt) & (tg <= t_stop + 1e-9 * dt)
    idx = np.flatnonzero(used_all)
    if idx.size < max(2 * w, 20):
        return None, span
    lo = max(int(idx[0]) - half, 0)
    hi = min(int(idx[-1]) + half, tg.size - 1)
    region = slice(lo, hi + 1)
    points = _points(rid, tg, ps, d, used_all, k_edge, k_end)
    seg = _Segment(
        rid=rid,
        t=tg[region],
        ps=ps[region],
        d=d[region],
        p=pg[region],
        w=w,
        dt=dt,
        used=used_all[region],
        points=points,
        tf=tg[in_span],
        pf=pg[in_span],
    )
    return seg, span


def _fit_span(
    tg: FloatArray,
    level: FloatArray,
    dt: float,
    marks: tuple[int, int, int],
    rising: bool,
    skip: float,
    tail: float,
) -> tuple[float, float, npt.NDArray[np.bool_]]:
    """The closed-form fit's span: from ``max(edge + skip, onset)`` to the end of the command
    run, a discharge stopping where ``level`` (the smoothed or raw pressure) first falls
    below ``tail`` bar. ``marks`` = (edge, onset, end) indices; returns the first and last
    times and the mask of the grid samples inside."""
    k_edge, k_onset, k_end = marks
    t_first = max(tg[k_edge] + skip, tg[k_onset])
    t_last = tg[k_end]
    if not rising:
        below = np.flatnonzero(level[k_onset : k_end + 1] < tail)
        if below.size:
            t_last = min(t_last, tg[k_onset + int(below[0])] - 0.5 * dt)
    return t_first, t_last, (tg >= t_first - 1e-9 * dt) & (tg <= t_last + 1e-9 * dt)


def _points(
    rid: str,
    tg: FloatArray,
    p: FloatArray,
    d: FloatArray,
    used: npt.NDArray[np.bool_],
    k_edge: int,
    k_end: int,
) -> pd.DataFrame:
    """Fig. 2's points of one run: every grid point of the command run after the edge."""
    run = slice(k_edge, k_end + 1)
    return pd.DataFrame({"run": rid, "t": tg[run], "p": p[run], "dpdt": d[run], "used": used[run]})


def _line(x: FloatArray, y: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Least-squares line ``y = slope*x + intercept`` along the last axis."""
    xm = x.mean(axis=-1, keepdims=True)
    ym = y.mean(axis=-1, keepdims=True)
    sxy = ((x - xm) * (y - ym)).sum(axis=-1)
    sxx = ((x - xm) ** 2).sum(axis=-1)
    slope = sxy / np.where(sxx > 0, sxx, np.nan)
    return slope, ym[..., 0] - slope * xm[..., 0]


def _r2(y: FloatArray, fit: FloatArray) -> float:
    ss_tot = float(np.sum((y - y.mean()) ** 2))
    return 1.0 - float(np.sum((y - fit) ** 2)) / ss_tot if ss_tot > 0 else math.nan
