"""Sine linearity: lag compensation by cross-correlation and the deviation from the line."""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from spa._signal import correlate, correlation_lags
from spa.openloop._arrays import _array, _nonnegative, _time

__all__ = ["compensate_lag", "sine_linearity"]

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
    t_aligned, x_aligned, p_aligned : numpy.ndarray, shape (n - abs(L),)
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
    corr = correlate(pp - pp.mean(), x - x.mean())
    lags = correlation_lags(n, n)  # corr[i] = sum_k p[k + lags[i]]*x[k]
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
        ``max_dev``: largest ``|p/max(p) - xi|``;
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
    {'rms': 0.072169, 'max_dev': 0.125, 'p_max': 0.8}
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
        "max_dev": float(np.max(np.abs(dev))),
        "p_max": p_max,
    }
