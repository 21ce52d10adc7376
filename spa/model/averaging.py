"""Averaged analysis of a pulse-driven valve feeding a soft actuator (MODEL.md section 3).

Section 4.2 of the paper replaces the switched plant by its average over one pulse period:
the actuator discharges for the fraction ``alpha1`` of the period and charges for the fraction
``alpha2``, the valve's opening and closing delays being dead time. Everything here is a
closed form in the input fraction ``xi`` and the modulator's settings:

* :func:`pulse_times` – steady high/low durations of each modulator (Appendix A);
* :func:`time_fractions` – the effective fractions ``alpha1``, ``alpha2`` (Eqs. 6–7);
* :func:`equilibrium_pressure`, :func:`equilibrium` – the averaged equilibrium (Eq. 5);
* :func:`time_constant` – the equivalent time constant (Eq. 9);
* :func:`chattering_estimate` – the chattering estimate (Eq. 10);
* :func:`pseudo_steady_state`, :func:`pseudo_steady_mean` – the exact periodic extrema for a
  fixed pulse train (Appendix B), no averaging assumed;
* :func:`thresholds`, :func:`threshold_table` – dead-zone and saturation (Table 1).

All functions are vectorised: ``xi`` and the modulator settings may be scalars or arrays and
broadcast against each other (NumPy rules); a scalar in gives a NumPy scalar out.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from typing import Any, TypeAlias

import numpy as np
import numpy.typing as npt
import pandas as pd

from spa.model.modulators import MODULATORS, check_settings
from spa.model.params import ValveParams

__all__ = [
    "THRESHOLD_FORMULAS",
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

#: A float64 array, or a NumPy float scalar when every input was a scalar.
Floats: TypeAlias = npt.NDArray[np.float64] | np.float64

#: Table 1 as text: ``kind -> (dead-zone, saturation)`` closed forms of ``xi`` (clipped to
#: [0, 1]). The ΔΣM forms reduce to the paper's 0 and 1 when ``period >= 2*t_on, 2*t_off``.
THRESHOLD_FORMULAS: Mapping[str, tuple[str, str]] = {
    "pwm": ("t_on*f_w", "1 - t_off*f_w"),
    "ipfm": ("0", "gain*t_h/(t_h + t_off)"),
    "iipfm": ("1 - gain/(1 + t_on/t_l)", "1"),
    "dsm": ("max(0, 1 - period/(2*t_on))", "min(1, period/(2*t_off))"),
}


# --------------------------------------------------------------------------- validation
def _params(params: ValveParams | None) -> ValveParams:
    if params is None:
        return ValveParams()
    if not isinstance(params, ValveParams):
        raise ValueError(f"params must be a ValveParams, got {type(params).__name__}")
    return params


def _xi(xi: npt.ArrayLike) -> npt.NDArray[np.float64]:
    try:
        x = np.asarray(xi, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"xi must be numeric, got {xi!r}") from None
    if not np.all(np.isfinite(x)):
        raise ValueError("xi must be finite (no NaN or inf)")
    return np.clip(x, 0.0, 1.0)


def _settings(kind: str, settings: Mapping[str, Any]) -> dict[str, Any]:
    """Validate settings like :func:`spa.model.modulators.check_settings`, allowing arrays.

    Scalar settings go through ``check_settings`` unchanged (same messages); array-valued
    ones must be finite and > 0 everywhere.
    """
    scalars: dict[str, Any] = {}
    arrays: dict[str, npt.NDArray[np.float64]] = {}
    for name, value in settings.items():
        if np.ndim(value) == 0:
            scalars[name] = value
            continue
        try:
            arrays[name] = np.asarray(value, dtype=np.float64)
        except (TypeError, ValueError):
            raise ValueError(f"{kind}: setting {name!r} must be numeric, got {value!r}") from None
    out: dict[str, Any] = check_settings(kind, **scalars, **dict.fromkeys(arrays, 1.0))
    for name, a in arrays.items():
        if not np.all(np.isfinite(a) & (a > 0.0)):
            raise ValueError(f"{kind}: setting {name!r} must be finite and > 0 everywhere")
        out[name] = a
    return out


def _out(a: npt.NDArray[np.float64]) -> Floats:
    """0-d arrays become NumPy scalars; other arrays pass through."""
    return np.asarray(a, dtype=np.float64)[()]


def _safe_div(num: npt.ArrayLike, den: npt.ArrayLike, fill: float) -> npt.NDArray[np.float64]:
    """``num/den`` where ``den != 0``, else ``fill``; never warns."""
    num, den = np.broadcast_arrays(np.asarray(num, np.float64), np.asarray(den, np.float64))
    out = np.full(num.shape, fill, dtype=np.float64)
    np.divide(num, den, out=out, where=den != 0.0)
    return out


# --------------------------------------------------------------------------- pulse trains
def pulse_times(kind: str, xi: npt.ArrayLike, **settings: Any) -> tuple[Floats, Floats]:
    """Steady high and low durations of a modulator's pulse train for a constant input.

    Parameters
    ----------
    kind : {"pwm", "ipfm", "iipfm", "dsm"}
        Modulator type.
    xi : array_like of float
        Input fraction; clipped to [0, 1].
    **settings
        ``f_w`` (Hz) for PWM; ``t_h`` (s) and ``gain`` (default 1) for IPFM; ``t_l`` (s) and
        ``gain`` (default 1) for IIPFM; ``period`` (s) for ΔΣM. Scalars or arrays that
        broadcast with ``xi``.

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
    s = _settings(kind, settings)
    x = _xi(xi)
    if kind == "pwm":
        t_h = x / s["f_w"]
        t_l = (1.0 - x) / s["f_w"]
    elif kind == "ipfm":
        t_h = np.broadcast_to(s["t_h"], np.broadcast_shapes(np.shape(x), np.shape(s["t_h"])))
        ratio = _safe_div(s["gain"], x, np.inf)
        t_l = t_h * np.maximum(ratio - 1.0, 0.0)
    elif kind == "iipfm":
        t_l = np.broadcast_to(s["t_l"], np.broadcast_shapes(np.shape(x), np.shape(s["t_l"])))
        ratio = _safe_div(s["gain"], 1.0 - x, np.inf)
        t_h = t_l * np.maximum(ratio - 1.0, 0.0)
    else:
        t_h = _safe_div(s["period"], 2.0 * (1.0 - x), np.inf)
        t_l = _safe_div(s["period"], 2.0 * x, np.inf)
    return _out(np.asarray(t_h)), _out(np.asarray(t_l))


