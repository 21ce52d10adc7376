"""Equilibrium pressure (Eq. 5) and time constant (Eq. 9) of the averaged model."""

from __future__ import annotations

from typing import Any

import numpy as np
import numpy.typing as npt

from spa.model.params import ValveParams
from spa.model.pulses import Floats, _out, _params, _safe_div, time_fractions


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
