"""Staircase and sine linearity analyses of the open-loop experiments (MODEL.md section 5).

Pure functions on arrays; the arguments are the columns of the canonical run table
(``t`` in s, ``p`` in bar, ``valve`` 0/1, ``u`` the input fraction), so a run is analysed as

>>> import pandas as pd
>>> t = np.arange(0, 20, 0.01)
>>> u = np.floor(t / 5) / 4  # four levels, 0 .. 0.75
>>> run = pd.DataFrame({"t": t, "p": 0.8 * u, "u": u})
>>> levels = staircase_levels(run["t"], run["p"], run["u"])
>>> round(linear_fit_metrics(levels["xi"], levels["p_eq"])["fit"], 9)
100.0

* Staircase (Table 3, Fig. 7): `staircase_levels` finds the constant-input levels and the
  settled statistics of each; `linear_fit_metrics` fits ``P = m*xi + n`` to the equilibrium
  pressures; `step_time_constants` measures the time to 63.2 % of each step's change.
* Sine (Fig. 8): `compensate_lag` removes the phase lag by cross-correlation, then
  `sine_linearity` compares the pressure normalised to its maximum with the line from
  (0, 0) to (1, 1).

None of them loops over samples in Python: per-level statistics use ``ufunc.reduceat`` and
cumulative sums over the contiguous runs of samples that make up each level.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import numpy.typing as npt
import pandas as pd
from scipy.signal import correlate, correlation_lags

__all__ = [
    "TAU_FRACTION",
    "compensate_lag",
    "linear_fit_metrics",
    "sine_linearity",
    "staircase_levels",
    "step_time_constants",
]

#: Fraction of a first-order step response reached after one time constant (63.2 %).
TAU_FRACTION = 1.0 - math.exp(-1.0)


# ---------------------------------------------------------------- validation helpers


def _array(name: str, a: Any, size: int | None = None, min_size: int = 1) -> np.ndarray:
    """``a`` as a finite one-dimensional float64 array, or ValueError naming ``name``."""
    try:
        x = np.asarray(a, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be an array of real numbers") from None
    if x.ndim != 1:
        raise ValueError(f"{name} must be a one-dimensional array, got shape {x.shape}")
    if size is not None and x.size != size:
        raise ValueError(f"{name} must have the same length as t ({size}), got {x.size}")
    if x.size < min_size:
        raise ValueError(f"{name} must hold at least {min_size} samples, got {x.size}")
    if not np.all(np.isfinite(x)):
        bad = int(np.flatnonzero(~np.isfinite(x))[0])
        raise ValueError(f"{name} must be finite; {name}[{bad}] = {x[bad]!r}")
    return x


def _time(t: Any) -> np.ndarray:
    tt = _array("t", t, min_size=2)
    if np.any(np.diff(tt) <= 0.0):
        bad = int(np.flatnonzero(np.diff(tt) <= 0.0)[0]) + 1
        raise ValueError(f"t must be strictly increasing; t[{bad}] = {tt[bad]!r} <= t[{bad - 1}]")
    return tt


def _fraction(name: str, value: Any) -> float:
    """A number in (0, 1], or ValueError naming it."""
    try:
        v = float(value)
    except (TypeError, ValueError):
        v = math.nan
    if not (0.0 < v <= 1.0):
        raise ValueError(f"{name} must be a fraction in (0, 1], got {value!r}")
    return v


def _nonnegative(name: str, value: Any, unit: str) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        v = math.nan
    if not (math.isfinite(v) and v >= 0.0):
        raise ValueError(f"{name} must be a finite number >= 0 ({unit}), got {value!r}")
    return v


def _valve(valve: Any, size: int) -> np.ndarray:
    v = _array("valve", valve, size=size)
    if not np.all((v == 0.0) | (v == 1.0)):
        bad = int(np.flatnonzero((v != 0.0) & (v != 1.0))[0])
        raise ValueError(f"valve must hold only 0 and 1; valve[{bad}] = {v[bad]!r}")
    return v


# ---------------------------------------------------------------- staircase


def _segment_sums(ufunc: np.ufunc, values: np.ndarray, first: np.ndarray, end: np.ndarray):
    """``ufunc.reduce(values[first[j]:end[j]])`` for every j (all ranges non-empty)."""
    padded = np.append(values, values[:1])  # so that end == len(values) is a valid index
    idx = np.column_stack((first, end)).ravel()
    return ufunc.reduceat(padded, idx)[::2]


def _staircase(t, p, u, settle, atol):
    """Levels of ``u`` and the settled window of each: the arrays behind the public tables."""
    n = t.size
    starts = np.concatenate(([0], np.flatnonzero(np.abs(np.diff(u)) > atol) + 1))
    ends = np.append(starts[1:], n)
    lengths = ends - starts
    label = np.repeat(np.arange(starts.size), lengths)
    t_start = t[starts]
    # The last level lasts one more sample period, so equal steps report equal durations.
    t_end = np.append(t[starts[1:]], t[-1] + (t[-1] - t[-2]))
    threshold = t_end - settle * (t_end - t_start)
    in_window = t >= threshold[label]
    in_window[ends - 1] = True  # at least the last sample of each level
    # t increases, so each window is a tail [first, end) of its level.
    first = np.minimum.reduceat(np.where(in_window, np.arange(n), n), starts)
    count = ends - first
    p_eq = _segment_sums(np.add, p, first, ends) / count
    dev2 = (p - p_eq[label]) ** 2
    p_std = np.sqrt(_segment_sums(np.add, dev2, first, ends) / count)
    p_pp = _segment_sums(np.maximum, p, first, ends) - _segment_sums(np.minimum, p, first, ends)
    # Ripple about the window's least-squares line: the chattering without the slow tail of
    # the step response still settling inside the window.
    t_mid = _segment_sums(np.add, t, first, ends) / count
    dt_ = np.where(in_window, t - t_mid[label], 0.0)
    sxx = _segment_sums(np.add, dt_ * dt_, first, ends)
    sxy = _segment_sums(np.add, dt_ * (p - p_eq[label]), first, ends)
    slope = np.divide(sxy, sxx, out=np.zeros_like(sxy), where=sxx > 0.0)
    resid = p - p_eq[label] - slope[label] * dt_
    p_ripple = _segment_sums(np.maximum, resid, first, ends) - _segment_sums(
        np.minimum, resid, first, ends
    )
    return {
        "starts": starts,
        "ends": ends,
        "first": first,
        "label": label,
        "xi": u[starts],
        "t_start": t_start,
        "t_end": t_end,
        "p_eq": p_eq,
        "p_std": p_std,
        "p_pp": p_pp,
        "p_ripple": p_ripple,
        "n_window": count,
    }


def staircase_levels(
    t: npt.ArrayLike,
    p: npt.ArrayLike,
    u: npt.ArrayLike,
    valve: npt.ArrayLike | None = None,
    *,
    settle: float = 0.4,
    atol: float = 1e-9,
) -> pd.DataFrame:
    """Equilibrium pressure, spread and chattering of every level of a staircase input.

    Parameters
    ----------
    t : array_like of float, shape (n,)
        Sample times in s, strictly increasing (column ``t`` of a run table).
    p : array_like of float, shape (n,)
        Pressure in bar (column ``p``).
    u : array_like of float, shape (n,)
        Input fraction (column ``u``), piece-wise constant: a new level starts wherever it
        changes by more than ``atol`` from one sample to the next.
    valve : array_like of {0, 1}, shape (n,), optional
        Valve command (column ``valve``); when given, ``switching_rate`` is computed.
    settle : float, default 0.4
        Settled window of each level as the fraction of its duration at its end, in (0, 1]:
        the samples with ``t >= t_end - settle*(t_end - t_start)``. The default keeps the last
        40 % (the last 2 s of a 5 s step).
    atol : float, default 1e-9
        Smallest change of ``u`` that starts a new level (>= 0).

    Returns
    -------
    pandas.DataFrame
        One row per level, in time order, with columns

        ``level``
            0, 1, 2, ...
        ``xi``
            The level's input fraction (its first sample of ``u``).
        ``t_start``, ``t_end``
            Start of the level and start of the next one, in s. The last level ends one
            sample period after the last sample (so equal steps report equal durations).
        ``p_eq``
            Equilibrium pressure: mean of ``p`` over the settled window (bar).
        ``p_std``
            Standard deviation of ``p`` over the window (bar, population: ``ddof = 0``).
        ``p_pp``
            Peak-to-peak ``max(p) - min(p)`` over the window (bar).
        ``p_ripple``
            Chattering: peak-to-peak of ``p`` about the window's least-squares straight
            line (bar), so that the tail of a response still settling in the window does
            not count as chattering.
        ``switching_rate``
            Valve edges (rising and falling) per second over the window: the number of
            changes between consecutive window samples divided by the time from the
            window's first to its last sample. NaN without ``valve`` or for a one-sample
            window. For a periodic pulse train it is twice the firing frequency.
        ``n_window``
            Samples in the window (at least 1: the level's last sample is always in).

    Raises
    ------
    ValueError
        If ``t``, ``p``, ``u`` (or ``valve``) are not finite one-dimensional arrays of one
        length >= 2, ``t`` is not strictly increasing, ``valve`` holds values other than 0
        and 1, ``settle`` is not in (0, 1] or ``atol`` is negative; the message names the
        argument.

    Notes
    -----
    MODEL.md section 5: the equilibrium pressure of a level is the mean over the settled part
    of the step; the staircase of the paper holds each of 11 levels (``xi = 0, 0.1, .., 1``)
    for 5 s.

    Examples
    --------
    >>> t = np.arange(0, 4, 0.5)
    >>> levels = staircase_levels(t, [0, 0, 1, 3, 3, 3, 5, 7], [0, 0, 0, 0, .5, .5, .5, .5],
    ...                           settle=0.5)
    >>> levels[["xi", "t_start", "t_end", "p_eq", "p_pp", "n_window"]]
        xi  t_start  t_end  p_eq  p_pp  n_window
    0  0.0      0.0    2.0   2.0   2.0         2
    1  0.5      2.0    4.0   6.0   2.0         2
    """
    tt = _time(t)
    pp = _array("p", p, size=tt.size)
    uu = _array("u", u, size=tt.size)
    vv = None if valve is None else _valve(valve, tt.size)
    s = _fraction("settle", settle)
    tol = _nonnegative("atol", atol, "input fraction")

    lv = _staircase(tt, pp, uu, s, tol)
    rate = np.full(lv["starts"].size, np.nan)
    if vv is not None:
        edge = np.zeros(tt.size, dtype=np.int64)
        edge[1:] = vv[1:] != vv[:-1]
        cum = np.concatenate(([0], np.cumsum(edge)))  # cum[k] = edges at samples < k
        first, ends = lv["first"], lv["ends"]
        # edges at samples first+1 .. end-1: both samples of the pair inside the window
        n_edges = cum[ends] - cum[np.minimum(first + 1, ends)]
        span = tt[ends - 1] - tt[first]
        np.divide(n_edges, span, out=rate, where=span > 0.0)
    return pd.DataFrame(
        {
            "level": np.arange(lv["starts"].size),
            "xi": lv["xi"],
            "t_start": lv["t_start"],
            "t_end": lv["t_end"],
            "p_eq": lv["p_eq"],
            "p_std": lv["p_std"],
            "p_pp": lv["p_pp"],
            "p_ripple": lv["p_ripple"],
            "switching_rate": rate,
            "n_window": lv["n_window"],
        }
    )


def linear_fit_metrics(xi: npt.ArrayLike, p_eq: npt.ArrayLike) -> dict[str, float]:
    """Least-squares line through the equilibrium pressures, and how far they are from it.

    Parameters
    ----------
    xi : array_like of float, shape (k,)
        Input fractions of the levels (at least two distinct values).
    p_eq : array_like of float, shape (k,)
        Equilibrium pressures of the levels in bar.

    Returns
    -------
    dict
        ``m`` (bar), ``n`` (bar): the line ``P = m*xi + n``;
        ``mse`` (bar²): mean of the squared residuals;
        ``md`` (bar): largest absolute residual;
        ``mad`` (bar): mean absolute residual (see Notes);
        ``fit`` (%): ``100*(1 - ||P - P_fit|| / ||P - mean(P)||)``, NaN if all ``p_eq`` are
        equal (the fit is undefined; the other entries are still valid).

    Raises
    ------
    ValueError
        If the arrays are not finite, one-dimensional and of one length, or ``xi`` holds
        fewer than two distinct values.

    Notes
    -----
    Table 3 of the paper (MSE, MD = maximum deviation, FIT %). FIT is the normalised-RMSE fit
    of system-identification tools: 100 for points on a line, 0 for a fit no better than the
    mean, negative for worse. It is unchanged by any affine rescaling ``a*P + b`` (``a != 0``)
    of the pressures.

    The paper calls MD the "maximum deviation", but its Table 3 has ``sqrt(MSE) > MD`` in every
    row, which no largest residual can satisfy; its MD values are close to the mean absolute
    residual ``mad`` of simulated staircases (and about half their largest residual). Both
    are returned; ``md`` is the largest, as specified in MODEL.md.

    Examples
    --------
    >>> r = linear_fit_metrics([0, 0.5, 1], [0, 0.5, 0.75])
    >>> {k: round(v, 6) for k, v in r.items()}
    {'m': 0.75, 'n': 0.041667, 'mse': 0.003472, 'md': 0.083333, 'mad': 0.055556, 'fit': 81.101776}
    """
    x = _array("xi", xi)
    p = _array("p_eq", p_eq)
    if p.size != x.size:
        raise ValueError(f"p_eq must have the same length as xi ({x.size}), got {p.size}")
    if np.unique(x).size < 2:
        raise ValueError("xi must hold at least two distinct values to fit a line")
    xc = x - x.mean()
    # Exactly flat data: keep the residuals exactly 0 (p - p.mean() may leave rounding error).
    pc = p - p.mean() if np.ptp(p) > 0.0 else np.zeros_like(p)
    m = float(np.dot(xc, pc) / np.dot(xc, xc))
    n = float(p.mean() - m * x.mean()) if np.ptp(p) > 0.0 else float(p[0])
    resid = p - (m * x + n)
    spread = float(np.linalg.norm(pc))
    fit = 100.0 * (1.0 - float(np.linalg.norm(resid)) / spread) if spread > 0.0 else math.nan
    return {
        "m": m,
        "n": n,
        "mse": float(np.mean(resid**2)),
        "md": float(np.max(np.abs(resid))),
        "mad": float(np.mean(np.abs(resid))),
        "fit": fit,
    }


def _moving_average(t: np.ndarray, p: np.ndarray, width: float) -> np.ndarray:
    """Centred moving average of ``p`` over ``[t - width/2, t + width/2]`` (shrinks at the ends)."""
    lo = np.searchsorted(t, t - width / 2, side="left")
    hi = np.searchsorted(t, t + width / 2, side="right")
    cum = np.concatenate(([0.0], np.cumsum(p)))
    return (cum[hi] - cum[lo]) / (hi - lo)


def step_time_constants(
    t: npt.ArrayLike,
    p: npt.ArrayLike,
    u: npt.ArrayLike,
    *,
    settle: float = 0.4,
    fraction: float = TAU_FRACTION,
    min_change: float = 0.01,
    smooth: float = 0.0,
    atol: float = 1e-9,
) -> pd.DataFrame:
    """Time to 63.2 % of the pressure change of every step of a staircase.

    Parameters
    ----------
    t, p, u : array_like of float, shape (n,)
        Columns ``t`` (s), ``p`` (bar) and ``u`` (input fraction) of a run, as in
        `staircase_levels`.
    settle : float, default 0.4
        Settled window used for the pressures before and after each step, as in
        `staircase_levels`.
    fraction : float, default ``1 - exp(-1)`` (0.632...)
        Fraction of the change that defines the time constant, in (0, 1].
    min_change : float, default 0.01
        Steps whose pressure change ``|p_to - p_from|`` is at most this (bar) get
        ``tau = NaN``: without a change (dead-zone, saturation) there is no time constant.
    smooth : float, default 0.0
        Width in s of a centred moving average applied to ``p`` before looking for the
        crossing (0: none). Chattering of the size of the step makes the raw first crossing
        early; a width of one modulation period removes most of it.
    atol : float, default 1e-9
        Smallest change of ``u`` that starts a new level.

    Returns
    -------
    pandas.DataFrame
        One row per step (a change of level; the first level is not a step), with columns
        ``step`` (index of the level stepped into, 1, 2, ...), ``xi_from``, ``xi_to``,
        ``t_start`` (s), ``p_from``, ``p_to`` (settled means of the two levels, bar),
        ``dp = p_to - p_from`` (bar) and ``tau`` (s): the time from ``t_start`` to the first
        moment the (smoothed) pressure reaches ``p_from + fraction*dp``, linearly
        interpolated between samples. ``tau`` is NaN if ``|dp| <= min_change`` or if the
        pressure never gets there before the next step; it is 0 if it is already there at
        the step's first sample. Mean and spread over the steps are left to the caller
        (``df["tau"].mean()``, ``df["tau"].std()`` skip NaN).

    Raises
    ------
    ValueError
        For arrays as in `staircase_levels`, ``fraction`` outside (0, 1], a negative or
        non-finite ``min_change``, ``smooth`` or ``atol``; the message names the argument.

    Notes
    -----
    Fig. 7b of the paper: for a first-order response ``p_from + dp*(1 - exp(-(t - t0)/tau))``
    the default fraction ``1 - exp(-1)`` is reached exactly at ``t0 + tau``. The time includes
    any dead time after the step (e.g. the valve's switching delays).

    Examples
    --------
    >>> t = np.arange(0, 20, 0.001)
    >>> u = np.where(t < 10, 0.2, 0.6)
    >>> p = np.where(t < 10, 0.1, 0.5 - 0.4 * np.exp(-(t - 10) / 0.75))
    >>> steps = step_time_constants(t, p, u)
    >>> steps[["xi_from", "xi_to", "dp"]].round(4).to_dict("records")
    [{'xi_from': 0.2, 'xi_to': 0.6, 'dp': 0.4}]
    >>> round(float(steps["tau"].iloc[0]), 3)
    0.75
    """
    tt = _time(t)
    pp = _array("p", p, size=tt.size)
    uu = _array("u", u, size=tt.size)
    s = _fraction("settle", settle)
    frac = _fraction("fraction", fraction)
    dp_min = _nonnegative("min_change", min_change, "bar")
    width = _nonnegative("smooth", smooth, "s")
    tol = _nonnegative("atol", atol, "input fraction")

    lv = _staircase(tt, pp, uu, s, tol)
    n_levels = lv["starts"].size
    p_from = lv["p_eq"][:-1]
    p_to = lv["p_eq"][1:]
    dp = p_to - p_from
    ps = _moving_average(tt, pp, width) if width > 0.0 else pp

    # Per level (level 0 is not a step): target pressure, direction, and whether to look.
    target = np.concatenate(([0.0], p_from + frac * dp))
    direction = np.concatenate(([0.0], np.sign(dp)))
    look = np.concatenate(([False], np.abs(dp) > dp_min))
    label = lv["label"]
    reached = look[label] & (direction[label] * (ps - target[label]) >= 0.0)
    n = tt.size
    k = np.minimum.reduceat(np.where(reached, np.arange(n), n), lv["starts"])[1:]
    starts = lv["starts"][1:]
    found = k < n
    kk = np.where(found, k, starts)  # placeholder index where not found
    prev = np.maximum(kk - 1, 0)
    # Between samples prev and kk the pressure goes from short of the target to past it.
    gap = ps[kk] - ps[prev]
    interp = kk > starts
    w = np.zeros(n_levels - 1)
    np.divide(target[1:] - ps[prev], gap, out=w, where=interp & (gap != 0.0))
    t_cross = np.where(interp, tt[prev] + w * (tt[kk] - tt[prev]), tt[kk])
    tau = np.where(found, t_cross - tt[starts], np.nan)
    return pd.DataFrame(
        {
            "step": np.arange(1, n_levels),
            "xi_from": lv["xi"][:-1],
            "xi_to": lv["xi"][1:],
            "t_start": lv["t_start"][1:],
            "p_from": p_from,
            "p_to": p_to,
            "dp": dp,
            "tau": tau,
        }
    )


# ---------------------------------------------------------------- sine


def compensate_lag(
    t: npt.ArrayLike,
    x_in: npt.ArrayLike,
    p: npt.ArrayLike,
    *,
    max_lag: float | None = None,
    causal: bool = True,
) -> tuple[float, np.ndarray, np.ndarray, np.ndarray]:
    """Delay between an input and the pressure by cross-correlation, and the aligned records.

    Parameters
    ----------
    t : array_like of float, shape (n,)
        Sample times in s, uniformly spaced (relative spread of the steps below 1e-6).
    x_in : array_like of float, shape (n,)
        Input, e.g. column ``u`` (input fraction).
    p : array_like of float, shape (n,)
        Response, e.g. column ``p`` (bar).
    max_lag : float, optional
        Largest ``|lag|`` searched, in s (default: the whole record).
    causal : bool, default True
        Only search lags >= 0 (the pressure follows the input).

    Returns
    -------
    lag : float
        Delay of ``p`` with respect to ``x_in`` in s, a whole number of sample periods:
        the lag ``L`` maximising ``sum_k (p[k + L] - mean(p))*(x_in[k] - mean(x_in))``.
    t_aligned, x_aligned, p_aligned : numpy.ndarray, shape (n - |L|,)
        The overlapping part with ``p`` shifted back by the lag: ``p_aligned[k]`` is the
        response to ``x_aligned[k]``, which was applied at ``t_aligned[k]``.

    Raises
    ------
    ValueError
        If the arrays are not finite, one-dimensional and of one length >= 2, ``t`` is not
        uniformly spaced and increasing, ``x_in`` or ``p`` is constant, or ``max_lag`` is
        negative; the message names the argument.

    Notes
    -----
    The means are removed before correlating, and the raw (unnormalised) correlation is
    maximised. For a periodic input the delay is only defined modulo the period; the raw
    sum favours the candidate with the largest overlap, i.e. the smallest ``|lag|``, which is
    the physical one when the phase lag is below 180° (a first-order lag stays below 90°).
    A piece-wise decreasing amplitude, as in the paper's sine experiment (Fig. 8), makes the
    true lag a strict maximum. Use ``max_lag`` to rule out far candidates.

    Examples
    --------
    >>> t = np.arange(0, 10, 0.01)
    >>> x = 0.5 + 0.4 * np.sin(2 * np.pi * 0.5 * t)
    >>> p = 0.5 + 0.4 * np.sin(2 * np.pi * 0.5 * (t - 0.12))
    >>> lag, ta, xa, pa = compensate_lag(t, x, p)
    >>> round(lag, 6), ta.size, bool(np.allclose(xa, pa))
    (0.12, 988, True)
    """
    tt = _time(t)
    x = _array("x_in", x_in, size=tt.size)
    pp = _array("p", p, size=tt.size)
    limit = None if max_lag is None else _nonnegative("max_lag", max_lag, "s")
    steps = np.diff(tt)
    dt = float(np.mean(steps))
    if np.max(np.abs(steps - dt)) > 1e-6 * dt:
        raise ValueError("t must be uniformly spaced to measure a lag in samples")
    if np.ptp(x) == 0.0:
        raise ValueError("x_in is constant: no lag can be measured")
    if np.ptp(pp) == 0.0:
        raise ValueError("p is constant: no lag can be measured")
    n = tt.size
    corr = correlate(pp - pp.mean(), x - x.mean(), mode="full", method="fft")
    lags = correlation_lags(n, n, mode="full")  # corr[i] = sum_k p[k + lags[i]]*x[k]
    allowed = np.ones(lags.size, dtype=bool)
    if causal:
        allowed &= lags >= 0
    if limit is not None:
        allowed &= np.abs(lags) <= math.floor(limit / dt + 1e-9)
    lag_n = int(lags[np.flatnonzero(allowed)[np.argmax(corr[allowed])]])
    if lag_n >= 0:
        sl_x, sl_p = slice(0, n - lag_n), slice(lag_n, n)
    else:
        sl_x, sl_p = slice(-lag_n, n), slice(0, n + lag_n)
    return lag_n * dt, tt[sl_x], x[sl_x], pp[sl_p]


def sine_linearity(xi: npt.ArrayLike, p: npt.ArrayLike) -> dict[str, float]:
    """Deviation of the normalised pressure from the line from (0, 0) to (1, 1).

    Parameters
    ----------
    xi : array_like of float, shape (n,)
        Input fraction, aligned with ``p`` (e.g. ``x_aligned`` of `compensate_lag`).
    p : array_like of float, shape (n,)
        Pressure in bar (e.g. ``p_aligned``); its maximum must be > 0.

    Returns
    -------
    dict
        ``rms``: root-mean-square of ``p/max(p) - xi`` over the samples;
        ``md``: largest ``|p/max(p) - xi|``;
        ``p_max``: the normalising maximum ``max(p)`` in bar (so that the normalised curve
        for a plot is ``p/p_max``).

    Raises
    ------
    ValueError
        If the arrays are not finite, one-dimensional and of one length, or ``max(p) <= 0``.

    Notes
    -----
    Fig. 8 of the paper plots the input fraction against the pressure normalised to its
    maximum, after compensating the phase lag, and compares it with the identity line.
    Deviations are vertical (in normalised pressure), not perpendicular to the line. Only the
    pressure is normalised; ``xi`` is used as given. The figure depends on the samples'
    distribution over ``xi`` (a sine spends more time near its extremes), so compare runs
    with the same input.

    Examples
    --------
    >>> r = sine_linearity([0.0, 0.5, 1.0], [0.0, 0.3, 0.8])
    >>> {k: round(v, 6) for k, v in r.items()}
    {'rms': 0.072169, 'md': 0.125, 'p_max': 0.8}
    """
    x = _array("xi", xi)
    pp = _array("p", p)
    if pp.size != x.size:
        raise ValueError(f"p must have the same length as xi ({x.size}), got {pp.size}")
    p_max = float(pp.max())
    if p_max <= 0.0:
        raise ValueError(f"p must have a positive maximum to be normalised, got max(p) = {p_max!r}")
    dev = pp / p_max - x
    return {
        "rms": float(np.sqrt(np.mean(dev**2))),
        "md": float(np.max(np.abs(dev))),
        "p_max": p_max,
    }