def time_fractions(
    kind: str, xi: npt.ArrayLike, params: ValveParams | None = None, **settings: Any
) -> tuple[Floats, Floats]:
    """Effective discharging and charging fractions of the period (Eqs. 6–7).

    Parameters
    ----------
    kind : {"pwm", "ipfm", "iipfm", "dsm"}
        Modulator type.
    xi : array_like of float
        Input fraction; clipped to [0, 1].
    params : ValveParams, optional
        Valve parameters (``t_on``, ``t_off`` are used); nominal when omitted.
    **settings
        Modulator settings as in :func:`pulse_times`; may be arrays broadcasting with ``xi``.

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
    MODEL.md section 3 (paper Section 4.3.1), with ``f = 1/T_DS`` for ΔΣM:

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
    p = _params(params)
    s = _settings(kind, settings)
    x = _xi(xi)
    if kind == "pwm":
        a1 = (1.0 - x) - p.t_off * s["f_w"]
        a2 = x - p.t_on * s["f_w"]
    elif kind == "ipfm":
        a1 = 1.0 - (1.0 + p.t_off / s["t_h"]) * x / s["gain"]
        a2 = (1.0 - p.t_on / s["t_h"]) * x / s["gain"]
    elif kind == "iipfm":
        a1 = (1.0 - p.t_off / s["t_l"]) * (1.0 - x) / s["gain"]
        a2 = 1.0 - (1.0 + p.t_on / s["t_l"]) * (1.0 - x) / s["gain"]
    else:
        f = 1.0 / s["period"]
        a1 = (1.0 - x) * (1.0 - 2.0 * f * p.t_off * x)
        a2 = x * (1.0 - 2.0 * f * p.t_on * (1.0 - x))
    return _out(np.asarray(a1)), _out(np.asarray(a2))


# --------------------------------------------------------------------------- equilibrium
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

    which needs no division by ``alpha1`` or ``alpha2``.

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
    p = _params(params)
    a1, a2 = np.broadcast_arrays(np.asarray(alpha1, np.float64), np.asarray(alpha2, np.float64))
    if not (np.all(np.isfinite(a1)) and np.all(np.isfinite(a2))):
        raise ValueError("alpha1 and alpha2 must be finite")
    charging = a2 > 0.0
    inside = charging & (a1 > 0.0)
    num = 2.0 * p.k2 * p.c1 * a2
    den = a1 * p.tau2 + np.sqrt((a1 * p.tau2) ** 2 + 4.0 * p.k2 * (p.c1 * a2) ** 2)
    root = _safe_div(np.where(inside, num, 0.0), np.where(inside, den, 1.0), 0.0)
    peq = np.where(inside, np.minimum(root * root, p.k2), np.where(charging, p.k2, 0.0))
    return _out(peq)


def equilibrium(
    kind: str, xi: npt.ArrayLike, params: ValveParams | None = None, **settings: Any
) -> Floats:
    """Averaged equilibrium pressure of a modulator for a constant input fraction.

    Parameters
    ----------
    kind : {"pwm", "ipfm", "iipfm", "dsm"}
        Modulator type.
    xi : array_like of float
        Input fraction; clipped to [0, 1].
    params : ValveParams, optional
        Valve parameters; nominal when omitted.
    **settings
        Modulator settings as in :func:`pulse_times`; may be arrays broadcasting with ``xi``.

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
    p = _params(params)
    a1, a2 = time_fractions(kind, xi, p, **settings)
    return equilibrium_pressure(a1, a2, p)


