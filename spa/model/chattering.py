"""Chattering: the pressure ripple of a steady pulse train (docs/model.md section 3, Appendix B).

* :func:`chattering_estimate` – the paper's estimate, the rise during one high pulse at the
  averaged equilibrium (Eq. 10);
* :func:`pseudo_steady_state` – the exact extrema ``P+`` and ``P-`` of the periodic orbit of
  a train with fixed high and low durations (Appendix B), no averaging assumed;
* :func:`pseudo_steady_mean` – their mid-point, the fast-switching estimate of the
  equilibrium.

Vectorised like :mod:`spa.model.averaging`: arguments broadcast, scalars give NumPy scalars.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from spa._docs import fill_doc
from spa.model._broadcast import Floats, as_output
from spa.model.params import ValveParams, valve_params

__all__ = ["chattering_estimate", "pseudo_steady_mean", "pseudo_steady_state"]


def train_segments(
    th: npt.NDArray[np.float64], tl: npt.NDArray[np.float64], p: ValveParams
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """A periodic train's charging and discharging times per cycle, and whether it charges
    and discharges at all (for :func:`pseudo_steady_state` and
    :func:`spa.model.periodic.train_mean`).

    The times are the pulse widths less what the delays take (the hold convention's holds,
    the transport convention's shift of the edges: :attr:`ValveParams.on_loss`), at least 0.
    A pulse of zero width is no pulse (under the transport convention the delays would
    otherwise stretch it); a level that lasts forever leaves the other unreached.

    Examples
    --------
    >>> h, l, c, d = train_segments(np.array([0.02]), np.array([0.02]), ValveParams())
    >>> h.round(4).tolist(), l.round(4).tolist(), c.tolist(), d.tolist()
    ([0.017], [0.01], [True], [True])
    """
    h = np.maximum(th - p.on_loss, 0.0)
    l_eff = np.maximum(tl - p.off_loss, 0.0)
    charges = (h > 0.0) & np.isfinite(tl) & (th > 0.0)
    discharges = (l_eff > 0.0) & np.isfinite(th) & (tl > 0.0)
    return h, l_eff, charges, discharges


def chattering_estimate(
    t_h: npt.ArrayLike, p_eq: npt.ArrayLike, params: ValveParams | None = None
) -> Floats:
    """Chattering estimate: the pressure rise during one high pulse at equilibrium (Eq. 10).

    Parameters
    ----------
    t_h : array_like of float
        High duration in s (:func:`pulse_times`); may be ``inf``.
    p_eq : array_like of float
        Equilibrium pressure in bar (:func:`equilibrium`).
    params : ValveParams, optional
        Valve parameters (``k2``, ``tau2``); nominal when omitted.

    Returns
    -------
    numpy.ndarray or numpy.float64
        ``dP2`` in bar; 0 where ``p_eq >= k2`` (saturated: no chattering), even for an
        infinite ``t_h``.

    Raises
    ------
    ValueError
        If ``params`` is not a ValveParams.

    Notes
    -----
    ``dP2 = t_h*(k2 - P_eq)/tau2``: the charging slope of Eq. 2 at ``P_eq`` times the high
    duration. It is an estimate for short pulses; :func:`pseudo_steady_state` is exact. A
    valve with its own laws (``params.laws``) uses its charge law's slope there,
    ``t_h*f_open(P_eq)``.

    Examples
    --------
    >>> p = ValveParams()
    >>> round(float(chattering_estimate(0.02, 0.4, p)), 5)
    0.01058
    """
    p = valve_params(params)
    th, pe = np.broadcast_arrays(np.asarray(t_h, np.float64), np.asarray(p_eq, np.float64))
    gap = np.maximum(p.k2 - pe, 0.0)
    if p.laws is not None:  # the valve's own charge law at P_eq: t_h*(k2 - P_eq)*g(P_eq)
        from spa.model.laws.rates import open_rate

        with np.errstate(invalid="ignore"):
            d = th * np.asarray(open_rate(np.minimum(pe, p.k2), p))
        return as_output(np.where(gap > 0.0, d, 0.0))
    with np.errstate(invalid="ignore"):
        d = th * gap / p.tau2
    return as_output(np.where(gap > 0.0, d, 0.0))


@fill_doc
def pseudo_steady_state(
    t_h: npt.ArrayLike, t_l: npt.ArrayLike, params: ValveParams | None = None
) -> tuple[Floats, Floats]:
    """Exact pseudo-steady extrema of the pressure for a fixed periodic pulse train (App. B).

    Parameters
    ----------
    %(train_params)s

    Returns
    -------
    p_plus, p_minus : numpy.ndarray or numpy.float64
        Pressure at the end of the charging and of the discharging phase, bar. A train that
        never charges (``t_h <= t_on``, or ``t_l = inf``) gives ``(0, 0)``; one that never
        discharges (``t_l <= t_off`` with ``t_h > t_on``, or ``t_h = inf``) gives ``(k2, k2)``.

    Raises
    ------
    ValueError
        If a duration is negative or NaN, or ``params`` is not a ValveParams.

    Notes
    -----
    With ``h = max(t_h - t_on, 0)``, ``l = max(t_l - t_off, 0)``, ``E = exp(-h/tau2)`` and
    ``beta = l/(2*c1)``, the fixed point of "charge for ``h``, then discharge for ``l``" is

    ``sqrt(P+) = -E*beta/(1 - E) + sqrt(k2 + E*beta²/(1 - E)²)``,
    ``P- = (sqrt(P+) - beta)²``,

    and if ``sqrt(P+) < beta`` the actuator empties each period: ``P- = 0``,
    ``P+ = k2*(1 - E)``. ``sqrt(P+)`` is evaluated as ``c/(a + sqrt(a² + c))`` with
    ``a = E*beta/(1 - E)`` and ``c = k2 + E*beta²/(1 - E)``, free of cancellation.

    A valve with its own laws (``params.laws``) has no closed form: its orbit is the fixed
    point of the composed time maps (:func:`spa.model.laws.orbit.law_train_orbit`), exact
    however long the pulses are against the local time constant.

    Examples
    --------
    >>> p = ValveParams()
    >>> hi, lo = pseudo_steady_state(0.02, 0.02, p)
    >>> round(float(hi), 4), round(float(lo), 4)
    (0.326, 0.3154)
    """
    p = valve_params(params)
    th, tl = np.broadcast_arrays(np.asarray(t_h, np.float64), np.asarray(t_l, np.float64))
    if np.any(np.isnan(th)) or np.any(np.isnan(tl)) or np.any(th < 0) or np.any(tl < 0):
        raise ValueError("t_h and t_l must be >= 0 (inf allowed), not NaN")
    if p.laws is not None:  # the valve's own laws: the orbit of their time maps
        from spa.model.laws.orbit import law_train_orbit

        hi, lo, _ = law_train_orbit(th, tl, p)
        return as_output(hi), as_output(lo)
    h, l_eff, charges, discharges = train_segments(th, tl, p)
    both = charges & discharges
    # Placeholders outside `both` keep the arithmetic finite; those entries are overwritten.
    hb = np.where(both, h, 1.0)
    lb = np.where(both, l_eff, 0.0)
    e = np.exp(-hb / p.tau2)
    one_minus_e = -np.expm1(-hb / p.tau2)
    beta = lb / (2.0 * p.c1)
    a = e * beta / one_minus_e
    c = p.k2 + e * beta * beta / one_minus_e
    s = c / (a + np.sqrt(a * a + c))
    empties = s < beta
    # P+ <= k2 holds exactly; clamp the last-ulp rounding of s*s so the bound survives floats.
    p_plus = np.where(empties, p.k2 * one_minus_e, np.minimum(s * s, p.k2))
    p_minus = np.where(empties, 0.0, np.minimum((s - beta) ** 2, p_plus))
    saturated = charges & ~discharges
    p_plus = np.where(both, p_plus, np.where(saturated, p.k2, 0.0))
    p_minus = np.where(both, p_minus, np.where(saturated, p.k2, 0.0))
    return as_output(p_plus), as_output(p_minus)


@fill_doc
def pseudo_steady_mean(
    t_h: npt.ArrayLike, t_l: npt.ArrayLike, params: ValveParams | None = None
) -> Floats:
    """Fast-switching estimate of the equilibrium: the mid-point ``(P+ + P-)/2`` (App. B).

    Parameters
    ----------
    t_h, t_l : array_like of float
        High and low durations in s; broadcast.
    %(params)s

    Returns
    -------
    numpy.ndarray or numpy.float64
        ``(P+ + P-)/2`` in bar.

    Raises
    ------
    ValueError
        As :func:`pseudo_steady_state`.

    Notes
    -----
    When the period is short compared with ``tau2`` and ``c1*sqrt(P)`` the pressure moves
    almost linearly between ``P-`` and ``P+``, so its time mean is close to the mid-point and
    to the averaged ``P_eq`` of Eq. 5.

    Examples
    --------
    >>> round(float(pseudo_steady_mean(0.02, 0.02)), 4)  # Eq. 5 gives 0.3207 too
    0.3207
    """
    hi, lo = pseudo_steady_state(t_h, t_l, params)
    return as_output(0.5 * (np.asarray(hi) + np.asarray(lo)))
