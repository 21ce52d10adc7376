"""The plants of the promise's box: the set-points every one of them holds, and the hold that
lets the slowest settle (:func:`spa.closedloop.bench.bench_outputs`)."""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from spa.model.modulators import Modulator
from spa.model.params import ValveParams

__all__ = ["box_hold", "box_levels", "promise_levels"]


def promise_levels(levels: list[float], k2: float, step_fraction: float) -> list[float]:
    """The promise's staircase: ``levels`` (increasing) thinned so that each step is at
    least ``step_fraction * k2``, from the lowest; the highest level is kept (it replaces
    the last kept one when that is closer than the step).

    A step smaller than the loop's ripple, or than the pressure one step of the modulator's
    duty moves, is within the loop's resolution: its "overshoot" and its 2 % band measure
    the limit cycle, which the promise states as ripple.

    Examples
    --------
    >>> promise_levels([0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7], 1.0, 0.2)
    [0.1, 0.3, 0.5, 0.7]
    >>> promise_levels([0.1, 0.2, 0.3, 0.4, 0.5, 0.6], 1.0, 0.2)
    [0.1, 0.3, 0.6]
    >>> promise_levels([0.1, 0.2, 0.3], 1.0, 0.0)
    [0.1, 0.2, 0.3]
    """
    step = float(step_fraction) * float(k2)
    if step <= 0.0 or len(levels) <= 2:
        return list(levels)
    kept = [levels[0]]
    for v in levels[1:-1]:
        if v - kept[-1] >= step * 0.95:  # levels are rounded to 3 significant digits
            kept.append(v)
    top = levels[-1]
    if len(kept) > 1 and top - kept[-1] < step * 0.95:
        kept[-1] = top
    else:
        kept.append(top)
    return kept


def box_hold(
    mod: Modulator,
    params: ValveParams,
    box: Mapping[str, tuple[float, float]],
    levels: list[float],
    tau_c: float,
    cfg: Mapping[str, Any],
    gain: float = 1.0,
) -> float:
    """Each level's hold for the promise: the longest
    :func:`spa.closedloop.comparison.level_hold` over the estimate and every corner of the box,
    so that the slowest plant the promise covers gets its transit plus five closed-loop time
    constants too. A PI designed at the estimate closes a slower loop on a plant whose local
    gain ``K = dP_eq/dxi`` is lower by ``g < 1`` (its crossover, and so its closed-loop
    time constant, scale by ``1/g``): such a corner's hold is taken at ``tau_c/g``, and at
    ``tau_c/(g*gain)`` with the measured model error's smallest loop-gain factor ``gain``.

    Examples
    --------
    >>> from spa.closedloop.comparison import DEFAULTS
    >>> m = Modulator.from_mapping({"type": "pwm", "f_w": 20.0})
    >>> c = {**DEFAULTS, "hold": None}
    >>> box_hold(m, ValveParams(), {"tau2": (0.5, 1.5)}, [0.2, 0.3], 0.2, c) > box_hold(
    ...     m, ValveParams(), {}, [0.2, 0.3], 0.2, c)
    True
    """
    from spa.closedloop.comparison import level_hold
    from spa.closedloop.design import local_models
    from spa.closedloop.levels import held_range
    from spa.closedloop.robust import corners

    k_est = local_models(levels, mod, params).gain
    gain = min(1.0, max(float(gain), 0.1))
    out = level_hold(mod, params, levels, tau_c / gain, cfg)
    for v in corners(params, box):
        if held_range(mod, v) is None:
            continue  # the setting cannot work on this corner: no hold makes it
        k = local_models(levels, mod, v).gain
        with np.errstate(divide="ignore", invalid="ignore"):
            ratio = k / k_est
        finite = ratio[np.isfinite(ratio) & (ratio > 0)]
        g = min(1.0, float(finite.min())) if finite.size else 1.0
        out = max(out, level_hold(mod, v, levels, tau_c / max(g * gain, 0.1), cfg))
    return out


def box_levels(
    mod: Modulator,
    params: ValveParams,
    box: Mapping[str, tuple[float, float]],
    levels: list[float],
    max_fraction: float = 0.95,
) -> list[float]:
    """The set-points that every valve of the box holds with ``mod``.

    A plant of the box whose supply is lower than a set-point cannot hold it, whatever the
    controller: the promise can only be about the set-points every plant holds
    (:func:`spa.closedloop.levels.held_range` at the estimate and each corner). When fewer
    than two are left, ``levels`` is returned unchanged (the promise then fails on them and
    says so).

    Examples
    --------
    >>> m = Modulator.from_mapping({"type": "pwm", "f_w": 20.0})
    >>> box_levels(m, ValveParams(), {"k2": (0.6, 1.0)}, [0.2, 0.4, 0.6, 0.8])
    [0.2, 0.4]
    """
    from spa.closedloop.levels import held_range
    from spa.closedloop.robust import corners

    lo, hi = -math.inf, math.inf
    for valve in (params, *corners(params, box)):
        held = held_range(mod, valve, max_fraction)
        if held is None:
            return list(levels)
        lo, hi = max(lo, held[0]), min(hi, held[1])
    kept = [v for v in levels if lo <= v <= hi]
    return kept if len(kept) >= 2 else list(levels)
