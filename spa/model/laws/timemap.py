"""Exact simulation of the two modes under general laws: the time map ``T(p) = ∫ dp/f(p)``.

In a mode of constant connection the pressure after ``t`` s is ``T⁻¹(T(p0) + t)``. ``T`` is
tabulated once per valve (:func:`law_tables`, cached):

* **forward**, on a uniform grid of a coordinate ``y`` in which ``dT/dy`` is smooth and
  bounded: ``y = -ln(k2 - p)`` while charging (``T`` diverges logarithmically at the
  simple zero ``p = k2``), ``y = -ln p`` while exhausting (the square-root zero is
  reached in finite time; at ``m = 1`` ``T`` diverges logarithmically). ``T`` at the nodes
  is the composite Gauss–Legendre integral of ``dT/dy``, exact to rounding;
* **inverse**, the pressure at uniformly spaced values of ``T`` (each node solved by Newton
  on the forward integral), interpolated by cubic Hermite polynomials with the exact
  slope ``dp/dT = f(p)``, so a sample costs one table look-up, no search.

The tables span ``[0, k2]``, the laws' domain; beyond ``k2`` the rates are held at their
values at ``k2`` and each mode has a closed form (a charge from above ``k2`` decays
exponentially at ``g(k2)``; a discharge from above ``k2`` follows ``p**(1-m)`` linearly, or
``ln p`` at ``m = 1``, until it reaches ``k2`` and enters its table). Beyond the table's end
the pressure is clamped: at 0 once the discharge has emptied the chamber (``m < 1``),
within ``1e-14*k2`` of ``k2`` or of 0 where ``T`` diverges.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property, lru_cache
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

from spa.model.laws._kernel import law_chain, law_step
from spa.model.laws.rates import law_rates, valve_laws

if TYPE_CHECKING:  # pragma: no cover
    from spa.model.params import ValveParams

__all__ = [
    "FIT_NODES",
    "NODES",
    "LawTables",
    "law_replay",
    "law_run_start_pressures",
    "law_segment_pressure",
    "law_tables",
]

_EPS = 1e-14  # the tables stop this close (relative to k2) to a divergence of T
#: Inverse nodes per mode of the simulation's time maps (:func:`law_tables`).
NODES = 1 << 15
#: Inverse nodes per mode of a fit's trial valves (:func:`law_tables`).
FIT_NODES = 1 << 11
_GL_X, _GL_W = np.polynomial.legendre.leggauss(8)


@dataclass(frozen=True)
class _Mode:
    """One mode's time map. ``coef[k]``: Hermite coefficients on ``[k, k + 1)`` in units of
    the inverse step (row ``nodes - 1`` is the clamp: the last pressure, constant)."""

    open: bool
    y0: float  # forward grid: y0 + i*hy
    hy: float
    ty: np.ndarray  # T at the forward nodes
    wy: np.ndarray  # dT/dy at the forward nodes, times hy
    t_end: float  # T of the last inverse node
    inv_h: float  # inverse nodes per second
    coef: np.ndarray  # (nodes, 4)

    def coordinate(self, p: np.ndarray, k2: float) -> np.ndarray:
        if self.open:
            return -np.log(np.maximum(k2 - p, k2 * _EPS))
        return -np.log(np.maximum(p, k2 * _EPS))

    def forward(self, p: npt.ArrayLike, k2: float) -> np.ndarray:
        """``T(p)``, clipped to the table's span."""
        y = self.coordinate(np.asarray(p, dtype=np.float64), k2)
        u = np.clip((y - self.y0) / self.hy, 0.0, self.ty.size - 1.0)
        i = np.minimum(u.astype(np.int64), self.ty.size - 2)
        s = u - i
        t0, t1, w0, w1 = self.ty[i], self.ty[i + 1], self.wy[i], self.wy[i + 1]
        c2 = 3.0 * (t1 - t0) - 2.0 * w0 - w1
        c3 = 2.0 * (t0 - t1) + w0 + w1
        return t0 + s * (w0 + s * (c2 + s * c3))


