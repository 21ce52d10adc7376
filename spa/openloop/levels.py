"""Staircase levels: equilibrium, spread and ripple per level, and the line fit of Table 3."""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt
import pandas as pd

from spa.openloop._arrays import _array, _fraction, _nonnegative, _time, _valve

__all__ = ["linear_fit_metrics", "staircase_levels"]

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
    p_ripple_sd = np.sqrt(_segment_sums(np.add, resid * resid, first, ends) / count)
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
        "p_ripple_sd": p_ripple_sd,
        "p_drift": slope * (t[ends - 1] - t[first]),
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
        ``p_ripple_sd``
            Standard deviation of ``p`` about that line (bar): the ripple as a variance,
            from which a sensor's noise variance can be subtracted
            (`spa.openloop.noise.corrected_ripple`).
        ``p_drift``
            Change of that line across the window (bar): how far the level is from settled
            (0 for a level that has settled).
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
    docs/model.md section 5: the equilibrium pressure of a level is the mean over the settled part
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
            "p_ripple_sd": lv["p_ripple_sd"],
            "p_drift": lv["p_drift"],
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
        ``mad`` (bar): mean absolute residual, the paper's MD (see Notes);
        ``max_dev`` (bar): largest absolute residual;
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

    The paper calls MD the "maximum deviation", but its Table 3 has ``MD < sqrt(MSE)`` in every
    row, which no largest residual can satisfy (the largest ``|r|`` is at least the RMS of
    ``r``), while the mean absolute residual always satisfies it; its MD/sqrt(MSE) ratios
    (0.81-0.89) are those of MAD/RMSE. So ``mad`` is compared with the paper's MD, and the
    largest residual is returned apart as ``max_dev``.

    Examples
    --------
    >>> r = linear_fit_metrics([0, 0.5, 1], [0, 0.5, 0.75])
    >>> {k: round(v, 6) for k, v in r.items()}  # doctest: +NORMALIZE_WHITESPACE
    {'m': 0.75, 'n': 0.041667, 'mse': 0.003472, 'mad': 0.055556, 'max_dev': 0.083333,
     'fit': 81.101776}
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
        "mad": float(np.mean(np.abs(resid))),
        "max_dev": float(np.max(np.abs(resid))),
        "fit": fit,
    }
