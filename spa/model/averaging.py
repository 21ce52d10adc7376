"""Averaged analysis of a pulse-driven valve feeding a soft actuator (docs/model.md section 3).

Section 4.2 of the paper replaces the switched plant by its average over one pulse period:
the actuator discharges for the fraction ``alpha1`` of the period and charges for the fraction
``alpha2``, the valve's opening and closing delays being dead time. Everything here is a
closed form in the input fraction ``xi`` and the modulator's settings:

* :func:`pulse_times` – steady high/low durations of each modulator (Appendix A);
* :func:`time_fractions` – the effective fractions ``alpha1``, ``alpha2`` (Eqs. 6–7);
* :func:`equilibrium_pressure`, :func:`equilibrium` – the averaged equilibrium (Eq. 5);
* :func:`time_constant` – the equivalent time constant (Eq. 9).

Two neighbouring concepts live in their own modules and are re-exported here, so that
``spa.model.averaging`` keeps offering all of Section 4:

* :mod:`spa.model.chattering` – the chattering estimate (Eq. 10) and the exact periodic
  extrema of Appendix B (:func:`chattering_estimate`, :func:`pseudo_steady_state`,
  :func:`pseudo_steady_mean`);
* :mod:`spa.model.thresholds` – dead-zone and saturation (Table 1: :func:`thresholds`,
  :func:`threshold_table`, :data:`THRESHOLD_FORMULAS`).

All functions are vectorised: ``xi`` and the modulator settings may be scalars or arrays and
broadcast against each other (NumPy rules); a scalar in gives a NumPy scalar out.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import numpy.typing as npt

from spa._docs import fill_doc
from spa.model._broadcast import (
    Floats,
    as_output,
    input_fraction,
    safe_div,
)
from spa.model.chattering import chattering_estimate, pseudo_steady_mean, pseudo_steady_state
from spa.model.modulators import get_kind
from spa.model.modulators.core import settings_arrays
from spa.model.params import ValveParams, valve_params
from spa.model.thresholds import THRESHOLD_FORMULAS, threshold_table, thresholds

__all__ = [
    "THRESHOLD_FORMULAS",
    "Floats",
    "chattering_estimate",
    "equilibrium",
    "equilibrium_pressure",
    "pseudo_steady_mean",
    "pseudo_steady_state",
    "pulse_times",
    "threshold_table",
    "thresholds",
    "time_constant",
    "time_fractions",
]


@fill_doc
def pulse_times(
    kind: str, xi: npt.ArrayLike, params: ValveParams | None = None, **settings: Any
) -> tuple[Floats, Floats]:
    """Steady high and low durations of a modulator's pulse train for a constant input.

    Parameters
    ----------
    %(kind_xi)s
    params : ValveParams, optional
        The valve of the context (LPWM inverts it unless its settings name one); nominal
        when omitted. The other kinds do not use it.
    **settings
        ``f_w`` (Hz) for PWM; ``t_h`` (s) and ``gain`` (default 1) for IPFM; ``t_l`` (s) and
        ``gain`` (default 1) for IIPFM; ``period`` (s) for ΔΣM; ``f_w`` and optionally the
        valve for LPWM. Scalars or arrays that broadcast with ``xi``.

    Returns
    -------
    t_h, t_l : numpy.ndarray or numpy.float64
        High and low durations in s. ``inf`` where the train never leaves that level (IPFM
        at ``xi = 0`` has ``t_l = inf``; IIPFM at ``xi = 1`` has ``t_h = inf``); ``0`` where
        the level is never reached (IPFM with ``xi >= gain`` stays high: ``t_l = 0``).

    Raises
    ------
    ValueError
        For an unknown ``kind``, an unknown, missing or non-positive setting (the message
        names it), or a non-finite ``xi``.

    Notes
    -----
    Appendix A, Table A1:

    * PWM: ``t_h = xi/f_w``, ``t_l = (1 - xi)/f_w``;
    * IPFM: ``t_h`` fixed, ``t_l = t_h*(G/xi - 1)``;
    * IIPFM: ``t_h = t_l*(G/(1 - xi) - 1)``, ``t_l`` fixed;
    * ΔΣM: the mean durations implied by the paper's firing-frequency approximation
      ``f = 2*xi*(1 - xi)/T_DS`` with duty ``xi``: ``t_h = T_DS/(2*(1 - xi))``,
      ``t_l = T_DS/(2*xi)``. These are what the ΔΣM time fractions of :func:`time_fractions`
      assume. The true first-order pattern has single-period pulses of the minority level
      (for ``xi <= 1/2``: ``t_h = T_DS`` and a mean ``t_l = T_DS*(1 - xi)/xi``); the two
      agree at ``xi = 1/2``.

    Examples
    --------
    >>> pulse_times("pwm", 0.25, f_w=20.0)
    (np.float64(0.0125), np.float64(0.0375))
    >>> pulse_times("ipfm", 0.5, t_h=0.02)
    (np.float64(0.02), np.float64(0.02))
    >>> pulse_times("iipfm", [0.0, 1.0], t_l=0.02)[0].tolist()
    [0.0, inf]
    """
    p = valve_params(params)
    s = settings_arrays(kind, settings)
    t_h, t_l = get_kind(kind).pulse_times(input_fraction(xi), s, p)
    return as_output(np.asarray(t_h)), as_output(np.asarray(t_l))


@fill_doc
def time_fractions(
    kind: str, xi: npt.ArrayLike, params: ValveParams | None = None, **settings: Any
) -> tuple[Floats, Floats]:
    """Effective discharging and charging fractions of the period (Eqs. 6–7).

    Parameters
    ----------
    %(kind_xi)s
    params : ValveParams, optional
        Valve parameters (``t_on``, ``t_off`` are used); nominal when omitted.
    %(settings)s

    Returns
    -------
    alpha1, alpha2 : numpy.ndarray or numpy.float64
        ``alpha1 = (t_l - t_off)/T`` (time discharging) and ``alpha2 = (t_h - t_on)/T``
        (time charging). ``alpha2 <= 0`` is the dead-zone, ``alpha1 <= 0`` saturation.

    Raises
    ------
    ValueError
        For an unknown ``kind``, a bad setting (named in the message), a non-finite ``xi`` or
        ``params`` that is not a :class:`~spa.model.params.ValveParams`.

    Notes
    -----
    docs/model.md section 3 (paper Section 4.3.1), with ``f = 1/T_DS`` for ΔΣM:

    =======  ======================================  ======================================
    kind     alpha1                                  alpha2
    =======  ======================================  ======================================
    PWM      ``(1 - xi) - t_off*f_w``                ``xi - t_on*f_w``
    IPFM     ``1 - (1 + t_off/t_h)*xi/G``            ``(1 - t_on/t_h)*xi/G``
    IIPFM    ``(1/G)*(1 - t_off/t_l)*(1 - xi)``      ``1 - (1/G)*(1 + t_on/t_l)*(1 - xi)``
    ΔΣM      ``(1 - xi)*(1 - 2*f*t_off*xi)``         ``xi*(1 - 2*f*t_on*(1 - xi))``
    =======  ======================================  ======================================

    The paper states IPFM for ``G = 1`` (its choice); the general form follows from its
    period ``G*t_h/xi``. The ΔΣM rows are the paper's quadratics
    ``1 - (1 + 2f t_off) xi + 2f t_off xi²`` and ``(1 - 2f t_on) xi + 2f t_on xi²`` factored,
    which keeps the end points exact.

    The table is written for the paper's hold convention. For a valve with
    ``delay="transport"`` the same rows are evaluated with ``t_on``, ``t_off`` replaced by
    the charging and discharging time a pulse loses,
    :attr:`~spa.model.params.ValveParams.on_loss` ``= t_on - t_off`` and
    :attr:`~spa.model.params.ValveParams.off_loss` ``= t_off - t_on``: the plant charges
    from ``t_on`` after a rising edge to ``t_off`` after the falling one and holds never, so
    ``alpha1 + alpha2 = 1``; ``alpha2`` is clipped to [0, 1].

    Examples
    --------
    >>> p = ValveParams()
    >>> a1, a2 = time_fractions("pwm", 0.5, p, f_w=20.0)
    >>> round(float(a1), 6), round(float(a2), 6)
    (0.3, 0.44)
    >>> a1, a2 = time_fractions("iipfm", 0.0, p, t_l=0.02, gain=1.15)
    >>> round(float(a2), 12)
    0.0
    """
    p = valve_params(params)
    s = settings_arrays(kind, settings)
    x = input_fraction(xi)
    spec = get_kind(kind)
    a1, a2 = spec.fractions(x, s, p)
    if p.delay == "transport":
        # No hold: the plant charges or discharges all the time. A train that never leaves
        # a level (a pulse of zero width is no pulse) is that level's.
        t_h, t_l = (np.asarray(a) for a in spec.pulse_times(x, s, p))
        a2 = np.clip(np.asarray(a2, dtype=np.float64), 0.0, 1.0)
        a2 = np.where((t_h <= 0.0) | np.isinf(t_l), 0.0, a2)
        a2 = np.where((t_l <= 0.0) | np.isinf(t_h), 1.0, a2)
        a1 = 1.0 - a2
    return as_output(np.asarray(a1)), as_output(np.asarray(a2))


def equilibrium_pressure(
    alpha1: npt.ArrayLike, alpha2: npt.ArrayLike, params: ValveParams | None = None
) -> Floats:
    """Averaged equilibrium pressure for given time fractions (Eq. 5).

    Parameters
    ----------
    alpha1, alpha2 : array_like of float
        Discharging and charging time fractions (:func:`time_fractions`); broadcast.
    params : ValveParams, optional
        Valve parameters (``c1``, ``k2``, ``tau2``); nominal when omitted.

    Returns
    -------
    numpy.ndarray or numpy.float64
        ``P_eq`` in bar, in ``[0, k2]``: ``0`` where ``alpha2 <= 0`` (dead-zone, which takes
        precedence: from rest a valve that never charges keeps the actuator empty) and ``k2``
        where ``alpha1 <= 0 < alpha2`` (saturation).

    Raises
    ------
    ValueError
        If ``alpha1`` or ``alpha2`` is not finite, or ``params`` is not a ValveParams.

    Notes
    -----
    Equilibrium of the averaged dynamics (Eq. 4):
    ``-alpha1*sqrt(P)/c1 + alpha2*(k2 - P)/tau2 = 0``, a quadratic in ``sqrt(P)``. Its
    positive root, Eq. 5, is
    ``P_eq = k2 + tau2²*alpha1²/(2*c1²*alpha2²)*(1 - sqrt(1 + 4*k2*c1²*alpha2²/(tau2²*alpha1²)))``.
    It is evaluated in the cancellation-free form

    ``sqrt(P_eq) = 2*k2*c1*alpha2 / (alpha1*tau2 + sqrt(alpha1²*tau2² + 4*k2*c1²*alpha2²))``,

    which needs no division by ``alpha1`` or ``alpha2``. A valve carrying its own laws
    (``params.laws``) gets the root of ``alpha2*f_open(P) + alpha1*f_closed(P)`` instead
    (:func:`spa.model.laws.equilibrium.law_equilibrium_pressure`).

    Examples
    --------
    >>> p = ValveParams()
    >>> float(equilibrium_pressure(0.0, 0.5, p)) == p.k2
    True
    >>> float(equilibrium_pressure(0.5, 0.0, p))
    0.0
    >>> round(float(equilibrium_pressure(0.25, 0.425, p)), 4)  # t_h = t_l = 20 ms
    0.3207
    """
    p = valve_params(params)
    if p.laws is not None:  # the valve's own laws: the root of the averaged rate
        from spa.model.laws.equilibrium import _equilibrium

        return _equilibrium(alpha1, alpha2, p)
    a1, a2 = np.broadcast_arrays(np.asarray(alpha1, np.float64), np.asarray(alpha2, np.float64))
    if not (np.all(np.isfinite(a1)) and np.all(np.isfinite(a2))):
        raise ValueError("alpha1 and alpha2 must be finite")
    charging = a2 > 0.0
    inside = charging & (a1 > 0.0)
    num = 2.0 * p.k2 * p.c1 * a2
    den = a1 * p.tau2 + np.sqrt((a1 * p.tau2) ** 2 + 4.0 * p.k2 * (p.c1 * a2) ** 2)
    root = safe_div(np.where(inside, num, 0.0), np.where(inside, den, 1.0), 0.0)
    peq = np.where(inside, np.minimum(root * root, p.k2), np.where(charging, p.k2, 0.0))
    return as_output(peq)


@fill_doc
def equilibrium(
    kind: str, xi: npt.ArrayLike, params: ValveParams | None = None, **settings: Any
) -> Floats:
    """Averaged equilibrium pressure of a modulator for a constant input fraction.

    Parameters
    ----------
    %(modulator_args)s

    Returns
    -------
    numpy.ndarray or numpy.float64
        ``P_eq(xi)`` in bar.

    Raises
    ------
    ValueError
        As :func:`time_fractions`.

    Notes
    -----
    ``equilibrium_pressure(*time_fractions(kind, xi, params, **settings), params)``: Eq. 5
    with the modulator's fractions (Eqs. 11–19).

    Examples
    --------
    >>> p = ValveParams()
    >>> float(equilibrium("pwm", 0.05, p, f_w=20.0))  # below t_on*f_w = 0.06
    0.0
    >>> float(equilibrium("pwm", 0.85, p, f_w=20.0)) == p.k2  # above 1 - t_off*f_w = 0.8
    True
    """
    p = valve_params(params)
    a1, a2 = time_fractions(kind, xi, p, **settings)
    return equilibrium_pressure(a1, a2, p)


def time_constant(
    alpha1: npt.ArrayLike, alpha2: npt.ArrayLike, params: ValveParams | None = None
) -> Floats:
    """Equivalent first-order time constant around the averaged equilibrium (Eq. 9).

    The arguments are those of :func:`equilibrium_pressure`.

    Returns
    -------
    numpy.ndarray or numpy.float64
        ``tau_m`` in s; NaN in the dead-zone (``alpha2 <= 0``: the pressure does not move)
        and beyond saturation (``alpha1 < 0``). At ``alpha1 = 0`` it is ``tau2/alpha2``.

    Raises
    ------
    ValueError
        As :func:`equilibrium_pressure`.

    Notes
    -----
    ``tau_m = 2*tau2*c1*sqrt(P_eq) / (alpha1*tau2 + 2*alpha2*c1*sqrt(P_eq))``, from
    ``1/tau_m = sum_i alpha_i/tau_i`` with the discharge linearised at ``P_eq``
    (``tau1 = 2*c1*sqrt(P_eq)``).

    Examples
    --------
    >>> p = ValveParams()
    >>> round(float(time_constant(0.0, 0.5, p)), 3)  # = tau2/alpha2
    1.652
    >>> bool(np.isnan(time_constant(0.5, 0.0, p)))
    True
    """
    p = valve_params(params)
    if p.laws is not None:  # the valve's own laws: linearised at their equilibrium
        from spa.model.laws.equilibrium import _time_constant

        return _time_constant(alpha1, alpha2, p)
    a1, a2 = np.broadcast_arrays(np.asarray(alpha1, np.float64), np.asarray(alpha2, np.float64))
    sq = np.sqrt(np.asarray(equilibrium_pressure(a1, a2, p)))
    valid = (a2 > 0.0) & (a1 >= 0.0)
    tau = safe_div(2.0 * p.tau2 * p.c1 * sq, a1 * p.tau2 + 2.0 * a2 * p.c1 * sq, np.nan)
    return as_output(np.where(valid, tau, np.nan))
