"""Step time constants of a staircase: time to 63.2 % of each level change."""

from __future__ import annotations

import numpy as np
import numpy.typing as npt
import pandas as pd

from spa.openloop._arrays import TAU_FRACTION, _array, _fraction, _nonnegative, _time
from spa.openloop.levels import _staircase

__all__ = ["step_time_constants"]


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
