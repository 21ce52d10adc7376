"""Exact periodic steady state of a constant input: the orbit and its time mean.

For a constant input fraction every modulator's pulse train is periodic, and the exact plant
(:mod:`spa.model.plant`) settles on a periodic orbit. No averaging is assumed here:

* PWM, IPFM and IIPFM repeat one high and one low pulse (durations of
  :func:`spa.model.averaging.pulse_times`). Appendix B gives the orbit's extrema ``P+`` and
  ``P-`` in closed form (:func:`spa.model.chattering.pseudo_steady_state`);
  :func:`train_mean` integrates the orbit over one cycle in closed form.
* First-order ΔΣ at ``xi = p/q`` (lowest terms) repeats a pattern of ``q`` clock periods
  (:func:`dsm_runs`); :func:`dsm_mean` finds the orbit's fixed point by Newton's method on
  the cycle map (the composition of :func:`spa.model.plant.charge` and
  :func:`spa.model.plant.discharge` over the pattern's runs) and integrates it.
* :func:`spa.model.steady_state.periodic_mean` dispatches on the modulator.

Over a cycle the pressure holds (for ``t_on`` after a rising edge, ``t_off`` after a falling
one), charges or discharges. With ``P0`` the pressure where an active part starts, ``P1``
where it ends and ``a`` its length, the closed-form integrals are
(:func:`charge_integral`, :func:`discharge_integral`):

* charging, ``P = k2 + (P0 - k2)*exp(-s/tau2)``: ``k2*a - tau2*(P1 - P0)``;
* discharging, ``sqrt(P) = sqrt(P0) - s/(2*c1)`` clamped at 0:
  ``(2*c1/3)*(P0**1.5 - P1**1.5)``.
"""

from __future__ import annotations

from collections.abc import Sequence
from fractions import Fraction
from functools import lru_cache
from typing import NamedTuple

import numpy as np
import numpy.typing as npt

from spa import _checks as checks
from spa._docs import fill_doc
from spa.model._broadcast import Floats, as_output
from spa.model.chattering import pseudo_steady_state, train_segments
from spa.model.params import ValveParams, valve_params
from spa.model.plant import charge, discharge

__all__ = [
    "charge_integral",
    "discharge_integral",
    "dsm_mean",
    "dsm_means",
    "dsm_runs",
    "train_mean",
]

# Newton's method on the ΔΣ cycle map stops when no fixed point moves by more than this (bar).
_NEWTON_TOL = 1e-13
_NEWTON_MAX = 60


def charge_integral(
    p0: npt.ArrayLike, p1: npt.ArrayLike, elapsed: npt.ArrayLike, params: ValveParams
) -> npt.NDArray[np.float64]:
    """Integral of the pressure over a charge from ``p0`` to ``p1`` lasting ``elapsed`` (bar·s).

    Notes
    -----
    ``∫_0^a (k2 + (P0 - k2) e^(-s/tau2)) ds = k2*a + (P0 - k2)*tau2*(1 - e^(-a/tau2))``,
    and ``(P0 - k2)*(1 - e^(-a/tau2)) = P0 - P1``.

    Examples
    --------
    >>> p = ValveParams()
    >>> p1 = float(charge(0.0, 0.5, p))
    >>> round(float(charge_integral(0.0, p1, 0.5, p)), 6)
    0.10455
    """
    a = np.asarray(elapsed, dtype=np.float64)
    return params.k2 * a - params.tau2 * (np.asarray(p1, np.float64) - np.asarray(p0, np.float64))


def discharge_integral(
    p0: npt.ArrayLike, p1: npt.ArrayLike, params: ValveParams
) -> npt.NDArray[np.float64]:
    """Integral of the pressure over a discharge from ``p0`` down to ``p1`` (bar·s).

    Notes
    -----
    With ``s0 = sqrt(P0)``, ``s1 = sqrt(P1)``:
    ``∫ (s0 - t/(2*c1))² dt = (2*c1/3)*(s0³ - s1³)`` over the time the square root falls
    from ``s0`` to ``s1``; once empty the pressure stays 0 and adds nothing.

    Examples
    --------
    >>> p = ValveParams(c1=0.5)
    >>> float(discharge_integral(1.0, 0.0, p))  # 1 bar emptied in 2*c1 = 1 s: ∫(1-t)² = 1/3
    0.3333333333333333
    """
    s0 = np.sqrt(np.asarray(p0, np.float64))
    s1 = np.sqrt(np.asarray(p1, np.float64))
    return (2.0 * params.c1 / 3.0) * (s0**3 - s1**3)


