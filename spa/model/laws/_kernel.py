"""Compiled scalar step of the time maps (:mod:`spa.model.laws.timemap`): the chain of run
starts, one step per run, and a per-sample step a compiled loop can call."""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(cache=True)
def law_step(
    on: bool,
    p: float,
    active: float,
    k2: float,
    m: float,
    g_top: float,
    h_top: float,
    eps: float,
    y0: np.ndarray,
    hy: np.ndarray,
    ty: np.ndarray,
    wy: np.ndarray,
    t_end: np.ndarray,
    inv_h: np.ndarray,
    coef: np.ndarray,
) -> float:  # pragma: no cover (compiled; checked against law_segment_pressure)
    """One mode's pressure after ``active`` s from ``p``: ``T⁻¹(T(p) + active)``.

    Mode index ``j`` is 0 while charging and 1 while exhausting; ``ty[j]``, ``wy[j]`` the
    forward table on ``y0[j] + i*hy[j]``; ``coef[:, j*nodes:(j+1)*nodes]`` the inverse
    Hermite coefficients (as :class:`~spa.model.laws.timemap.LawTables`).
    """
    e = max(active, 0.0)
    j = 0 if on else 1
    nodes = coef.shape[1] // 2
    if on and p >= coef[0, nodes - 1]:
        return k2 + (p - k2) * math.exp(-g_top * e)
    if not on and p > k2:
        if m == 1.0:
            reach = math.log(p / k2) / h_top
        else:
            reach = (p ** (1.0 - m) - k2 ** (1.0 - m)) / ((1.0 - m) * h_top)
        if e < reach:
            if m == 1.0:
                return p * math.exp(-h_top * e)
            z = max(p ** (1.0 - m) - (1.0 - m) * h_top * e, 0.0)
            return z ** (1.0 / (1.0 - m))
        t0 = -reach
    else:
        if on:
            y = -math.log(max(k2 - p, k2 * eps))
        else:
            y = -math.log(max(p, k2 * eps))
        last = ty.shape[1] - 1
        u = min(max((y - y0[j]) / hy[j], 0.0), float(last))
        i = min(int(u), last - 1)
        s = u - i
        ta, tb, wa, wb = ty[j, i], ty[j, i + 1], wy[j, i], wy[j, i + 1]
        c2 = 3.0 * (tb - ta) - 2.0 * wa - wb
        c3 = 2.0 * (ta - tb) + wa + wb
        t0 = ta + s * (wa + s * (c2 + s * c3))
    u = max((t0 + min(e, t_end[j] - t0)) * inv_h[j], 0.0)
    i = int(u)
    s = u - i
    i += j * nodes
    return ((coef[3, i] * s + coef[2, i]) * s + coef[1, i]) * s + coef[0, i]


@njit(cache=True)
def law_chain(
    level: np.ndarray,
    active: np.ndarray,
    p0: float,
    k2: float,
    m: float,
    g_top: float,
    h_top: float,
    eps: float,
    y0: np.ndarray,
    hy: np.ndarray,
    ty: np.ndarray,
    wy: np.ndarray,
    t_end: np.ndarray,
    inv_h: np.ndarray,
    coef: np.ndarray,
) -> np.ndarray:  # pragma: no cover (compiled; checked against law_segment_pressure)
    """Pressure at the start of every run (:func:`law_step` chained)."""
    out = np.empty(level.size)
    p = p0
    for r in range(level.size):
        out[r] = p
        p = law_step(
            level[r], p, active[r], k2, m, g_top, h_top, eps, y0, hy, ty, wy, t_end, inv_h, coef
        )
    return out
