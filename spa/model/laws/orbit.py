"""The exact periodic orbit of a constant input on a valve with laws (docs/model.md,
"The general two-mode model").

For a constant input every modulator repeats a pattern of alternating high and low runs, and
the exact plant settles on a periodic orbit. With the paper's laws the orbit has closed
forms (:mod:`spa.model.chattering`, :mod:`spa.model.periodic`); under general laws each
active part of a run is the mode's time map, ``T⁻¹(T(p) + a)``
(:func:`spa.model.laws.timemap.law_segment_pressure`), and no averaging is assumed: the
orbit is exact however long the cycle is against the local time constant.

* :func:`law_orbit` – the orbit of a batch of patterns: the pressure where each run starts
  and the cycle's time mean;
* :func:`law_train_orbit` – the orbit of a train of one high and one low pulse (PWM, IPFM,
  IIPFM): ``P+``, ``P-`` and the mean.

The cycle map ``F`` (the runs' time maps composed) is non-decreasing, with ``F(0) >= 0``
and ``F(k2) <= k2``, so ``[0, k2]`` brackets a fixed point. Its slope is the product over
the active parts of ``f(p_end)/f(p_start)`` (the flow's derivative in its start for an
autonomous one-dimensional law). Newton's method, kept inside the bracket and falling back
to bisection, finds the fixed point whether or not the laws make ``F`` convex.

Everything is read from the simulation's own time maps
(:func:`spa.model.laws.timemap.law_tables`), so the orbit is the one :func:`spa.simulate`
settles on: a part's end pressure is ``T⁻¹(T(p) + a)``, the rates ``f`` are the inverse's
exact slopes ``dp/dT``, and the integral of the pressure over a part is the integral of the
inverse's cubic pieces in ``T`` (a cumulative table, built once per valve). In pressure the
same integrals read

* charging: ``∫ p dt = k2*a - ∫ dp/g(p)``;
* discharging: ``∫ p dt = ∫ p**(1 - m)/h(p) dp``;

:func:`law_charge_integral` and :func:`law_discharge_integral` evaluate these by quadrature
(a reference for the tables). With the paper's laws they are ``k2*a - tau2*(P1 - P0)`` and
``(2*c1/3)*(P0**1.5 - P1**1.5)`` (:func:`spa.model.periodic.charge_integral`,
:func:`~spa.model.periodic.discharge_integral`).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np
import numpy.typing as npt

from spa.model.chattering import train_segments
from spa.model.laws.rates import law_rates, valve_laws
from spa.model.laws.timemap import LawTables, law_tables
from spa.model.params import ValveParams

__all__ = ["law_charge_integral", "law_discharge_integral", "law_orbit", "law_train_orbit"]

# The fixed point stops when its step, or its bracket, is below this (bar).
_TOL = 1e-13
_MAX_ITER = 200
_GL_X, _GL_W = np.polynomial.legendre.leggauss(16)


@dataclass(frozen=True)
class _Tables:
    """A valve's time maps with the cumulative integral of each mode's inverse pressure."""

    maps: LawTables
    cum: tuple[np.ndarray, np.ndarray]  # charge, discharge: ∫ p du up to each inverse node


@lru_cache(maxsize=16)
def _tables(c1: float, k2: float, tau2: float, laws) -> _Tables:
    """The time maps of the valve's laws; the delays do not change them, so the corners of
    a box that differ only in their delays share one table."""
    maps = law_tables(ValveParams(c1=c1, k2=k2, tau2=tau2, laws=laws))
    cum = []
    for mode in (maps.charge, maps.discharge):
        c = mode.coef
        piece = c[:, 0] + c[:, 1] / 2.0 + c[:, 2] / 3.0 + c[:, 3] / 4.0
        cum.append(np.concatenate(([0.0], np.cumsum(piece[:-1]))))
    return _Tables(maps, (cum[0], cum[1]))


def _segment(
    tables: _Tables, on: bool, p0: np.ndarray, active: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """One mode's part from ``p0`` lasting ``active`` (pressures within ``[0, k2]``): the end
    pressure, the integral of the pressure over the part, and the rate at its start and end,
    all from the time map's inverse (as :func:`~spa.model.laws.timemap.law_segment_pressure`
    evaluates it)."""
    maps = tables.maps
    mode = maps.charge if on else maps.discharge
    coef, cum = mode.coef, tables.cum[0 if on else 1]
    last = coef.shape[0] - 1
    x = np.clip(p0, 0.0, maps.k2)
    t0 = mode.forward(x, maps.k2)
    a = np.maximum(active, 0.0)
    t1 = t0 + np.minimum(a, mode.t_end - t0)

    def at(t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        u = np.maximum(t * mode.inv_h, 0.0)
        i = np.minimum(u.astype(np.int64), last)
        f = u - i
        c0, c1, c2, c3 = (coef[i, k] for k in range(4))
        p = ((c3 * f + c2) * f + c1) * f + c0
        rate = ((3.0 * c3 * f + 2.0 * c2) * f + c1) * mode.inv_h
        area = cum[i] + f * (c0 + f * (c1 / 2.0 + f * (c2 / 3.0 + f * c3 / 4.0)))
        return p, rate, area

    _, rate0, area0 = at(t0)
    p1, rate1, area1 = at(t1)
    # Past the table's end the pressure is clamped (emptied, or within 1e-14*k2 of k2).
    area = (area1 - area0) / mode.inv_h + coef[last, 0] * (a - (t1 - t0))
    # A charge from (within rounding of) the supply pressure stays there.
    top = x >= coef[last, 0] if on else np.zeros(x.shape, dtype=bool)
    p1 = np.where(top, x, p1)
    area = np.where(top, x * a, area)
    return p1, area, rate0, rate1


def _quadrature(lo: np.ndarray, hi: np.ndarray, integrand) -> np.ndarray:
    """``∫_lo^hi integrand`` by 16-point Gauss–Legendre, vectorised over the intervals."""
    half = 0.5 * (hi - lo)
    x = (0.5 * (hi + lo))[..., None] + half[..., None] * _GL_X
    return half * (integrand(x) @ _GL_W)


def law_charge_integral(
    p0: npt.ArrayLike, p1: npt.ArrayLike, elapsed: npt.ArrayLike, params: ValveParams
) -> npt.NDArray[np.float64]:
    """Integral of the pressure over a charge from ``p0`` to ``p1`` lasting ``elapsed``
    under the valve's laws (bar·s): ``k2*elapsed - ∫_p0^p1 dp/g(p)``.

    Examples
    --------
    >>> from spa.model.periodic import charge_integral
    >>> from spa.model.laws import Laws
    >>> p = ValveParams()
    >>> law = law_charge_integral(0.1, 0.5, 0.3, p)  # the paper's laws: g = 1/tau2
    >>> bool(abs(law - charge_integral(0.1, 0.5, 0.3, p)) < 1e-14)
    True
    """
    a = np.asarray(elapsed, dtype=np.float64)
    lo, hi = np.broadcast_arrays(np.asarray(p0, np.float64), np.asarray(p1, np.float64))
    inverse_g = _quadrature(lo, hi, lambda p: 1.0 / law_rates(p, params)[0])
    return params.k2 * a - inverse_g


def law_discharge_integral(
    p0: npt.ArrayLike, p1: npt.ArrayLike, params: ValveParams
) -> npt.NDArray[np.float64]:
    """Integral of the pressure over a discharge from ``p0`` down to ``p1`` under the valve's
    laws (bar·s): ``∫_p1^p0 p**(1 - m)/h(p) dp``; once empty the pressure adds nothing.

    Examples
    --------
    >>> from spa.model.periodic import discharge_integral
    >>> p = ValveParams()
    >>> law = law_discharge_integral(0.5, 0.1, p)  # the paper's laws: m = 1/2, h = 1/c1
    >>> bool(abs(law - discharge_integral(0.5, 0.1, p)) < 1e-14)
    True
    """
    e = 2.0 - valve_laws(params).m
    top = np.maximum(np.asarray(p0, np.float64), 0.0) ** e
    bottom = np.maximum(np.asarray(p1, np.float64), 0.0) ** e
    top, bottom = np.broadcast_arrays(top, bottom)
    return _quadrature(bottom, top, lambda v: 1.0 / (e * law_rates(v ** (1.0 / e), params)[1]))


def law_orbit(
    active: npt.ArrayLike,
    hold: npt.ArrayLike,
    runs: npt.ArrayLike,
    params: ValveParams,
    cycle_time: npt.ArrayLike | None = None,
) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
    """The periodic orbits of a batch of run patterns on one valve with laws.

    Parameters
    ----------
    active : array_like, shape (n, R)
        Each element's runs' active times, s (the run's length less what the delays take),
        alternating high and low from a high run; entries from column ``runs[e]`` on are
        ignored.
    hold : array_like, shape (n, R)
        Each run's hold, s (the pressure stays where the run starts; 0 under the transport
        convention).
    runs : array_like of int, shape (n,)
        Number of runs of each element's pattern (even, at least 2).
    params : ValveParams
        The valve; its laws (the paper's when ``params.laws`` is None, through the general
        code).
    cycle_time : array_like, shape (n,), optional
        Each pattern's period, s; the sum of its runs' active and hold times when omitted.

    Returns
    -------
    starts : numpy.ndarray, shape (n, R)
        The pressure at the start of each run on the orbit (bar); column 0 is the orbit's
        start ``P-`` of the first high run, columns past ``runs[e]`` repeat its end.
    mean : numpy.ndarray, shape (n,)
        The time mean of the pressure over one cycle (bar).

    Notes
    -----
    Each element's iteration stops on its own step, so an element's orbit does not depend on
    the other elements of the batch.

    Examples
    --------
    >>> from spa.model.periodic import train_mean
    >>> p = ValveParams()
    >>> starts, mean = law_orbit([[0.017, 0.01]], [[0.003, 0.01]], [2], p)
    >>> bool(abs(mean[0] - train_mean(0.02, 0.02, p)) < 1e-10)
    True
    """
    act = np.atleast_2d(np.asarray(active, dtype=np.float64))
    hld = np.broadcast_to(np.asarray(hold, dtype=np.float64), act.shape)
    count = np.broadcast_to(np.asarray(runs, dtype=np.int64), act.shape[:1])
    n, width = act.shape
    tables = _tables(params.c1, params.k2, params.tau2, params.laws)
    live = np.arange(width)[None, :] < count[:, None]
    act = np.where(live, np.maximum(act, 0.0), 0.0)

    def cycle(start: np.ndarray, idx: np.ndarray, area: bool = False):
        """The cycle map of the elements ``idx`` at ``start``, its slope, the runs' start
        pressures and (``area``) the integral of the pressure over the cycle."""
        x = start.copy()
        slope = np.ones(idx.size)
        starts = np.empty((idx.size, width))
        total = np.zeros(idx.size)
        for r in range(width):
            starts[:, r] = x
            run = np.flatnonzero(live[idx, r])
            if not run.size:
                continue
            before = x[run]
            a = act[idx[run], r]
            after, part, rate0, rate1 = _segment(tables, r % 2 == 0, before, a)
            moving = a > 0.0
            with np.errstate(divide="ignore", invalid="ignore"):
                d = rate1 / rate0
            slope[run] *= np.where(moving & (rate0 != 0.0) & np.isfinite(d), d, 1.0)
            if area:
                total[run] += before * hld[idx[run], r] + np.where(moving, part, 0.0)
            x[run] = np.where(moving, after, before)
        return x, slope, starts, total

    x = np.zeros(n)
    lo, hi = np.zeros(n), np.full(n, params.k2)
    todo = np.arange(n)  # the elements still moving; each stops on its own step
    for _ in range(_MAX_ITER):
        if not todo.size:
            break
        xt = x[todo]
        f, slope, _, _ = cycle(xt, todo)
        g = f - xt
        lo_t = np.where(g >= 0.0, xt, lo[todo])
        hi_t = np.where(g <= 0.0, xt, hi[todo])
        with np.errstate(divide="ignore", invalid="ignore"):
            newton = xt - g / (slope - 1.0)
        inside = np.isfinite(newton) & (newton > lo_t) & (newton < hi_t)
        new = np.where(inside, newton, 0.5 * (lo_t + hi_t))
        # A step within rounding of the fixed point stays put, wherever rounding puts it.
        new = np.where(np.abs(newton - xt) < _TOL, xt, new)
        new = np.where(g == 0.0, xt, new)
        lo[todo], hi[todo], x[todo] = lo_t, hi_t, new
        todo = todo[(np.abs(new - xt) >= _TOL) & (hi_t - lo_t >= _TOL)]
    _, _, starts, area = cycle(x, np.arange(n), area=True)
    if cycle_time is None:
        total = np.where(live, act + hld, 0.0).sum(axis=1)
    else:
        total = np.broadcast_to(np.asarray(cycle_time, dtype=np.float64), (n,))
    return starts, area / total


def law_train_orbit(
    t_h: npt.ArrayLike, t_l: npt.ArrayLike, params: ValveParams
) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64], npt.NDArray[np.float64]]:
    """``P+``, ``P-`` and the time mean of a train of high ``t_h``, low ``t_l`` on a valve
    with laws (the general case of :func:`spa.model.chattering.pseudo_steady_state` and
    :func:`spa.model.periodic.train_mean`).

    Parameters
    ----------
    t_h, t_l : array_like of float
        High and low durations in s (``inf`` allowed); broadcast.
    params : ValveParams
        The valve.

    Returns
    -------
    p_plus, p_minus, mean : numpy.ndarray
        As the paper's: ``(0, 0, 0)`` where the train never charges, ``(k2, k2, k2)`` where
        it charges and never discharges.

    Examples
    --------
    >>> from spa.model.chattering import pseudo_steady_state
    >>> hi, lo, _ = law_train_orbit(0.02, 0.02, ValveParams())
    >>> paper = pseudo_steady_state(0.02, 0.02)
    >>> bool(abs(hi - paper[0]) < 1e-10 and abs(lo - paper[1]) < 1e-10)
    True
    """
    th, tl = np.broadcast_arrays(np.asarray(t_h, np.float64), np.asarray(t_l, np.float64))
    h, l_eff, charges, discharges = train_segments(th, tl, params)
    both = (charges & discharges).ravel()
    p_plus = np.where(charges, params.k2, 0.0).ravel()
    p_minus = p_plus.copy()
    mean = p_plus.copy()
    if both.any():
        hb, lb = h.ravel()[both], l_eff.ravel()[both]
        hold = np.stack(
            (
                np.minimum(th.ravel()[both], params.hold_time(True)),
                np.minimum(tl.ravel()[both], params.hold_time(False)),
            ),
            axis=1,
        )
        period = th.ravel()[both] + tl.ravel()[both]
        starts, m = law_orbit(np.stack((hb, lb), axis=1), hold, 2, params, period)
        p_minus[both], p_plus[both], mean[both] = starts[:, 0], starts[:, 1], m
    shape = th.shape
    return p_plus.reshape(shape), p_minus.reshape(shape), mean.reshape(shape)