@fill_doc
def train_mean(t_h: npt.ArrayLike, t_l: npt.ArrayLike, params: ValveParams | None = None) -> Floats:
    """Exact time mean of the periodic orbit of a train of high ``t_h``, low ``t_l`` (bar).

    Parameters
    ----------
    %(train_params)s

    Returns
    -------
    numpy.ndarray or numpy.float64
        The mean pressure over one cycle of the periodic steady state: 0 where the train
        never charges (``t_h <= t_on`` or ``t_l = inf``), ``k2`` where it charges and never
        discharges (``t_l <= t_off`` or ``t_h = inf``).

    Raises
    ------
    ValueError
        As :func:`spa.model.chattering.pseudo_steady_state`.

    Notes
    -----
    One cycle starts at a rising edge at ``P-``: hold for ``min(t_h, t_on)``, charge for
    ``h = max(t_h - t_on, 0)`` to ``P+``, hold for ``min(t_l, t_off)``, discharge for
    ``l = max(t_l - t_off, 0)`` back to ``P-`` (Appendix B). The mean is

    ``(P-*min(t_h, t_on) + k2*h - tau2*(P+ - P-) + P+*min(t_l, t_off)
    + (2*c1/3)*(P+**1.5 - P-**1.5)) / (t_h + t_l)``.

    A valve with its own laws (``params.laws``) gets the orbit of their time maps and the
    integrals of :mod:`spa.model.laws.orbit` (:func:`~spa.model.laws.orbit.law_train_orbit`).

    Examples
    --------
    >>> round(float(train_mean(0.02, 0.02)), 4)  # Eq. 5 and App. B's mid-point: 0.3207
    0.3217

    The orbit holds ``t_off = 10 ms`` at ``P+`` but only ``t_on = 3 ms`` at ``P-``, so its
    mean lies above the mid-point.
    """
    p = valve_params(params)
    th, tl = np.broadcast_arrays(np.asarray(t_h, np.float64), np.asarray(t_l, np.float64))
    if p.laws is not None:  # the valve's own laws: the orbit of their time maps
        from spa.model.laws.orbit import law_train_orbit

        if np.any(np.isnan(th)) or np.any(np.isnan(tl)) or np.any(th < 0) or np.any(tl < 0):
            raise ValueError("t_h and t_l must be >= 0 (inf allowed), not NaN")
        return as_output(law_train_orbit(th, tl, p)[2])
    hi, lo = (np.asarray(a, dtype=np.float64) for a in pseudo_steady_state(th, tl, p))
    h, _, charges, discharges = train_segments(th, tl, p)
    both = charges & discharges
    th_b, tl_b, h_b = (np.where(both, a, 1.0) for a in (th, tl, h))
    area = (
        lo * np.minimum(th_b, p.hold_time(True))
        + charge_integral(lo, hi, h_b, p)
        + hi * np.minimum(tl_b, p.hold_time(False))
        + discharge_integral(hi, lo, p)
    )
    mean = np.where(both, area / (th_b + tl_b), np.where(charges, p.k2, 0.0))
    return as_output(mean)


@lru_cache(maxsize=4096)
def _runs(p: int, q: int) -> tuple[int, ...]:
    """Run lengths (ticks) of the ΔΣ pattern of ``p/q``, starting with a high run."""
    m = np.arange(q + 1)
    ones = (2 * m * p + q) // (2 * q)  # ones in the first m ticks: floor(m*p/q + 1/2)
    u = np.diff(ones)
    rise = int(np.flatnonzero((u == 1) & (np.roll(u, 1) == 0))[0])
    u = np.roll(u, -rise)
    edges = np.flatnonzero(np.diff(u)) + 1
    return tuple(int(n) for n in np.diff(np.concatenate(([0], edges, [q]))))


