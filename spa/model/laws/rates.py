"""The two modes' rates ``f_open``, ``f_closed`` and their slopes for a valve with laws."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

from spa.model.laws.value import Laws

if TYPE_CHECKING:  # pragma: no cover
    from spa.model.params import ValveParams

__all__ = ["closed_rate", "law_rates", "open_rate", "valve_laws"]


def valve_laws(params: ValveParams) -> Laws:
    """The valve's laws: ``params.laws``, or the paper's as a :class:`Laws` when None."""
    return params.laws if params.laws is not None else Laws()


def law_rates(
    p: npt.ArrayLike, params: ValveParams, laws: Laws | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """``g(p)`` (1/s) and ``h(p)`` (bar**(1-m)/s) of the valve's (or the given) laws.

    Parameters
    ----------
    p : array_like
        Pressure, bar (gauge).
    params : ValveParams
        The valve: ``k2`` sets the knots' scale, ``tau2`` and ``c1`` the rates' scales.
    laws : Laws, optional
        Laws to use instead of ``params.laws`` (the paper's as a :class:`Laws` object, for
        instance, to run the general code on the nested case).

    Returns
    -------
    g, h : numpy.ndarray
        ``exp(a(p/k2))/tau2`` and ``sqrt(k2)*k2**(-m)*exp(b(p/k2))/c1``.
    """
    lw = valve_laws(params) if laws is None else laws
    a, b = lw.log_rates(np.asarray(p, dtype=np.float64) / params.k2)
    g = np.exp(a) / params.tau2
    h = np.exp(b) * (params.k2 ** (0.5 - lw.m) / params.c1)
    return g, h


def open_rate(
    p: npt.ArrayLike, params: ValveParams, laws: Laws | None = None, slope: bool = False
) -> np.ndarray:
    """``f_open(p) = (k2 - p)*g(p)`` in bar/s, or its slope ``df_open/dp`` (1/s)."""
    x = np.asarray(p, dtype=np.float64)
    g, _ = law_rates(x, params, laws)
    if not slope:
        return (params.k2 - x) * g
    lw = valve_laws(params) if laws is None else laws
    da, _ = lw.log_rates(x / params.k2, derivative=True)
    return -g + (params.k2 - x) * g * da / params.k2


def closed_rate(
    p: npt.ArrayLike, params: ValveParams, laws: Laws | None = None, slope: bool = False
) -> np.ndarray:
    """``f_closed(p) = -p**m * h(p)`` in bar/s, or its slope ``df_closed/dp`` (1/s; infinite
    at ``p = 0`` for ``m < 1``)."""
    x = np.maximum(np.asarray(p, dtype=np.float64), 0.0)
    lw = valve_laws(params) if laws is None else laws
    _, h = law_rates(x, params, lw)
    if not slope:
        return -(x**lw.m) * h
    _, db = lw.log_rates(x / params.k2, derivative=True)
    with np.errstate(divide="ignore"):
        return -(lw.m * x ** (lw.m - 1.0) * h + x**lw.m * h * db / params.k2)