@dataclass(frozen=True)
class LawTables:
    """Both modes' time maps of one valve (:func:`law_tables`)."""

    k2: float
    charge: _Mode
    discharge: _Mode
    coef: np.ndarray  # (2*nodes, 4): charge rows then discharge rows
    g_top: float  # g(k2), the charge rate beyond the supply pressure
    h_top: float  # h(k2), the discharge rate's factor beyond the supply pressure
    m: float

    def mode(self, on: bool) -> _Mode:
        return self.charge if on else self.discharge

    @cached_property
    def kernel_args(self) -> tuple:
        """The tables as the arguments ``k2 ... coef`` of :func:`~spa.model.laws._kernel.law_step`
        (mode 0 charging, 1 exhausting)."""
        ch, dis = self.charge, self.discharge
        return (
            self.k2,
            self.m,
            self.g_top,
            self.h_top,
            _EPS,
            np.array([ch.y0, dis.y0]),
            np.array([ch.hy, dis.hy]),
            np.stack((ch.ty, dis.ty)),
            np.stack((ch.wy, dis.wy)),
            np.array([ch.t_end, dis.t_end]),
            np.array([ch.inv_h, dis.inv_h]),
            np.ascontiguousarray(self.coef.T),
        )

    def step(self, on: bool, p: float, active: float) -> float:
        """One mode's pressure after ``active`` s from ``p``, on plain floats: the same table
        and formulas as :func:`law_segment_pressure`, compiled."""
        return float(law_step(bool(on), float(p), float(active), *self.kernel_args))


def _dtdy(y: np.ndarray, params: ValveParams, on: bool) -> tuple[np.ndarray, np.ndarray]:
    """``dT/dy`` and the pressure at the coordinate ``y``."""
    if on:
        p = params.k2 - np.exp(-y)
        g, _ = law_rates(p, params)
        return 1.0 / g, p
    p = np.exp(-y)
    _, h = law_rates(p, params)
    return p ** (1.0 - valve_laws(params).m) / h, p


def _mode(params: ValveParams, on: bool, nodes: int) -> _Mode:
    k2, m = params.k2, valve_laws(params).m
    ynodes = nodes // 2
    y0, y1 = -math.log(k2), -math.log(k2 * _EPS)
    hy = (y1 - y0) / ynodes
    yn = y0 + hy * np.arange(ynodes + 1)
    # Composite 8-point Gauss–Legendre: T at every forward node.
    yq = (yn[:-1, None] + 0.5 * hy) + (0.5 * hy) * _GL_X[None, :]
    wq, _ = _dtdy(yq, params, on)
    ty = np.concatenate(([0.0], np.cumsum((0.5 * hy) * (wq @ _GL_W))))
    wy, _ = _dtdy(yn, params, on)
    t_stop = float(ty[-1])
    # m < 1: the discharge empties the chamber in finite time; the remainder below k2*_EPS
    # is added when it is short (it is the law's own, with h held at h(0)).
    rest = 0.0
    if not on and m < 1.0:
        _, h0 = law_rates(0.0, params)
        rest = float((k2 * _EPS) ** (1.0 - m) / ((1.0 - m) * h0))
        if rest > 0.05 * t_stop:
            rest = 0.0
    t_end = t_stop + rest
    tn = np.linspace(0.0, t_end, nodes)
    inside = tn <= t_stop
    # Newton on the forward integral from the nearest forward node.
    ti = tn[inside]
    j = np.clip(np.searchsorted(ty, ti, side="right") - 1, 0, ynodes - 1)
    y = yn[j] + hy * (ti - ty[j]) / (ty[j + 1] - ty[j])
    for _ in range(3):
        y = np.clip(y, yn[j], yn[j + 1])
        half = 0.5 * (y - yn[j])
        w, _ = _dtdy((yn[j] + half)[:, None] + half[:, None] * _GL_X[None, :], params, on)
        t_y = ty[j] + half * (w @ _GL_W)
        w_end, _ = _dtdy(y, params, on)
        y = y - (t_y - ti) / w_end
    y = np.clip(y, yn[j], yn[j + 1])
    p = np.empty(nodes)
    p[inside] = k2 - np.exp(-y) if on else np.exp(-y)
    if rest > 0.0:
        _, h0 = law_rates(0.0, params)
        left = np.maximum(t_end - tn[~inside], 0.0)
        p[~inside] = ((1.0 - m) * float(h0) * left) ** (1.0 / (1.0 - m))
        p[-1] = 0.0
    g, h = law_rates(p, params)
    slope = (k2 - p) * g if on else -(p**m) * h
    d = slope * (t_end / (nodes - 1))
    coef = np.zeros((nodes, 4))
    coef[:, 0] = p
    coef[:-1, 1] = d[:-1]
    coef[:-1, 2] = 3.0 * (p[1:] - p[:-1]) - 2.0 * d[:-1] - d[1:]
    coef[:-1, 3] = 2.0 * (p[:-1] - p[1:]) + d[:-1] + d[1:]
    return _Mode(
        open=on,
        y0=y0,
        hy=hy,
        ty=ty,
        wy=wy * hy,
        t_end=t_end,
        inv_h=(nodes - 1) / t_end,
        coef=coef,
    )


