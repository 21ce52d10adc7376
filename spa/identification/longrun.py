"""Long-run covariance of correlated residuals: the Newey–West estimator with a Bartlett
kernel and its bandwidth chosen from the data (Andrews 1991), for the refinement's
intervals (:mod:`spa.identification.refine`)."""

from __future__ import annotations

import math

import numpy as np

from spa.identification.results import FloatArray

__all__ = ["andrews_bandwidth", "newey_west"]


def andrews_bandwidth(e: FloatArray) -> int:
    """Bartlett-kernel bandwidth from the data (Andrews 1991, AR(1) plug-in).

    ``1.1447*(alpha*n)**(1/3)`` with ``alpha = 4*rho**2/((1-rho)**2*(1+rho)**2)`` and
    ``rho`` the lag-1 autocorrelation of ``e``; 0 for white residuals, at most ``n - 1``.

    Examples
    --------
    >>> andrews_bandwidth(np.array([1.0, -1.0] * 50))
    0
    """
    n = e.size
    if n < 3:
        return 0
    x = e - e.mean()
    den = float(np.dot(x[:-1], x[:-1]))
    if den <= 0:
        return 0
    rho = float(np.clip(np.dot(x[1:], x[:-1]) / den, -0.97, 0.97))
    if rho <= 0:
        return 0
    alpha = 4 * rho**2 / ((1 - rho) ** 2 * (1 + rho) ** 2)
    return int(min(n - 1, math.floor(1.1447 * (alpha * n) ** (1 / 3))))


def newey_west(scores: FloatArray, lag: int) -> FloatArray:
    """Long-run covariance ``sum_k w_k * Gamma_k`` of score rows (Bartlett weights).

    Parameters
    ----------
    scores : numpy.ndarray, shape (n, m)
        One row per observation (Jacobian row times residual), mean zero at the optimum.
    lag : int
        Bandwidth; 0 gives ``scores.T @ scores``.

    Returns
    -------
    numpy.ndarray, shape (m, m)
    """
    s = np.asarray(scores, dtype=np.float64)
    omega = s.T @ s
    for k in range(1, min(lag, s.shape[0] - 1) + 1):
        g = s[k:].T @ s[:-k]
        omega += (1.0 - k / (lag + 1.0)) * (g + g.T)
    return omega
