"""Compiled chain of the run starts' sensitivities under the time maps
(:mod:`spa.model.laws.sensitivity`), and its plain-Python twin that checks it."""

from __future__ import annotations

import numpy as np
from numba import njit


def chain_sensitivity_py(
    level: np.ndarray,
    active: np.ndarray,
    dactive: np.ndarray,
    p_start: np.ndarray,
    t0: np.ndarray,
    inv_h: np.ndarray,
    t_end: np.ndarray,
    coef: np.ndarray,
    scoef: np.ndarray,
    k2: float,
) -> tuple[np.ndarray, np.ndarray]:
    """Plain-Python :func:`chain_sensitivity` (the reference its compiled twin is checked
    against; same arguments and results)."""
    nodes = coef.shape[1] // 2
    ncol = dactive.shape[1]
    nlaw = scoef.shape[0]
    dp = np.zeros((level.size, ncol))
    base = np.zeros((level.size, ncol))
    d = np.zeros(ncol)
    for r in range(level.size):
        dp[r] = d
        j = 0 if level[r] else 1
        u0 = max(t0[r] * inv_h[j], 0.0)
        i0 = min(int(u0), nodes - 1)
        s0 = u0 - i0
        k0 = i0 + j * nodes
        f0 = (coef[1, k0] + s0 * (2.0 * coef[2, k0] + 3.0 * s0 * coef[3, k0])) * inv_h[j]
        a = d / f0 if f0 != 0.0 else np.zeros(ncol)
        for c in range(nlaw):
            a[c] += ((scoef[c, 3, k0] * s0 + scoef[c, 2, k0]) * s0 + scoef[c, 1, k0]) * s0 + scoef[
                c, 0, k0
            ]
        base[r] = a
        e = max(active[r], 0.0)
        clamped = e >= t_end[j] - t0[r]
        u1 = max((t0[r] + min(e, t_end[j] - t0[r])) * inv_h[j], 0.0)
        i1 = min(int(u1), nodes - 1)
        s1 = u1 - i1
        k1 = i1 + j * nodes
        f1 = (coef[1, k1] + s1 * (2.0 * coef[2, k1] + 3.0 * s1 * coef[3, k1])) * inv_h[j]
        d = a.copy()
        for c in range(nlaw):
            d[c] -= ((scoef[c, 3, k1] * s1 + scoef[c, 2, k1]) * s1 + scoef[c, 1, k1]) * s1 + scoef[
                c, 0, k1
            ]
        if active[r] > 0.0 and not clamped:
            d += dactive[r]
        d = d * f1
        if j == 0 and f0 != 0.0:
            d[nlaw - 1] += k2 * (1.0 - f1 / f0)
    return dp, base


@njit(cache=True)
def chain_sensitivity(
    level: np.ndarray,
    active: np.ndarray,
    dactive: np.ndarray,
    p_start: np.ndarray,
    t0: np.ndarray,
    inv_h: np.ndarray,
    t_end: np.ndarray,
    coef: np.ndarray,
    scoef: np.ndarray,
    k2: float,
) -> tuple[np.ndarray, np.ndarray]:  # pragma: no cover (compiled; checked against the twin)
    """Sensitivities of every run's start pressure, and each run's base term.

    Run ``r`` starts at ``p_r`` in its mode ``j`` (0 charging, 1 exhausting), at ``T = t0[r]``
    of that mode's time map, and lasts ``active[r]`` s. Its end is ``p' = T⁻¹(T(p_r) +
    active)``, so ``dp'/dθ = f(p')·(dp_r/dθ / f(p_r) + S_θ(p_r) − S_θ(p') + dactive/dθ)``
    with ``S_θ = ∂T/∂θ`` at fixed pressure (zero past the table's end, where ``p'`` is
    clamped).

    Parameters
    ----------
    level, active : numpy.ndarray
        Each run's mode (True charging) and active time, s.
    dactive : numpy.ndarray
        ``(runs, ncol)``: the active time's derivative in each column.
    p_start : numpy.ndarray
        Each run's start pressure (unused; kept for the signature's symmetry with the twin).
    t0 : numpy.ndarray
        ``T(p_r)`` of each run's mode.
    inv_h, t_end, coef : numpy.ndarray
        The time maps' inverse tables (:class:`~spa.model.laws.timemap.LawTables`).
    scoef : numpy.ndarray
        ``(nlaw, 4, 2*nodes)``: Hermite coefficients of ``S_θ`` on the inverse grid, one per
        law coefficient (the first ``nlaw`` columns, the last ``log k2``: while charging at
        a fixed distance ``q = k2 - p``, so ``p``'s gains ``k2·(1 - f(p')/f(p_r))``).
    k2 : float
        The supply pressure, bar.

    Returns
    -------
    dp : numpy.ndarray
        ``(runs, ncol)``: ``dp_r/dθ``.
    base : numpy.ndarray
        ``(runs, ncol)``: ``dp_r/dθ / f(p_r) + S_θ(p_r)``, the run's samples' common term.
    """
    nodes = coef.shape[1] // 2
    ncol = dactive.shape[1]
    nlaw = scoef.shape[0]
    dp = np.zeros((level.size, ncol))
    base = np.zeros((level.size, ncol))
    d = np.zeros(ncol)
    a = np.zeros(ncol)
    for r in range(level.size):
        for c in range(ncol):
            dp[r, c] = d[c]
        j = 0 if level[r] else 1
        u0 = max(t0[r] * inv_h[j], 0.0)
        i0 = min(int(u0), nodes - 1)
        s0 = u0 - i0
        k0 = i0 + j * nodes
        f0 = (coef[1, k0] + s0 * (2.0 * coef[2, k0] + 3.0 * s0 * coef[3, k0])) * inv_h[j]
        for c in range(ncol):
            a[c] = d[c] / f0 if f0 != 0.0 else 0.0
        for c in range(nlaw):
            a[c] += ((scoef[c, 3, k0] * s0 + scoef[c, 2, k0]) * s0 + scoef[c, 1, k0]) * s0 + scoef[
                c, 0, k0
            ]
        for c in range(ncol):
            base[r, c] = a[c]
        e = max(active[r], 0.0)
        left = t_end[j] - t0[r]
        clamped = e >= left
        u1 = max((t0[r] + min(e, left)) * inv_h[j], 0.0)
        i1 = min(int(u1), nodes - 1)
        s1 = u1 - i1
        k1 = i1 + j * nodes
        f1 = (coef[1, k1] + s1 * (2.0 * coef[2, k1] + 3.0 * s1 * coef[3, k1])) * inv_h[j]
        for c in range(ncol):
            d[c] = a[c]
        for c in range(nlaw):
            d[c] -= ((scoef[c, 3, k1] * s1 + scoef[c, 2, k1]) * s1 + scoef[c, 1, k1]) * s1 + scoef[
                c, 0, k1
            ]
        if active[r] > 0.0 and not clamped:
            for c in range(ncol):
                d[c] += dactive[r, c]
        for c in range(ncol):
            d[c] *= f1
        if j == 0 and f0 != 0.0:
            d[nlaw - 1] += k2 * (1.0 - f1 / f0)
    return dp, base