def _mode_valve(params: ValveParams, on: bool) -> ValveParams:
    """``params`` with every field the mode's table does not read set to a fixed value: the
    charge's table reads ``k2``, ``tau2`` and ``log_g``; the discharge's ``k2``, ``c1``,
    ``log_h`` and ``m``. Neither reads the delays. So a fit's finite difference in one
    mode's coefficients, or in a delay, rebuilds no table of the other mode."""
    from spa.model.params import ValveParams

    lw = valve_laws(params)
    zeros = (0.0,) * len(lw.knots)
    if on:
        laws = type(lw)(log_g=lw.log_g, log_h=zeros, m=0.5, knots=lw.knots)
        return ValveParams(c1=1.0, k2=params.k2, tau2=params.tau2, t_on=0.0, t_off=0.0, laws=laws)
    laws = type(lw)(log_g=zeros, log_h=lw.log_h, m=lw.m, knots=lw.knots)
    return ValveParams(c1=params.c1, k2=params.k2, tau2=1.0, t_on=0.0, t_off=0.0, laws=laws)


@lru_cache(maxsize=128)
def _cached_mode(params: ValveParams, on: bool, nodes: int) -> _Mode:
    """:func:`_mode` of a valve reduced to what the mode reads (:func:`_mode_valve`)."""
    return _mode(params, on, nodes)


#: Valves whose time maps stay cached: a closed loop's promise runs the estimate and the 32
#: corners of its box at once (about 7 MB each at :data:`NODES`).
_CACHED = 64


@lru_cache(maxsize=_CACHED)
def law_tables(params: ValveParams, nodes: int = NODES) -> LawTables:
    """The valve's time maps, built once per valve (about 0.1 s) and cached.

    Parameters
    ----------
    params : ValveParams
        A valve with laws (``params.laws`` not None; the paper's laws have closed forms).
    nodes : int, optional
        Inverse nodes per mode (the forward grid has half as many intervals). The default
        keeps the simulation within 1e-11 bar of the ODE; the error grows as
        ``nodes**-4``, so a fit's trial valves may use a sixteenth of it
        (:data:`FIT_NODES`, about 1e-6 bar, built in about 10 ms).
    """
    charge, discharge = (
        _cached_mode(_mode_valve(params, True), True, nodes),
        _cached_mode(_mode_valve(params, False), False, nodes),
    )
    g_top, h_top = law_rates(params.k2, params)
    return LawTables(
        k2=params.k2,
        charge=charge,
        discharge=discharge,
        coef=np.concatenate((charge.coef, discharge.coef)),
        g_top=float(g_top),
        h_top=float(h_top),
        m=valve_laws(params).m,
    )


def _above(tab: LawTables, p0: np.ndarray, e: np.ndarray, on: bool) -> np.ndarray:
    """Closed forms above ``k2`` (rates held at their values there): a charge's pressure,
    or a discharge's time to reach ``k2`` (``e`` ignored) when ``e`` is None."""
    if on:
        return tab.k2 + (p0 - tab.k2) * np.exp(-tab.g_top * e)
    m = tab.m
    if m == 1.0:
        return p0 * np.exp(-tab.h_top * e)
    return np.maximum(p0 ** (1.0 - m) - (1.0 - m) * tab.h_top * e, 0.0) ** (1.0 / (1.0 - m))


def _reach_k2(tab: LawTables, p0: np.ndarray) -> np.ndarray:
    """Time a discharge from ``p0 > k2`` takes to reach ``k2`` (rates held above ``k2``)."""
    m = tab.m
    if m == 1.0:
        return np.log(p0 / tab.k2) / tab.h_top
    return (p0 ** (1.0 - m) - tab.k2 ** (1.0 - m)) / ((1.0 - m) * tab.h_top)


def _per_run(
    on: bool | npt.ArrayLike,
    p_start: npt.ArrayLike,
    elapsed: npt.ArrayLike,
    repeats: npt.ArrayLike | None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray | None, tuple[int, ...]]:
    e = np.asarray(elapsed, dtype=np.float64)
    if repeats is not None:
        p0 = np.asarray(p_start, dtype=np.float64)
        lv = np.broadcast_to(np.asarray(on, dtype=bool), p0.shape)
        return lv.ravel(), p0.ravel(), e.ravel(), np.asarray(repeats), e.shape
    lv, p0, e = np.broadcast_arrays(np.asarray(on, dtype=bool), np.asarray(p_start, float), e)
    return lv.ravel(), p0.ravel(), e.ravel(), None, e.shape


