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

from fractions import Fraction
from functools import lru_cache

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

    Examples
    --------
    >>> round(float(train_mean(0.02, 0.02)), 4)  # Eq. 5 and App. B's mid-point: 0.3207
    0.3217

    The orbit holds ``t_off = 10 ms`` at ``P+`` but only ``t_on = 3 ms`` at ``P-``, so its
    mean lies above the mid-point.
    """
    p = valve_params(params)
    th, tl = np.broadcast_arrays(np.asarray(t_h, np.float64), np.asarray(t_l, np.float64))
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


def _dsm_orbit(
    table: npt.NDArray[np.int64],
    pattern: npt.NDArray[np.int64],
    period: npt.NDArray[np.float64],
    p: ValveParams,
) -> npt.NDArray[np.float64]:
    """Cycle means of the elements with pattern ``table[pattern[e]]`` at clock ``period[e]``.

    ``table`` holds one zero-padded row of run lengths per pattern; the elements are sorted
    by decreasing number of runs, so that those still running at run ``r`` are a prefix.
    """
    runs_t = np.ascontiguousarray(table.T)  # run r of every pattern: runs_t[r]
    n_el = pattern.size
    counts = (table > 0).sum(axis=1)[pattern]
    # What each run loses to the delays (a hold, or the transport convention's shift).
    losses = np.where(np.arange(runs_t.shape[0]) % 2 == 0, p.on_loss, p.off_loss)
    holding = p.delay == "hold"
    lengths, actives = [], []
    for r in range(runs_t.shape[0]):
        n = int(np.searchsorted(-counts, -r, side="left"))  # elements with more than r runs
        length = runs_t[r][pattern[:n]] * period[:n]
        lengths.append(length)
        actives.append(np.maximum(length - losses[r], 0.0))

    def cycle(start: npt.NDArray[np.float64]) -> tuple[np.ndarray, np.ndarray]:
        """The cycle map and its derivative at ``start``."""
        x = start.copy()
        slope = np.ones(n_el)
        for r, active in enumerate(actives):
            n = active.size
            before = x[:n]
            if r % 2 == 0:
                after = charge(before, active, p)
                gap = p.k2 - before
                d = np.divide(p.k2 - after, gap, out=np.zeros(n), where=gap > 0.0)
            else:
                after = discharge(before, active, p)
                d = np.divide(np.sqrt(after), np.sqrt(before), out=np.zeros(n), where=before > 0)
                d = np.where(active > 0.0, d, 1.0)
            slope[:n] *= d
            x[:n] = after
        return x, slope

    # G(P) = F(P) - P is convex and decreasing on [0, k2] (charges are affine, discharges
    # convex, all non-decreasing), so Newton's method from P = 0 climbs to the root.
    x = np.zeros(n_el)
    for _ in range(_NEWTON_MAX):
        f, slope = cycle(x)
        step = np.divide(f - x, 1.0 - slope, out=np.zeros(n_el), where=slope < 1.0)
        x = np.clip(x + step, 0.0, p.k2)
        if np.max(np.abs(step), initial=0.0) < _NEWTON_TOL:
            break
    area = np.zeros(n_el)
    for r, (length, active) in enumerate(zip(lengths, actives, strict=True)):
        n = active.size
        before = x[:n]
        if holding:
            area[:n] += before * (length - active)  # the hold
        if r % 2 == 0:
            after = charge(before, active, p)
            area[:n] += charge_integral(before, after, active, p)
        else:
            after = discharge(before, active, p)
            area[:n] += discharge_integral(before, after, p)
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
    closed form (:func:`charge_integral`, :func:`discharge_integral`).

    Examples
    --------
    >>> from spa.model.periodic import train_mean
    >>> bool(abs(dsm_mean(0.5, 0.02) - train_mean(0.02, 0.02)) < 1e-12)  # 1 high, 1 low
    True
    """
    p = valve_params(params)
    x = np.clip(checks.finite_array("xi", xi), 0.0, 1.0)
    t = checks.positive_array("period", period)
    xb, tb = np.broadcast_arrays(x, t)
    shape = xb.shape
    xf, tf = xb.ravel(), tb.ravel()
    uniq, inverse = np.unique(xf, return_inverse=True)
    patterns = [dsm_runs(float(v), max_denominator) for v in uniq]
    width = max((len(r) for r in patterns), default=0)
    table = np.zeros((len(patterns), max(width, 1)), dtype=np.int64)
    for i, r in enumerate(patterns):
        table[i, : len(r)] = r
    count = np.array([len(r) for r in patterns])[inverse]
    out = np.where(uniq[inverse] >= 1.0, p.k2, 0.0)
    pulsing = count >= 2
    if np.any(pulsing):
        idx = np.flatnonzero(pulsing)
        idx = idx[np.argsort(-count[idx], kind="stable")]
        out[idx] = _dsm_orbit(table, inverse[idx], tf[idx], p)
    return as_output(out.reshape(shape))