def time_constant(
    alpha1: npt.ArrayLike, alpha2: npt.ArrayLike, params: ValveParams | None = None
) -> Floats:
    """Equivalent first-order time constant around the averaged equilibrium (Eq. 9).

    Parameters
    ----------
    alpha1, alpha2 : array_like of float
        Time fractions (:func:`time_fractions`); broadcast.
    params : ValveParams, optional
        Valve parameters; nominal when omitted.

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
    p = _params(params)
    a1, a2 = np.broadcast_arrays(np.asarray(alpha1, np.float64), np.asarray(alpha2, np.float64))
    sq = np.sqrt(np.asarray(equilibrium_pressure(a1, a2, p)))
    valid = (a2 > 0.0) & (a1 >= 0.0)
    tau = _safe_div(2.0 * p.tau2 * p.c1 * sq, a1 * p.tau2 + 2.0 * a2 * p.c1 * sq, np.nan)
    return _out(np.where(valid, tau, np.nan))


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
    duration. It is an estimate for short pulses; :func:`pseudo_steady_state` is exact.

    Examples
    --------
    >>> p = ValveParams()
    >>> round(float(chattering_estimate(0.02, 0.4, p)), 5)
    0.01058
    """
    p = _params(params)
    th, pe = np.broadcast_arrays(np.asarray(t_h, np.float64), np.asarray(p_eq, np.float64))
    gap = np.maximum(p.k2 - pe, 0.0)
    with np.errstate(invalid="ignore"):
        d = th * gap / p.tau2
    return _out(np.where(gap > 0.0, d, 0.0))


# --------------------------------------------------------------------------- Appendix B
def pseudo_steady_state(
    t_h: npt.ArrayLike, t_l: npt.ArrayLike, params: ValveParams | None = None
) -> tuple[Floats, Floats]:
    """Exact pseudo-steady extrema of the pressure for a fixed periodic pulse train (App. B).

    Parameters
    ----------
    t_h, t_l : array_like of float
        High and low durations of the command in s (>= 0, may be ``inf``); broadcast.
    params : ValveParams, optional
        Valve parameters; nominal when omitted.

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

    Examples
    --------
    >>> p = ValveParams()
    >>> hi, lo = pseudo_steady_state(0.02, 0.02, p)
    >>> round(float(hi), 4), round(float(lo), 4)
    (0.326, 0.3154)
    """
    p = _params(params)
    th, tl = np.broadcast_arrays(np.asarray(t_h, np.float64), np.asarray(t_l, np.float64))
    if np.any(np.isnan(th)) or np.any(np.isnan(tl)) or np.any(th < 0) or np.any(tl < 0):
        raise ValueError("t_h and t_l must be >= 0 (inf allowed), not NaN")
    h = np.maximum(th - p.t_on, 0.0)
    l_eff = np.maximum(tl - p.t_off, 0.0)
    charges = (h > 0.0) & np.isfinite(tl)
    discharges = (l_eff > 0.0) & np.isfinite(th)
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
    return _out(p_plus), _out(p_minus)


