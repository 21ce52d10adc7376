"""The exact sensitivities of the time maps' simulation to the laws and the delays.

In a mode the pressure after ``e`` s is ``p = T⁻¹(T(p0; θ) + e; θ)``
(:mod:`spa.model.laws.timemap`). With ``S_θ(p) = ∂T(p; θ)/∂θ = -∫^p (∂f/∂θ)/f² dp'`` at fixed
pressure,

    ∂p/∂θ = f(p)·(∂p0/∂θ / f(p0) + S_θ(p0) − S_θ(p) + ∂e/∂θ).

``S_θ`` is tabulated per law coefficient and mode by the same composite Gauss–Legendre
quadrature as ``T`` (integrand in ``y``: ``-ℓ_i(p/k2)·dT/dy`` for ``log_g[i]`` or
``log_h[i]``, ``ℓ_i`` the Lagrange basis at the knots; ``-ln(p/k2)·dT/dy`` for ``m``), then
re-tabulated on the inverse grid of ``T``, where ``dS_θ/dT`` is ``-ℓ_i`` or ``-ln(p/k2)``.
Each run's start pressure chains the same way, one compiled step per run
(:func:`~spa.model.laws._sens_kernel.chain_sensitivity`). Under the hold convention a run's
active time and its samples' elapsed time shrink by the run's hold (``t_on`` on rising
runs, ``t_off`` on falling ones).

``log k2`` moves the knots, the discharge's scale ``k2**(1/2 - m)`` and the charge's zero.
While exhausting, ``∂ln f/∂ln k2 = 1/2 - m - s·b'(s)`` (``s = p/k2``; the origin of ``T``
moves too, by a constant that cancels). While charging it is taken at a fixed distance
``q = k2 - p``, where ``∂ln f/∂ln k2 = a'(s)·(1 - s)`` stays bounded; back in ``p`` that adds
``k2·(1 - f(p)/f(p0))``.

Covered: the hold convention, start pressures within ``[0, k2]``. Not covered (the caller
falls back to a finite difference): the transport convention (the delays move the runs'
edges), a charge started at or above ``k2`` and a discharge started above it (the closed
forms beyond ``k2``).
"""

from __future__ import annotations

from functools import lru_cache
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

from spa.model.laws._sens_kernel import chain_sensitivity
from spa.model.laws.rates import valve_laws
from spa.model.laws.timemap import (
    _GL_W,
    _GL_X,
    NODES,
    _cached_mode,
    _dtdy,
    _Mode,
    _mode_valve,
    law_tables,
)

if TYPE_CHECKING:  # pragma: no cover
    from spa.model.params import ValveParams

__all__ = ["law_replay_sensitivity", "law_tangents", "sensitivity_covered"]


def _lagrange(knots: tuple[float, ...]) -> np.ndarray:
    """Monomial coefficients of the Lagrange basis at ``knots``: column ``i`` is ``ℓ_i``."""
    s = np.asarray(knots)
    return np.linalg.solve(np.vander(s, increasing=True), np.eye(s.size))


def _basis(s: np.ndarray, knots: tuple[float, ...]) -> np.ndarray:
    """``ℓ_i(s)`` for every knot, shape ``s.shape + (len(knots),)``."""
    c = _lagrange(knots)  # (deg+1, n)
    out = np.zeros((*s.shape, c.shape[1]))
    for k in range(c.shape[0] - 1, -1, -1):
        out = out * s[..., None] + c[k]
    return out


def _dlog_rate(p: np.ndarray, params: ValveParams, on: bool) -> np.ndarray:
    """``∂ln f/∂θ`` at ``p`` for the mode's law coefficients: ``ℓ_i(p/k2)`` per knot, then
    ``ln(p/k2)`` for ``m`` when exhausting; shape ``p.shape + (columns,)``."""
    lw = valve_laws(params)
    s = np.clip(p / params.k2, 0.0, 1.0)
    basis = _basis(s, lw.knots)
    da, db = lw.log_rates(s, derivative=True)
    if on:
        # log k2 at fixed distance q = k2 - p (smooth; the rest is added in closed form)
        return np.concatenate((basis, (da * (1.0 - s))[..., None]), axis=-1)
    with np.errstate(divide="ignore"):
        lnp = np.log(np.maximum(p, params.k2 * 1e-300) / params.k2)
    k2col = (0.5 - lw.m) - s * db
    return np.concatenate((basis, lnp[..., None], k2col[..., None]), axis=-1)


