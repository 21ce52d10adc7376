"""Long-run covariance of correlated residuals: the Newey–West estimator with a Bartlett
kernel and its bandwidth chosen from the data (Andrews 1991), for the refinement's
intervals (:mod:`spa.identification.refine`)."""

from __future__ import annotations

import math

import numpy as np

from spa.identification.results import FloatArray

__all__ = ["andrews_bandwidth", "block_means", "correlation", "newey_west"]


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


def correlation(cov: FloatArray) -> tuple[tuple[float, ...], ...]:
    """The correlation matrix of a covariance (a variance of 0 correlates with nothing).

    Examples
    --------
    >>> correlation(np.array([[4.0, 2.0], [2.0, 4.0]]))
    ((1.0, 0.5), (0.5, 1.0))
    """
    sd = np.sqrt(np.maximum(np.diag(cov), 0.0))
    scale = np.where(sd > 0, sd, 1.0)
    corr = np.clip(cov / np.outer(scale, scale), -1.0, 1.0)
    corr[sd == 0, :] = 0.0
    corr[:, sd == 0] = 0.0
    np.fill_diagonal(corr, 1.0)
    return tuple(tuple(round(float(v), 6) for v in row) for row in corr)


def block_means(x: FloatArray, block: int) -> FloatArray:
    """Means of ``x`` over consecutive blocks of ``block`` samples (the last may be shorter),
    along its first axis (a column per derivative, for instance).

    Examples
    --------
    >>> block_means(np.arange(5.0), 2).tolist()
    [0.5, 2.5, 4.0]
    >>> block_means(np.arange(6.0).reshape(3, 2), 2).tolist()
    [[1.0, 2.0], [4.0, 5.0]]
    """
    x = np.asarray(x, dtype=np.float64)
    if block <= 1:
        return x
    n = x.shape[0]
    idx = np.arange(0, n, block)
    sums = np.add.reduceat(x, idx, axis=0)
    return sums / np.diff(np.append(idx, n)).reshape(-1, *(1,) * (x.ndim - 1))