def pseudo_steady_mean(
    t_h: npt.ArrayLike, t_l: npt.ArrayLike, params: ValveParams | None = None
) -> Floats:
    """Fast-switching estimate of the equilibrium: the mid-point ``(P+ + P-)/2`` (App. B).

    Parameters
    ----------
    t_h, t_l : array_like of float
        High and low durations in s; broadcast.
    params : ValveParams, optional
        Valve parameters; nominal when omitted.

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
    return _out(0.5 * (np.asarray(hi) + np.asarray(lo)))


# --------------------------------------------------------------------------- Table 1
def thresholds(
    kind: str, params: ValveParams | None = None, **settings: Any
) -> tuple[Floats, Floats]:
    """Dead-zone and saturation thresholds of the input fraction (Table 1).

    Parameters
    ----------
    kind : {"pwm", "ipfm", "iipfm", "dsm"}
        Modulator type.
    params : ValveParams, optional
        Valve parameters (``t_on``, ``t_off``); nominal when omitted.
    **settings
        Modulator settings as in :func:`pulse_times` (scalars or arrays).

    Returns
    -------
    dead_zone, saturation : numpy.ndarray or numpy.float64
        ``dead_zone``: the largest ``xi`` in [0, 1] with ``alpha2(xi) <= 0`` (``P_eq = 0`` up
        to it). ``saturation``: the smallest ``xi`` in [0, 1] with ``alpha1(xi) <= 0``
        (``P_eq = k2`` from it); 1 when the actuator saturates only at ``xi = 1`` or never.

    Raises
    ------
    ValueError
        As :func:`time_fractions`.

    Notes
    -----
    The zero crossings of the fractions of :func:`time_fractions`, clipped to [0, 1]:

    =======  =================================  ==================================
    kind     dead-zone                          saturation
    =======  =================================  ==================================
    PWM      ``t_on*f_w``                       ``1 - t_off*f_w``
    IPFM     0 (1 if ``t_h <= t_on``)           ``G*t_h/(t_h + t_off)``
    IIPFM    ``1 - G/(1 + t_on/t_l)``           1 (0 if ``t_l <= t_off``)
    ΔΣM      ``1 - T_DS/(2*t_on)``              ``T_DS/(2*t_off)``
    =======  =================================  ==================================

    These are Table 1 of the paper (with ``G = 1`` for IPFM). For ΔΣM the paper prints 0
    and 1, which is what the formulas give when ``T_DS >= 2*t_on`` and ``T_DS >= 2*t_off``;
    for ``t_off < T_DS < 2*t_off`` the averaged fractions (built on the paper's approximate
    firing frequency ``2*xi*(1 - xi)/T_DS``) saturate before ``xi = 1``.

    Examples
    --------
    >>> p = ValveParams()
    >>> [round(float(v), 6) for v in thresholds("pwm", p, f_w=20.0)]
    [0.06, 0.8]
    >>> [round(float(v), 6) for v in thresholds("iipfm", p, t_l=0.02, gain=1.15)]
    [0.0, 1.0]
    """
    p = _params(params)
    s = _settings(kind, settings)
    if kind == "pwm":
        dead = p.t_on * s["f_w"]
        sat = 1.0 - p.t_off * s["f_w"]
    elif kind == "ipfm":
        dead = np.where(s["t_h"] > p.t_on, 0.0, 1.0)
        sat = s["gain"] * s["t_h"] / (s["t_h"] + p.t_off)
    elif kind == "iipfm":
        dead = 1.0 - s["gain"] / (1.0 + p.t_on / s["t_l"])
        sat = np.where(s["t_l"] > p.t_off, 1.0, 0.0)
    else:
        dead = 1.0 - s["period"] / (2.0 * p.t_on)
        sat = s["period"] / (2.0 * p.t_off)
    return (
        _out(np.clip(np.asarray(dead, np.float64), 0.0, 1.0)),
        _out(np.clip(np.asarray(sat, np.float64), 0.0, 1.0)),
    )


def threshold_table(
    selected: Iterable[Mapping[str, Any]], params: ValveParams | None = None
) -> pd.DataFrame:
    """Table 1 for a list of modulator settings, as a tidy table.

    Parameters
    ----------
    selected : iterable of mapping
        Entries like ``{"type": "iipfm", "t_l": 0.02, "gain": 1.15}`` (the ``analytic.selected``
        section of the configuration).
    params : ValveParams, optional
        Valve parameters; nominal when omitted.

    Returns
    -------
    pandas.DataFrame
        One row per entry: ``modulator``, ``settings`` (``name=value`` pairs, defaults filled
        in), ``dead_zone_formula``, ``dead_zone``, ``saturation_formula``, ``saturation``.

    Raises
    ------
    ValueError
        If an entry has no ``type`` or bad settings.

    Examples
    --------
    >>> threshold_table([{"type": "pwm", "f_w": 20.0}])[["dead_zone", "saturation"]].round(6)
       dead_zone  saturation
    0       0.06         0.8
    """
    p = _params(params)
    rows = []
    for i, entry in enumerate(selected):
        settings = dict(entry)
        kind = settings.pop("type", None)
        if kind is None:
            raise ValueError(f"selected[{i}]: missing 'type'; expected one of {sorted(MODULATORS)}")
        full = check_settings(kind, **settings)
        dead, sat = thresholds(kind, p, **full)
        rows.append(
            {
                "modulator": kind,
                "settings": " ".join(f"{k}={v:g}" for k, v in full.items()),
                "dead_zone_formula": THRESHOLD_FORMULAS[kind][0],
                "dead_zone": float(dead),
                "saturation_formula": THRESHOLD_FORMULAS[kind][1],
                "saturation": float(sat),
            }
        )
    return pd.DataFrame(rows)