@lru_cache(maxsize=128)
def _tangent(params: ValveParams, on: bool, nodes: int) -> np.ndarray:
    """``(columns, 4, nodes)``: Hermite coefficients of ``S_θ`` on the mode's inverse grid
    (``params`` reduced by :func:`~spa.model.laws.timemap._mode_valve`)."""
    mode: _Mode = _cached_mode(params, on, nodes)
    k2 = params.k2
    ny = mode.ty.size - 1
    hy = mode.hy
    yn = mode.y0 + hy * np.arange(ny + 1)
    # S at the forward nodes: composite Gauss–Legendre of -dlnf/dθ · dT/dy.
    yq = (yn[:-1, None] + 0.5 * hy) + (0.5 * hy) * _GL_X[None, :]
    wq, pq = _dtdy(yq, params, on)
    integrand = -_dlog_rate(pq, params, on) * wq[..., None]  # (ny, 8, cols)
    sy = np.concatenate(
        (
            np.zeros((1, integrand.shape[-1])),
            np.cumsum((0.5 * hy) * np.einsum("qkc,k->qc", integrand, _GL_W), axis=0),
        )
    )
    wn, pn = _dtdy(yn, params, on)
    sw = -_dlog_rate(pn, params, on) * (wn * hy)[:, None]
    # S at the inverse nodes: Hermite in y.
    p = mode.coef[:, 0]
    y = mode.coordinate(p, k2)
    u = np.clip((y - mode.y0) / hy, 0.0, float(ny))
    i = np.minimum(u.astype(np.int64), ny - 1)
    s = (u - i)[:, None]
    t0, t1, w0, w1 = sy[i], sy[i + 1], sw[i], sw[i + 1]
    c2 = 3.0 * (t1 - t0) - 2.0 * w0 - w1
    c3 = 2.0 * (t0 - t1) + w0 + w1
    sv = t0 + s * (w0 + s * (c2 + s * c3))  # (nodes, cols)
    d = -_dlog_rate(p, params, on) * (mode.t_end / (nodes - 1))
    d[-1] = 0.0
    coef = np.zeros((sv.shape[1], 4, nodes))
    coef[:, 0] = sv.T
    coef[:, 1, :-1] = d[:-1].T
    coef[:, 2, :-1] = (3.0 * (sv[1:] - sv[:-1]) - 2.0 * d[:-1] - d[1:]).T
    coef[:, 3, :-1] = (2.0 * (sv[:-1] - sv[1:]) + d[:-1] + d[1:]).T
    return coef


@lru_cache(maxsize=8)
def law_tangents(params: ValveParams, nodes: int = NODES) -> np.ndarray:
    """``(2n + 2, 4, 2*nodes)``: Hermite coefficients of ``S_θ`` for ``θ`` = ``log_g[i]``,
    ``log_h[i]``, ``m``, ``log k2`` on both modes' inverse grids (``log k2``'s while charging
    at a fixed distance to ``k2``) (zero where the mode does not read the
    coefficient), laid out as :attr:`~spa.model.laws.timemap.LawTables.coef`; cached (a
    fit's Jacobian reads it once per run)."""
    n = len(valve_laws(params).knots)
    ch = _tangent(_mode_valve(params, True), True, nodes)
    dis = _tangent(_mode_valve(params, False), False, nodes)
    out = np.zeros((2 * n + 2, 4, 2 * nodes))
    out[:n, :, :nodes] = ch[:n]
    out[-1, :, :nodes] = ch[n]
    out[n:, :, nodes:] = dis
    return out


def sensitivity_covered(
    level: npt.NDArray[np.bool_], p_start: npt.NDArray[np.float64], k2: float, top: float
) -> bool:
    """Whether every run starts where the exact sensitivities hold: a charge below the charge
    table's last pressure ``top``, a discharge at or below ``k2``."""
    return not bool(np.any(np.where(level, p_start >= top, p_start > k2)))


