"""Whether a modulator setting can work on a valve at all, and if not, why.

A setting is *usable* on a valve when some input fraction moves the pressure: the setting
meets its kind's constraint (Section 5.1: a pulse longer than the delay it must outlast,
an LPWM period longer than ``t_on + t_off``), its dead-zone ends before its saturation
begins (Table 1; a PWM period below ``t_on + t_off`` has none left), and the averaged
equilibrium ``P_eq(xi)`` (Eq. 5) rises somewhere on [0, 1]. A setting that fails is left out
of every stage by name, with the sentence :func:`unusable_reason` returns, instead of
failing that stage.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
import numpy.typing as npt

from spa.model.averaging import equilibrium
from spa.model.modulators import Modulator, get_kind
from spa.model.modulators.core import settings_arrays
from spa.model.params import ValveParams, valve_params
from spa.model.thresholds import thresholds

__all__ = ["JUMP", "MIN_RISE", "rising_range", "unusable_reason", "usable"]

#: Smallest rise of ``P_eq`` over [0, 1], as a fraction of ``k2``, that counts as a range.
MIN_RISE = 1e-6

_N_XI = 401

#: A step of ``P_eq`` between adjacent grid values of ``xi`` larger than this share of
#: ``k2`` is refined (:data:`_N_REFINE` points): a step that stays more than half as large
#: is a jump (:func:`rising_range`).
JUMP = 0.01
_N_REFINE = 65


def usable(
    kind: str, value: npt.ArrayLike, params: ValveParams, **settings: Any
) -> npt.NDArray[np.bool_]:
    """Whether settings of one kind leave an input range that moves the pressure.

    Parameters
    ----------
    kind : str
        Modulator kind.
    value : array_like
        Values of the kind's swept parameter (the kind's own unit: Hz for PWM and LPWM, s
        otherwise).
    params : ValveParams
        The valve.
    **settings
        The other settings (e.g. ``gain``), broadcast against ``value``.

    Returns
    -------
    numpy.ndarray of bool
        True where the kind's constraint holds and the dead-zone threshold is below the
        saturation threshold (Table 1).

    Examples
    --------
    >>> p = ValveParams(t_on=0.005, t_off=0.030)
    >>> usable("pwm", [10.0, 20.0, 30.0], p).tolist()
    [True, True, False]
    """
    spec = get_kind(kind)
    v = np.asarray(value, dtype=np.float64)
    ok = np.asarray(spec.feasible(v, params), dtype=bool)
    if not ok.any():  # nothing feasible (e.g. LPWM on laws it cannot invert): no thresholds
        return ok
    s = settings_arrays(kind, {spec.parameter: v, **settings})
    dead, sat = thresholds(kind, params, **s)
    return ok & (np.asarray(dead) < np.asarray(sat))


def rising_range(
    modulator: Modulator | Mapping[str, Any], params: ValveParams | None = None
) -> tuple[float, float] | None:
    """The pressures the averaged equilibrium reaches while it rises with ``xi``, without a
    jump: the part of ``P_eq`` on [0, 1] that rises the most between its jumps.

    Under the transport convention, a valve that opens later than it closes
    (``t_on > t_off``) stays closed for at least ``t_on - t_off`` in every PWM period,
    however short the command's off-time: its modulated ``P_eq`` stops short of ``k2``,
    which it reaches only at ``xi = 1``, the valve held open. The pressures in that jump
    cannot be held by modulating (the loop would switch between the valve held open and the
    highest modulated pressure), so they are not in the range.

    Parameters
    ----------
    modulator : Modulator or mapping
        The setting (an LPWM without a valve inverts ``params``).
    params : ValveParams, optional
        The valve; nominal when omitted.

    Returns
    -------
    (lo, hi) or None
        ``P_eq`` at the start and the end of its rising part, bar; None when it does not
        rise by at least :data:`MIN_RISE` ``* k2`` anywhere on [0, 1].

    Examples
    --------
    >>> lo, hi = rising_range({"type": "pwm", "f_w": 20.0})
    >>> round(lo, 3), round(hi, 3)
    (0.0, 0.837)
    >>> slow = ValveParams(t_on=0.025, t_off=0.01, delay="transport")  # opens after it closes
    >>> round(rising_range({"type": "pwm", "f_w": 20.0}, slow)[1], 3), slow.k2
    (0.408, 0.837)
    """
    p = valve_params(params)
    mod = Modulator.from_mapping(modulator).bind(p)
    xi = np.linspace(0.0, 1.0, _N_XI)

    def peq_at(x: np.ndarray) -> np.ndarray:
        with np.errstate(all="ignore"):
            return np.asarray(equilibrium(mod.kind, x, p, **mod.settings), dtype=np.float64)

    peq = peq_at(xi)
    ok = np.isfinite(peq)
    xi, peq = xi[ok], peq[ok]
    if peq.size < 2 or float(peq.max() - peq.min()) <= MIN_RISE * p.k2:
        return None
    # split the curve where it jumps: a step that a finer grid does not shrink
    step = np.abs(np.diff(peq))
    cuts = []
    for i in np.flatnonzero(step > JUMP * p.k2):
        fine = peq_at(np.linspace(xi[i], xi[i + 1], _N_REFINE))
        if np.nanmax(np.abs(np.diff(fine))) > 0.5 * step[i]:
            cuts.append(int(i) + 1)
    parts = [q for q in np.split(peq, cuts) if q.size]
    best = max(parts, key=lambda q: float(q.max() - q.min()))
    if float(best.max() - best.min()) <= MIN_RISE * p.k2:
        return None
    return float(best.min()), float(best.max())


def unusable_reason(
    modulator: Modulator | Mapping[str, Any], params: ValveParams | None = None
) -> str | None:
    """Why a setting cannot work on a valve, or None when it can.

    Parameters
    ----------
    modulator : Modulator or mapping
        The setting.
    params : ValveParams, optional
        The valve; nominal when omitted.

    Returns
    -------
    str or None
        One sentence naming the setting, the rule it breaks and the valve's numbers, e.g.
        ``iipfm-20ms: t_l = 20 ms is not longer than t_off = 25 ms ...``.

    Examples
    --------
    >>> why = unusable_reason({"type": "iipfm", "t_l": 0.02}, ValveParams(t_off=0.025))
    >>> why[:60]
    'iipfm-20ms: unusable on this valve: it needs t_l > t_off = 2'
    >>> why[-49:]
    '(the valve would not finish switching in a pulse)'
    >>> unusable_reason({"type": "pwm", "f_w": 20.0}) is None
    True
    """
    p = valve_params(params)
    mod = Modulator.from_mapping(modulator).bind(p)
    spec = get_kind(mod.kind)
    if not bool(np.asarray(spec.feasible(np.asarray(mod.value, dtype=np.float64), p))):
        return (
            f"{mod.label}: unusable on this valve: it needs {spec.constraint(p)} "
            "(the valve would not finish switching in a pulse)"
        )
    dead, sat = (float(v) for v in thresholds(mod.kind, p, **mod.settings))
    if dead >= sat:
        return (
            f"{mod.label}: unusable on this valve: its dead-zone (xi up to {dead:.2f}) reaches "
            f"its saturation (xi from {sat:.2f}), so no input fraction moves the pressure "
            f"(t_on = {p.t_on * 1e3:g} ms, t_off = {p.t_off * 1e3:g} ms)"
        )
    if rising_range(mod, p) is None:
        return (
            f"{mod.label}: unusable on this valve: its averaged equilibrium P_eq(xi) is flat, "
            "so no input fraction moves the pressure"
        )
    return None
