"""The averaged model's pulse trains (Appendix A): pulse times and the time fractions of each
state, and the argument checks shared by the averaged analysis."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, TypeAlias

import numpy as np
import numpy.typing as npt

from spa.model.modulators import check_settings
from spa.model.params import ValveParams

#: A float64 array, or a NumPy float scalar when every input was a scalar.
Floats: TypeAlias = npt.NDArray[np.float64] | np.float64


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
