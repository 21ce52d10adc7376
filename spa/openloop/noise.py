"""Chattering without the sensor's noise: variance subtraction on a staircase's levels.

The peak-to-peak ripple of a level (``p_ripple`` of `spa.openloop.levels.staircase_levels`)
grows with the sensor's noise: over the 2,000 samples of a 2 s window at 1 kHz, Gaussian
noise of standard deviation ``s`` alone spans about ``7*s`` (35 mbar for 5 mbar), more than
the chattering of the paper's settings (16-22 mbar). Noise and chattering are independent,
so their variances add: the noise's variance, measured on levels where the valve does not
move and the pressure has settled, is subtracted from each level's ripple variance.

* `sensor_noise`: the noise's standard deviation, pooled over the still levels.
* `corrected_ripple`: the ripple's standard deviation without the noise, and the
  peak-to-peak it stands for.
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from spa.openloop._arrays import _array

__all__ = ["TRIANGLE_PP_PER_SD", "corrected_ripple", "sensor_noise"]

#: Peak-to-peak over standard deviation of a triangle (or sawtooth) wave: ``sqrt(12)``.
#: Chattering at equilibrium rises and falls almost linearly between its extremes (each
#: pulse covers a small part of an exponential), so its values are nearly uniform over its
#: range, whose standard deviation is the range over ``sqrt(12)``.
TRIANGLE_PP_PER_SD = math.sqrt(12.0)


def sensor_noise(
    p_ripple_sd: npt.ArrayLike,
    n_window: npt.ArrayLike,
    still: npt.ArrayLike,
    p_drift: npt.ArrayLike | None = None,
    max_drift: float = 0.005,
) -> tuple[float, int]:
    """Standard deviation of the sensor's noise, from the levels where nothing moves.

    Parameters
    ----------
    p_ripple_sd : array_like of float, shape (k,)
        Each level's standard deviation about its window's line (bar).
    n_window : array_like of int, shape (k,)
        Samples in each level's window (the weights of the pooled variance).
    still : array_like of bool, shape (k,)
        Levels whose window has no valve edge (``switching_rate == 0``).
    p_drift : array_like of float, shape (k,), optional
        Each level's drift across its window (bar); levels drifting by more than
        ``max_drift`` are still settling and are left out.
    max_drift : float, default 0.005
        Largest ``|p_drift|`` of a settled level, bar.

    Returns
    -------
    noise_sd : float
        ``sqrt(sum(n_i*sd_i**2) / sum(n_i))`` over the still, settled levels (bar); NaN if
        there is none.
    n_levels : int
        How many levels it pools.

    Examples
    --------
    >>> sensor_noise([0.005, 0.02, 0.005], [100, 100, 300], [True, False, True])
    (0.005, 2)
    >>> sensor_noise([0.02], [100], [False])
    (nan, 0)
    """
    sd = _array("p_ripple_sd", p_ripple_sd)
    n = _array("n_window", n_window, size=sd.size)
    use = np.asarray(still, dtype=bool).copy()
    if use.shape != sd.shape:
        raise ValueError(f"still must have the shape of p_ripple_sd {sd.shape}, got {use.shape}")
    if p_drift is not None:
        use &= np.abs(_array("p_drift", p_drift, size=sd.size)) <= max_drift
    if not use.any():
        return math.nan, 0
    pooled = float(np.sqrt(np.sum(n[use] * sd[use] ** 2) / np.sum(n[use])))
    return pooled, int(use.sum())


def corrected_ripple(
    p_ripple_sd: npt.ArrayLike, noise_sd: float
) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
    """A level's ripple without the sensor's noise (variance subtraction).

    Parameters
    ----------
    p_ripple_sd : array_like of float, shape (k,)
        Each level's standard deviation about its window's line (bar).
    noise_sd : float
        The sensor's noise (`sensor_noise`), bar; NaN gives NaN.

    Returns
    -------
    sd : numpy.ndarray, shape (k,)
        ``sqrt(max(p_ripple_sd**2 - noise_sd**2, 0))`` (bar).
    pp : numpy.ndarray, shape (k,)
        The peak-to-peak chattering it stands for, ``TRIANGLE_PP_PER_SD*sd`` (bar): exact
        for a ripple that rises and falls linearly, to be compared with Appendix B's
        ``P+ - P-``.

    Examples
    --------
    >>> sd, pp = corrected_ripple([0.005, 0.013], 0.005)
    >>> sd.round(6).tolist(), pp.round(4).tolist()
    ([0.0, 0.012], [0.0, 0.0416])
    """
    sd = _array("p_ripple_sd", p_ripple_sd)
    noise = float(noise_sd)
    clean = np.sqrt(np.maximum(sd**2 - noise**2, 0.0))
    return clean, TRIANGLE_PP_PER_SD * clean