def dsm_runs(xi: float, max_denominator: int = 1000) -> tuple[int, ...]:
    """The periodic pattern of first-order ΔΣ at a constant ``xi``, as run lengths in ticks.

    Parameters
    ----------
    xi : float
        Input fraction in [0, 1], read as the nearest fraction ``p/q`` (lowest terms) with
        ``q <= max_denominator``.
    max_denominator : int, default 1000
        Largest pattern length considered, in clock periods.

    Returns
    -------
    tuple of int
        Lengths of the alternating high and low runs of one period of the pattern, starting
        with a high run (their sum is ``q``); ``()`` for ``xi = 0`` (always low) and ``(1,)``
        for ``xi = 1`` (always high).

    Notes
    -----
    From ``v = u = 0``, ``v_k = v_{k-1} + xi - u_{k-1}``, ``u_k = [v_k >= 1/2]`` gives
    ``floor((k + 1)*xi + 1/2)`` ones in the first ``k + 1`` ticks
    (:func:`spa.model.modulators.modulate`), which repeats every ``q`` ticks with ``p`` ones.

    Examples
    --------
    >>> dsm_runs(0.5), dsm_runs(0.3), dsm_runs(0.75)
    ((1, 1), (1, 2, 1, 3, 1, 2), (3, 1))
    """
    return _pattern(checks.fraction("xi", xi), checks.integer("max_denominator", max_denominator))


@lru_cache(maxsize=4096)
def _pattern(xi: float, max_denominator: int) -> tuple[int, ...]:
    frac = Fraction(xi).limit_denominator(max_denominator)
    if frac.numerator == 0:
        return ()
    if frac.numerator == frac.denominator:
        return (1,)
    return _runs(frac.numerator, frac.denominator)


class _Valves(NamedTuple):
    """The valve of each element of a batch of ΔΣ orbits, as arrays (one value an element):
    what :func:`spa.model.plant.charge`, :func:`~spa.model.plant.discharge` and the
    integrals read of a valve."""

    c1: npt.NDArray[np.float64]
    k2: npt.NDArray[np.float64]
    tau2: npt.NDArray[np.float64]
    on_loss: npt.NDArray[np.float64]
    off_loss: npt.NDArray[np.float64]

    def first(self, n: int) -> _Valves:
        """The first ``n`` elements' valves."""
        return _Valves(*(field[:n] for field in self))


def _dsm_orbit(
    table: npt.NDArray[np.int64],
    pattern: npt.NDArray[np.int64],
    period: npt.NDArray[np.float64],
    valves: _Valves,
    holding: bool,
) -> npt.NDArray[np.float64]:
    """Cycle means of the elements with pattern ``table[pattern[e]]`` at clock ``period[e]``
    on valve ``e`` of ``valves`` (``holding``: the hold convention, or transport).

    ``table`` holds one zero-padded row of run lengths per pattern; the elements are sorted
    by decreasing number of runs, so that those still running at run ``r`` are a prefix.
    Each element's Newton iteration stops on its own step, so an element's mean does not
    depend on the other elements of the batch.
    """
    runs_t = np.ascontiguousarray(table.T)  # run r of every pattern: runs_t[r]
    n_el = pattern.size
    counts = (table > 0).sum(axis=1)[pattern]
    lengths, actives, prefixes = [], [], []
    for r in range(runs_t.shape[0]):
        n = int(np.searchsorted(-counts, -r, side="left"))  # elements with more than r runs
        length = runs_t[r][pattern[:n]] * period[:n]
        # What each run loses to the delays (a hold, or the transport convention's shift).
        loss = (valves.on_loss if r % 2 == 0 else valves.off_loss)[:n]
        lengths.append(length)
        actives.append(np.maximum(length - loss, 0.0))
        prefixes.append(valves.first(n))

    def cycle(start: npt.NDArray[np.float64]) -> tuple[np.ndarray, np.ndarray]:
        """The cycle map and its derivative at ``start``."""
        x = start.copy()
        slope = np.ones(n_el)
        for r, (active, v) in enumerate(zip(actives, prefixes, strict=True)):
            n = active.size
            before = x[:n]
            if r % 2 == 0:
                after = charge(before, active, v)
                gap = v.k2 - before
                d = np.divide(v.k2 - after, gap, out=np.zeros(n), where=gap > 0.0)
            else:
                after = discharge(before, active, v)
                d = np.divide(np.sqrt(after), np.sqrt(before), out=np.zeros(n), where=before > 0)
                d = np.where(active > 0.0, d, 1.0)
            slope[:n] *= d
            x[:n] = after
        return x, slope

    # G(P) = F(P) - P is convex and decreasing on [0, k2] (charges are affine, discharges
    # convex, all non-decreasing), so Newton's method from P = 0 climbs to the root.
    x = np.zeros(n_el)
    done = np.zeros(n_el, dtype=bool)
    for _ in range(_NEWTON_MAX):
        f, slope = cycle(x)
        step = np.divide(f - x, 1.0 - slope, out=np.zeros(n_el), where=(slope < 1.0) & ~done)
        x = np.clip(x + step, 0.0, valves.k2)
        done |= np.abs(step) < _NEWTON_TOL
        if done.all():
            break
    area = np.zeros(n_el)
    for r, (length, active, v) in enumerate(zip(lengths, actives, prefixes, strict=True)):
        n = active.size
        before = x[:n]
        if holding:
            area[:n] += before * (length - active)  # the hold
        if r % 2 == 0:
            after = charge(before, active, v)
            area[:n] += charge_integral(before, after, active, v)
        else:
            after = discharge(before, active, v)
            area[:n] += discharge_integral(before, after, v)
        x[:n] = after
    return area / (table.sum(axis=1)[pattern] * period)


