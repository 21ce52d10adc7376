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

import math

import numpy as np
import numpy.typing as npt

from spa.model import averaging
from spa.model._broadcast import Floats, as_output
from spa.model.laws.rates import closed_rate, open_rate, valve_laws
from spa.model.laws.value import Laws
from spa.model.params import ValveParams, valve_params

__all__ = ["law_equilibrium_pressure", "law_time_constant"]

# Newton's method on the averaged rate, kept inside its bracket (bisection where a step would
# leave it): at most this many steps, each element stopping when its step is below _STEP*k2.
_ITERATIONS = 100
_STEP = 4.0 * np.finfo(np.float64).eps
_CLOSE = 1e-11
_START_NODES = 1025


def _fractions(alpha1: npt.ArrayLike, alpha2: npt.ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    a1, a2 = np.broadcast_arrays(np.asarray(alpha1, np.float64), np.asarray(alpha2, np.float64))
    if not (np.all(np.isfinite(a1)) and np.all(np.isfinite(a2))):
        raise ValueError("alpha1 and alpha2 must be finite")
    return a1, a2


def _start(ratio: np.ndarray, p: ValveParams, lw: Laws) -> np.ndarray:
    """Newton's start for the fractions' ratio ``alpha2/alpha1``: where the rates' ratio
    ``-f_closed/f_open`` (increasing in ``P`` for most laws) takes it on a grid of
    :data:`_START_NODES` pressures; the middle of ``[0, k2]`` where it is not increasing."""
    grid = p.k2 * np.linspace(0.0, 1.0, _START_NODES)[1:-1]
    rates = -closed_rate(grid, p, lw) / open_rate(grid, p, lw)
    if not np.all(np.diff(rates) > 0.0):
        return np.full(ratio.shape, 0.5 * p.k2)
    return np.interp(ratio, rates, grid)


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
    ``k2``, so ``[0, k2]`` brackets a root. Newton's method on the log-ratio of the two
    terms, ``log(alpha2*f_open) - log(-alpha1*f_closed)`` (the rate's sign, and smooth near
    ``0`` and ``k2`` where the rate's slope diverges), with its exact slope, kept inside the
    shrinking bracket (a bisection step where Newton's would leave it) and vectorised over
    the fractions, finds it to the last bits in a few steps. Rates
    that are not monotone may give several roots; the iteration returns one of them (the
    only one where the rate changes sign once).

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
    peq = np.where(charging, p.k2, 0.0)
    w1, w2 = a1[inside], a2[inside]
    lw = valve_laws(p) if laws is None else laws
    lo, hi = np.zeros(w1.shape), np.full(w1.shape, p.k2)
    x = _start(w2 / w1, p, lw)
    todo = np.arange(w1.size)  # the elements still moving; each stops on its own step
    # log(h/g) less the log-rates: log(tau2*k2**(1/2 - m)/c1)
    offset = math.log(p.tau2 * p.k2 ** (0.5 - lw.m) / p.c1)
    for _ in range(_ITERATIONS):
        if not todo.size:
            break
        xt, b1, b2 = x[todo], w1[todo], w2[todo]
        da, db = lw.log_rates(xt / p.k2, derivative=True)
        a, b = lw.log_rates(xt / p.k2)
        gap = p.k2 - xt
        with np.errstate(divide="ignore", invalid="ignore"):
            # log(alpha2*f_open) - log(-alpha1*f_closed): the rate's sign, smooth in log P
            # and log(k2 - P) at both ends, where the rate's own slope diverges.
            rate = (np.log(b2 * gap) + a) - (np.log(b1) + lw.m * np.log(xt) + b + offset)
            slope = -1.0 / gap + (da - db) / p.k2 - lw.m / xt
            newton = xt - rate / slope
        up = rate > 0.0
        lo_t = np.where(up, xt, lo[todo])
        hi_t = np.where(up, hi[todo], xt)
        lo_t = np.where(rate == 0.0, xt, lo_t)
        hi_t = np.where(rate == 0.0, xt, hi_t)
        ok = np.isfinite(newton) & (newton > lo_t) & (newton < hi_t)
        new = np.where(ok, newton, 0.5 * (lo_t + hi_t))
        # A step within rounding of the root stays put, wherever rounding puts it.
        new = np.where(np.abs(newton - xt) <= _STEP * p.k2, xt, new)
        new = np.where(rate == 0.0, xt, new)
        lo[todo], hi[todo], x[todo] = lo_t, hi_t, new
        # A Newton step below _CLOSE*k2 leaves an error of its square's order: the last one.
        close = ok & (np.abs(newton - xt) <= _CLOSE * p.k2)
        moving = ~close & (np.abs(new - xt) > _STEP * p.k2) & (hi_t - lo_t > _STEP * p.k2)
        todo = todo[moving]
    peq[inside] = x
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
