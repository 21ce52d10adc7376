"""The averaged equilibrium and time constant under general laws (docs/model.md section 3,
"The general two-mode model").

Averaged over one modulation cycle the pressure moves at ``alpha2*f_open(P) +
alpha1*f_closed(P)``; its equilibrium ``P_eq`` is where that rate vanishes, and the
equivalent time constant is the inverse of the rate's slope there. With the paper's laws
these are Eq. 5 and Eq. 9 (:func:`spa.model.averaging.equilibrium_pressure`,
:func:`spa.model.averaging.time_constant`), which are returned unchanged for a valve
without laws.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from spa.model import averaging
from spa.model._broadcast import Floats, as_output
from spa.model.laws.rates import closed_rate, open_rate
from spa.model.laws.value import Laws
from spa.model.params import ValveParams, valve_params

__all__ = ["law_equilibrium_pressure", "law_time_constant"]

_BISECTIONS = 64


def _fractions(alpha1: npt.ArrayLike, alpha2: npt.ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    a1, a2 = np.broadcast_arrays(np.asarray(alpha1, np.float64), np.asarray(alpha2, np.float64))
    if not (np.all(np.isfinite(a1)) and np.all(np.isfinite(a2))):
        raise ValueError("alpha1 and alpha2 must be finite")
    return a1, a2


def law_equilibrium_pressure(
    alpha1: npt.ArrayLike,
    alpha2: npt.ArrayLike,
    params: ValveParams | None = None,
    laws: Laws | None = None,
) -> Floats:
    """Averaged equilibrium pressure under the valve's laws.

    Parameters
    ----------
    alpha1, alpha2 : array_like of float
        Discharging and charging time fractions
        (:func:`spa.model.averaging.time_fractions`); broadcast.
    params : ValveParams, optional
        The valve; nominal when omitted. Without laws (``params.laws is None``) the result
        is :func:`spa.model.averaging.equilibrium_pressure` (Eq. 5), bit for bit.
    laws : Laws, optional
        Laws to use instead of ``params.laws``; given, the general root-finding runs even
        for the paper's laws.

    Returns
    -------
    numpy.ndarray or numpy.float64
        ``P_eq`` in bar, in ``[0, k2]``: ``0`` where ``alpha2 <= 0`` (dead-zone), ``k2``
        where ``alpha1 <= 0 < alpha2`` (saturation), elsewhere the root of
        ``alpha2*f_open(P) + alpha1*f_closed(P) = 0``.

    Raises
    ------
    ValueError
        If ``alpha1`` or ``alpha2`` is not finite.

    Notes
    -----
    The rate is ``alpha2*k2*g(0) > 0`` at ``P = 0`` and ``-alpha1*k2**m*h(k2) < 0`` at
    ``k2``, so ``[0, k2]`` brackets a root; 64 bisections, vectorised over the fractions,
    find it to the last bit. Rates that are not monotone may give several roots; the
    bisection returns one of them (the largest stable one where the rate changes sign
    once).

    Examples
    --------
    >>> p = ValveParams()
    >>> eq5 = float(averaging.equilibrium_pressure(0.25, 0.425, p))
    >>> abs(float(law_equilibrium_pressure(0.25, 0.425, p, Laws())) - eq5) < 1e-15
    True
    """
    return _equilibrium(alpha1, alpha2, valve_params(params), laws)


def _equilibrium(
    alpha1: npt.ArrayLike, alpha2: npt.ArrayLike, p: ValveParams, laws: Laws | None = None
) -> Floats:
    """:func:`law_equilibrium_pressure` of a valve already checked (where it entered:
    :func:`spa.model.averaging.equilibrium_pressure`'s dispatch)."""
    if laws is None and p.laws is None:
        return averaging.equilibrium_pressure(alpha1, alpha2, p)
    a1, a2 = _fractions(alpha1, alpha2)
    charging = a2 > 0.0
    inside = charging & (a1 > 0.0)
    lo = np.zeros(a1.shape)
    hi = np.full(a1.shape, p.k2)
    w1, w2 = np.where(inside, a1, 0.0), np.where(inside, a2, 0.0)
    for _ in range(_BISECTIONS):
        mid = 0.5 * (lo + hi)
        rate = w2 * open_rate(mid, p, laws) + w1 * closed_rate(mid, p, laws)
        up = rate > 0.0
        lo = np.where(up, mid, lo)
        hi = np.where(up, hi, mid)
    peq = np.where(inside, 0.5 * (lo + hi), np.where(charging, p.k2, 0.0))
    return as_output(peq)


def law_time_constant(
    alpha1: npt.ArrayLike,
    alpha2: npt.ArrayLike,
    params: ValveParams | None = None,
    laws: Laws | None = None,
) -> Floats:
    """Equivalent first-order time constant around the averaged equilibrium.

    The arguments are those of :func:`law_equilibrium_pressure`; without laws the result is
    :func:`spa.model.averaging.time_constant` (Eq. 9), bit for bit.

    Returns
    -------
    numpy.ndarray or numpy.float64
        ``tau_m = -1/(alpha2*f_open'(P_eq) + alpha1*f_closed'(P_eq))`` in s; NaN in the
        dead-zone (``alpha2 <= 0``) and beyond saturation (``alpha1 < 0``).

    Notes
    -----
    With the paper's laws ``f_open' = -1/tau2`` and ``f_closed' = -1/(2*c1*sqrt(P))``,
    which gives Eq. 9, ``tau_m = 2*tau2*c1*sqrt(P_eq)/(alpha1*tau2 + 2*alpha2*c1*sqrt(P_eq))``.

    Examples
    --------
    >>> p = ValveParams()
    >>> eq9 = float(averaging.time_constant(0.25, 0.425, p))
    >>> abs(float(law_time_constant(0.25, 0.425, p, Laws())) - eq9) < 1e-12
    True
    """
    return _time_constant(alpha1, alpha2, valve_params(params), laws)


def _time_constant(
    alpha1: npt.ArrayLike, alpha2: npt.ArrayLike, p: ValveParams, laws: Laws | None = None
) -> Floats:
    """:func:`law_time_constant` of a valve already checked (where it entered:
    :func:`spa.model.averaging.time_constant`'s dispatch)."""
    if laws is None and p.laws is None:
        return averaging.time_constant(alpha1, alpha2, p)
    a1, a2 = _fractions(alpha1, alpha2)
    peq = np.asarray(_equilibrium(a1, a2, p, laws))
    valid = (a2 > 0.0) & (a1 >= 0.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        slope = a2 * open_rate(peq, p, laws, slope=True) + np.where(
            a1 > 0.0, a1 * closed_rate(peq, p, laws, slope=True), 0.0
        )
        tau = -1.0 / slope
    return as_output(np.where(valid & np.isfinite(tau), tau, np.nan))