@fill_doc
def dsm_mean(
    xi: npt.ArrayLike,
    period: npt.ArrayLike,
    params: ValveParams | None = None,
    max_denominator: int = 1000,
) -> Floats:
    """Exact time mean of the periodic orbit under first-order ΔΣ at constant ``xi`` (bar).

    Parameters
    ----------
    xi : array_like of float
        Input fractions, clipped to [0, 1]; each is read as a fraction ``p/q`` as in
        :func:`dsm_runs` (the tuning grid ``i/(N - 1)`` exactly).
    period : array_like of float
        Clock period ``T_DS`` in s (> 0); broadcasts with ``xi``.
    %(params)s
    max_denominator : int, default 1000
        As :func:`dsm_runs`.

    Returns
    -------
    numpy.ndarray or numpy.float64
        Mean pressure over one period of the pattern (``q*T_DS``) on the periodic orbit.

    Raises
    ------
    ValueError
        For a non-finite ``xi`` or a period that is not finite and > 0.

    Notes
    -----
    Each run of ``n`` ticks lasts ``n*T_DS``: a hold (``t_on`` after a rising edge,
    ``t_off`` after a falling one, cut short by the run's end), then the plant's closed form
    for the rest. The cycle map ``F`` (charges, discharges in turn, from the start of a high
    run) is non-decreasing and convex, so Newton's method on ``F(P) = P`` from ``P = 0``
    converges monotonically to the orbit's start; the mean then integrates each piece in
    closed form (:func:`charge_integral`, :func:`discharge_integral`). A valve with its own
    laws (``params.laws``) gets the orbit of their time maps
    (:func:`spa.model.laws.orbit.law_orbit`).

    Examples
    --------
    >>> from spa.model.periodic import train_mean
    >>> bool(abs(dsm_mean(0.5, 0.02) - train_mean(0.02, 0.02)) < 1e-12)  # 1 high, 1 low
    True
    """
    return as_output(dsm_means(xi, [period], [valve_params(params)], max_denominator)[0])