def law_replay_sensitivity(
    t: npt.NDArray[np.float64],
    starts: npt.NDArray[np.float64],
    level: npt.NDArray[np.bool_],
    hold: npt.NDArray[np.float64],
    p0: float,
    params: ValveParams,
    *,
    nodes: int = NODES,
    counts: npt.NDArray[np.int64] | None = None,
) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]] | None:
    """:func:`~spa.model.laws.timemap.law_replay` (hold convention) and its exact
    derivatives in ``log_g[i]``, ``log_h[i]``, ``m``, ``log k2``, ``t_on`` and ``t_off``.

    The arguments are :func:`~spa.model.laws.timemap.law_replay`'s. ``hold[r]`` is taken as
    ``t_on`` on a rising run and ``t_off`` on a falling one, except the first run's.

    Returns
    -------
    (p, dp) or None
        The pressure at ``t`` and ``(t.size, 2n + 4)`` derivatives, in the order of
        :func:`~spa.identification.laws_model.law_names`; None when a run starts
        outside ``[0, k2]`` (see the module's notes): the caller differentiates
        numerically.
    """
    from spa.model.laws.timemap import law_run_start_pressures

    tab = law_tables(params, nodes)
    n = len(valve_laws(params).knots)
    ncol = 2 * n + 4
    level = np.asarray(level, dtype=np.bool_)
    ends = np.append(starts[1:], np.inf)
    active = np.maximum(ends - starts - hold, 0.0)
    p_start = law_run_start_pressures(level, active, p0, params, nodes)
    if not sensitivity_covered(level, p_start, tab.k2, float(tab.charge.coef[-1, 0])):
        return None
    rising = level.copy()
    rising[0] = False
    falling = ~level
    falling[0] = False
    dhold = np.zeros((level.size, ncol))
    dhold[rising, 2 * n + 2] = 1.0
    dhold[falling, 2 * n + 3] = 1.0
    t0 = np.empty(level.size)
    t0[level] = tab.charge.forward(p_start[level], tab.k2)
    t0[~level] = tab.discharge.forward(p_start[~level], tab.k2)
    inv_h = np.array([tab.charge.inv_h, tab.discharge.inv_h])
    t_end = np.array([tab.charge.t_end, tab.discharge.t_end])
    scoef = law_tangents(params, nodes)
    coef = tab.kernel_args[-1]
    _, base = chain_sensitivity(
        level, active, -dhold, p_start, t0, inv_h, t_end, coef, scoef, tab.k2
    )
    if counts is None:
        j = np.maximum(np.searchsorted(starts, t, side="right") - 1, 0)
        counts = np.bincount(j, minlength=starts.size)
    run = np.repeat(np.arange(level.size), counts)
    lv = level[run]
    e = t - (starts + hold)[run]
    stop = np.where(level, t_end[0], t_end[1]) - t0
    ih = np.where(lv, inv_h[0], inv_h[1])
    ee = np.minimum(np.maximum(e, 0.0), stop[run])
    u = np.maximum(ee * ih + (t0 * np.where(level, inv_h[0], inv_h[1]))[run], 0.0)
    u += np.where(lv, 0.0, float(nodes))
    i = u.astype(np.int64)
    s = u - i
    c0, c1, c2, c3 = coef
    p = ((c3.take(i) * s + c2.take(i)) * s + c1.take(i)) * s + c0.take(i)
    f = (c1.take(i) + s * (2.0 * c2.take(i) + 3.0 * s * c3.take(i))) * ih
    dp = base[run]
    for c in range(2 * n + 2):
        sc = scoef[c]
        dp[:, c] -= ((sc[3].take(i) * s + sc[2].take(i)) * s + sc[1].take(i)) * s + sc[0].take(i)
    moving = (e > 0.0) & (e < stop[run])
    dp -= dhold[run] * moving[:, None]
    dp *= f[:, None]
    # log k2 while charging: the pressure is k2 - q, q's map moves as tabulated
    u0 = (t0 * np.where(level, inv_h[0], inv_h[1]))[level]
    i0 = np.minimum(u0.astype(np.int64), nodes - 1)
    s0 = u0 - i0
    f0 = np.zeros(level.size)
    f0[level] = (c1.take(i0) + s0 * (2.0 * c2.take(i0) + 3.0 * s0 * c3.take(i0))) * inv_h[0]
    with np.errstate(divide="ignore", invalid="ignore"):
        extra = np.where(lv & (f0[run] != 0.0), tab.k2 * (1.0 - f / f0[run]), 0.0)
    dp[:, 2 * n + 1] += extra
    return p, dp