def law_segment_pressure(
    on: bool | npt.ArrayLike,
    p_start: npt.ArrayLike,
    elapsed: npt.ArrayLike,
    params: ValveParams,
    repeats: npt.ArrayLike | None = None,
    nodes: int = NODES,
) -> np.ndarray:
    """:func:`spa.model.plant.segment_pressure` for a valve with general laws.

    The arguments are those of :func:`~spa.model.plant.segment_pressure`. Each sample is
    ``T⁻¹(T(p_start) + elapsed)`` of its mode, read from :func:`law_tables` (``nodes``
    per mode).

    """
    tab = law_tables(params, nodes)
    lv, p0, e, counts, shape = _per_run(on, p_start, elapsed, repeats)
    t0 = np.empty(p0.shape)
    t0[lv] = tab.charge.forward(p0[lv], tab.k2)
    t0[~lv] = tab.discharge.forward(p0[~lv], tab.k2)
    high = ~lv & (p0 > tab.k2)
    if np.any(high):
        t0[high] = -_reach_k2(tab, p0[high])
    inv_h = np.where(lv, tab.charge.inv_h, tab.discharge.inv_h)
    stop = np.where(lv, tab.charge.t_end, tab.discharge.t_end) - t0
    base = t0 * inv_h + np.where(lv, 0.0, float(nodes))

    def rep(x: np.ndarray) -> np.ndarray:
        return x if counts is None else np.repeat(x, counts)

    u = np.maximum(e, 0.0)
    np.minimum(u, rep(stop), out=u)
    u *= rep(inv_h)
    u += rep(base)
    np.maximum(u, 0.0, out=u)
    i = u.astype(np.int64)
    u -= i
    c0, c1, c2, c3 = tab.kernel_args[-1]
    out = c3.take(i)
    out *= u
    out += c2.take(i)
    out *= u
    out += c1.take(i)
    out *= u
    out += c0.take(i)
    # Charges from at or above the supply pressure: f_open = (k2 - p)*g(k2) there, exactly
    # exponential (g is held constant beyond k2).
    above = lv & (p0 >= tab.charge.coef[-1, 0])
    if np.any(above):
        mask = rep(above)
        out[mask] = _above(tab, rep(p0)[mask], np.maximum(e[mask], 0.0), True)
    if np.any(high):
        mask = rep(high)
        ea = np.maximum(e[mask], 0.0)
        early = ea < rep(-t0)[mask]
        out[np.flatnonzero(mask)[early]] = _above(tab, rep(p0)[mask][early], ea[early], False)
    return out.reshape(shape)


def law_run_start_pressures(
    level: npt.NDArray[np.bool_],
    active: npt.NDArray[np.float64],
    p0: float,
    params: ValveParams,
    nodes: int = NODES,
) -> npt.NDArray[np.float64]:
    """:func:`spa.model.plant.run_start_pressures` for a valve with general laws: one
    scalar step per run, ``p = T⁻¹(T(p) + active)`` of the run's mode."""
    tab = law_tables(params, nodes)
    return law_chain(
        np.asarray(level, dtype=np.bool_),
        np.asarray(active, dtype=np.float64),
        float(p0),
        *tab.kernel_args,
    )


def law_replay(
    t: npt.NDArray[np.float64],
    starts: npt.NDArray[np.float64],
    level: npt.NDArray[np.bool_],
    hold: npt.NDArray[np.float64],
    p0: float,
    params: ValveParams,
    *,
    delay: str = "hold",
    nodes: int = NODES,
    counts: npt.NDArray[np.int64] | None = None,
) -> npt.NDArray[np.float64]:
    """:func:`spa.model.plant.replay` for a valve with general laws, at sorted times ``t``,
    with time maps of ``nodes`` per mode (:data:`FIT_NODES` for a fit's trial valves).

    ``counts``, the samples of ``t`` in each command run (the first takes those before
    it), saves the search when the caller already holds them; the hold convention's only:
    a transport delay moves the runs."""
    from spa.model.plant import transport_runs

    if delay == "transport":
        starts, level = transport_runs(starts, level, hold)
        hold = np.zeros(starts.size)
    ends = np.append(starts[1:], np.inf)
    active = np.maximum(ends - starts - hold, 0.0)
    p_start = law_run_start_pressures(level, active, p0, params, nodes)
    if counts is None or delay == "transport":
        j = np.maximum(np.searchsorted(starts, t, side="right") - 1, 0)
        counts = np.bincount(j, minlength=starts.size)
    elapsed = t - np.repeat(starts + hold, counts)
    return law_segment_pressure(level, p_start, elapsed, params, counts, nodes)