def dsm_means(
    xi: npt.ArrayLike,
    periods: Sequence[npt.ArrayLike],
    valves: Sequence[ValveParams],
    max_denominator: int = 1000,
) -> npt.NDArray[np.float64]:
    """:func:`dsm_mean` of several valves, each at its own clock periods, in one batch.

    Parameters
    ----------
    xi : array_like of float
        Input fractions, as :func:`dsm_mean`; shared by every valve.
    periods : sequence of array_like of float
        The clock periods of each valve (> 0), each broadcasting with ``xi`` to one shape.
    valves : sequence of ValveParams
        One a row of the result, as many as ``periods``.
    max_denominator : int, default 1000
        As :func:`dsm_runs`.

    Returns
    -------
    numpy.ndarray
        Shape ``(len(valves),) + shape``: row ``j`` is ``dsm_mean(xi, periods[j],
        valves[j])``, bit for bit (each orbit's Newton iteration stops on its own step).

    Raises
    ------
    ValueError
        As :func:`dsm_mean`, or if ``periods`` and ``valves`` differ in length or are empty.

    Examples
    --------
    >>> from spa.model.params import ValveParams
    >>> a, b = ValveParams(), ValveParams(k2=0.8)
    >>> batch = dsm_means([0.3, 0.7], [0.02, 0.05], [a, b])
    >>> bool(batch[0, 1] == dsm_mean(0.7, 0.02, a) and batch[1, 0] == dsm_mean(0.3, 0.05, b))
    True
    """
    if len(periods) != len(valves) or not valves:
        raise ValueError(
            f"expected one period array a valve, got {len(periods)} for {len(valves)} valves"
        )
    x = np.clip(checks.finite_array("xi", xi), 0.0, 1.0)
    ts = [checks.positive_array("period", t) for t in periods]
    shape = np.broadcast_shapes(x.shape, *(t.shape for t in ts))
    xf = np.broadcast_to(x, shape).ravel()
    tf = np.stack([np.broadcast_to(t, shape).ravel() for t in ts])  # (valves, elements)
    uniq, inverse = np.unique(xf, return_inverse=True)
    patterns = [dsm_runs(float(v), max_denominator) for v in uniq]
    width = max((len(r) for r in patterns), default=0)
    table = np.zeros((len(patterns), max(width, 1)), dtype=np.int64)
    for i, r in enumerate(patterns):
        table[i, : len(r)] = r
    count = np.array([len(r) for r in patterns], dtype=np.int64)[inverse]
    fields = {
        f: np.array([getattr(v, f) for v in valves], dtype=np.float64) for f in _Valves._fields
    }
    out = np.where(uniq[inverse] >= 1.0, fields["k2"][:, np.newaxis], 0.0)
    pulsing = np.flatnonzero(count >= 2)
    order = pulsing[np.argsort(-count[pulsing], kind="stable")]  # most runs first
    for holding in (True, False):  # each convention's orbits in a batch of their own
        rows = np.flatnonzero(
            [(v.delay == "hold") == holding and v.laws is None for v in valves]
        )
        if not (order.size and rows.size):
            continue
        el = np.repeat(order, rows.size)  # still by decreasing number of runs
        row = np.tile(rows, order.size)
        batch = _Valves(*(fields[f][row] for f in _Valves._fields))
        out[row, el] = _dsm_orbit(table, inverse[el], tf[row, el], batch, holding)
    for row in np.flatnonzero([v.laws is not None for v in valves]):
        # A valve with its own laws: the orbit of their time maps, one valve at a time.
        if order.size:
            out[row, order] = _law_dsm_orbit(table, inverse[order], tf[row, order], valves[row])
    return out.reshape((len(valves), *shape))


def _law_dsm_orbit(
    table: npt.NDArray[np.int64],
    pattern: npt.NDArray[np.int64],
    period: npt.NDArray[np.float64],
    params: ValveParams,
) -> npt.NDArray[np.float64]:
    """Cycle means of :func:`_dsm_orbit`'s elements on one valve with laws
    (:func:`spa.model.laws.orbit.law_orbit`)."""
    from spa.model.laws.orbit import law_orbit

    length = table[pattern] * period[:, np.newaxis]
    loss = np.where(np.arange(table.shape[1]) % 2 == 0, params.on_loss, params.off_loss)
    active = np.maximum(length - loss, 0.0)
    hold = length - active if params.delay == "hold" else np.zeros_like(length)
    runs = (table > 0).sum(axis=1)[pattern]
    return law_orbit(active, hold, runs, params, table.sum(axis=1)[pattern] * period)[1]
