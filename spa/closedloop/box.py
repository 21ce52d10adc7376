"""The plants of the promise's box: the set-points every one of them holds, and the hold that
lets the slowest settle (:func:`spa.closedloop.bench.bench_outputs`)."""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from spa.identification.identified import corners
from spa.model.modulators import Modulator
from spa.model.params import ValveParams

__all__ = [
    "PromiseBox",
    "box_hold",
    "box_levels",
    "laws_box_above",
    "promise_levels",
    "three_levels",
]


def three_levels(levels: list[float]) -> list[float]:
    """``levels`` with their midpoint (3 significant digits) between them when there are two
    (the box's reach can leave two of the levels asked for: one step up and one down checks
    too little, issue 61); else unchanged.

    Examples
    --------
    >>> three_levels([0.222, 0.444]), three_levels([0.2, 0.4, 0.6])
    ([0.222, 0.333, 0.444], [0.2, 0.4, 0.6])
    """
    if len(levels) != 2:
        return list(levels)
    lo, hi = float(levels[0]), float(levels[1])
    return [lo, float(f"{0.5 * (lo + hi):.3g}"), hi]


def promise_levels(levels: list[float], k2: float, step_fraction: float) -> list[float]:
    """The promise's staircase: ``levels`` (increasing) thinned so that each step is at
    least ``step_fraction * k2``, from the lowest; the highest level is kept (it replaces
    the last kept one when that is closer than the step). Three levels are kept whenever
    three are given: when the thinning leaves two, the level nearest their midpoint goes
    back in (a promise of one step up and one down checks too little, issue 61), and two
    levels given take their midpoint between them (:func:`three_levels`).

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
    >>> promise_levels([0.1, 0.15, 0.2, 0.25], 1.0, 0.2)
    [0.1, 0.15, 0.25]
    >>> promise_levels([0.222, 0.444], 1.11, 0.2)
    [0.222, 0.333, 0.444]
    """
    step = float(step_fraction) * float(k2)
    if len(levels) == 2:
        return three_levels(levels)
    if step <= 0.0 or len(levels) < 2:
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
    if len(kept) < 3:
        inner = list(levels[1:-1])
        mid = 0.5 * (levels[0] + top)
        kept = [levels[0], min(inner, key=lambda v: abs(v - mid)), top]
    return kept


@dataclass(frozen=True)
class PromiseBox:
    """The plants a promise covers with one setting: the estimate and its box's corners.

    Attributes
    ----------
    modulator, params, box : Modulator, ValveParams, mapping
        The setting, the estimate and the box around it, ``name -> (lo, hi)``
        (:func:`spa.identification.identified.corners`).
    """

    modulator: Modulator
    params: ValveParams
    box: Mapping[str, tuple[float, float]]

    @property
    def corners(self) -> list[ValveParams]:
        """The box's corners (without the estimate)."""
        return corners(self.params, self.box)


def box_hold(
    plants: PromiseBox, levels: list[float], tau_c: float, cfg: Mapping[str, Any], gain: float = 1.0
) -> float:
    """Each level's hold for the promise: the longest
    :func:`spa.closedloop.comparison.level_hold` over the estimate and every corner of the box,
    so that the slowest plant the promise covers gets its transit plus five closed-loop time
    constants too. A PI designed at the estimate closes a slower loop on a plant whose local
    gain ``K = dP_eq/dxi`` is lower by ``g < 1`` (its crossover, and so its closed-loop
    time constant, scale by ``1/g``): such a corner's hold is taken at ``tau_c/g``, and at
    ``tau_c/(g*gain)`` with the measured model error's smallest loop-gain factor ``gain``.

    Parameters
    ----------
    plants : PromiseBox
        The setting, the estimate and the box.
    levels : list of float
        The promise's set-points, bar.
    tau_c : float
        SIMC's closed-loop time constant at the estimate, s.
    cfg : mapping
        The ``closed_loop`` stage's settings (:func:`~spa.closedloop.comparison.level_hold`).
    gain : float, default 1.0
        The smallest loop-gain factor of the measured model error (clipped to [0.1, 1]).

    Returns
    -------
    float
        The hold, s.

    Examples
    --------
    >>> from spa.closedloop.comparison import DEFAULTS
    >>> m = Modulator.from_mapping({"type": "pwm", "f_w": 20.0})
    >>> c = {**DEFAULTS, "hold": None}
    >>> wide, none = (PromiseBox(m, ValveParams(), b) for b in ({"tau2": (0.5, 1.5)}, {}))
    >>> box_hold(wide, [0.2, 0.3], 0.2, c) > box_hold(none, [0.2, 0.3], 0.2, c)
    True
    """
    from spa.closedloop.comparison import level_hold
    from spa.closedloop.design import _local_models
    from spa.closedloop.levels import held_range

    mod, params = plants.modulator, plants.params
    k_est = _local_models(levels, mod, params).gain
    gain = min(1.0, max(float(gain), 0.1))
    out = level_hold(mod, params, levels, tau_c / gain, cfg)
    for v in plants.corners:
        if held_range(mod, v) is None:
            continue  # the setting cannot work on this corner: no hold makes it
        k = _local_models(levels, mod, v).gain
        with np.errstate(divide="ignore", invalid="ignore"):
            ratio = k / k_est
        finite = ratio[np.isfinite(ratio) & (ratio > 0)]
        g = min(1.0, float(finite.min())) if finite.size else 1.0
        out = max(out, level_hold(mod, v, levels, tau_c / max(g * gain, 0.1), cfg))
    return out


def box_levels(plants: PromiseBox, levels: list[float], max_fraction: float = 0.95) -> list[float]:
    """The set-points that every valve of the box holds with its setting.

    A plant of the box whose supply is lower than a set-point cannot hold it, whatever the
    controller: the promise can only be about the set-points every plant holds
    (:func:`spa.closedloop.levels.held_range` at the estimate and each corner). When fewer
    than two are left, ``levels`` is returned unchanged (the promise then fails on them and
    says so). When two are left of three or more, a third goes in halfway between them and
    the end of the range every plant holds, on the side the box cut off.

    Parameters
    ----------
    plants : PromiseBox
        The setting, the estimate and the box.
    levels : list of float
        The candidate set-points, bar.
    max_fraction : float, default 0.95
        As :func:`~spa.closedloop.levels.held_range`.

    Returns
    -------
    list of float

    Examples
    --------
    >>> m = Modulator.from_mapping({"type": "pwm", "f_w": 20.0})
    >>> box_levels(PromiseBox(m, ValveParams(), {"k2": (0.6, 1.0)}), [0.2, 0.4, 0.6, 0.8])
    [0.2, 0.4, 0.485]
    """
    from spa.closedloop.levels import held_range

    lo, hi = -math.inf, math.inf
    for valve in (plants.params, *plants.corners):
        held = held_range(plants.modulator, valve, max_fraction)
        if held is None:
            return list(levels)
        lo, hi = max(lo, held[0]), min(hi, held[1])
    kept = [v for v in levels if lo <= v <= hi]
    if len(kept) < 2:
        return list(levels)
    if len(kept) < min(3, len(levels)):
        # a third set-point every plant holds, between the kept ones and the range's end on
        # the side the box cut off (a promise of one step up and one down checks too little)
        gap = (lo, kept[0]) if min(levels) < kept[0] else (kept[-1], hi)
        kept = sorted({*kept, float(f"{0.5 * (gap[0] + gap[1]):.3g}")})
    return kept


def laws_box_above(
    record: Mapping[str, Any] | None,
    params: ValveParams,
    intervals: Mapping[str, tuple[float, float]],
    lowest: float,
) -> dict[str, tuple[float, float]]:
    """The box of a laws valve for a promise whose loop stays above ``lowest`` bar.

    The laws' whole-law envelopes (``tau2`` for the charge, ``c1`` for the exhaust,
    :func:`spa.identification.identified.laws_intervals`) are taken over the pressures the
    data visited at or above ``lowest`` instead of all of them; every other interval is
    ``intervals``'. A discharge the data leave loose near 0 bar then no longer scales the
    exhaust law at the set-points a promise keeps clear of it.

    Parameters
    ----------
    record : mapping or None
        ``params.yaml``'s ``laws:`` record (its ``bands`` and ``visited``); None or a record
        without bands leaves ``intervals`` as they are.
    params : ValveParams
        The laws valve.
    intervals : mapping
        The valve's 95 % intervals, ``name -> (lo, hi)``.
    lowest : float
        The lowest pressure the promise's loop visits, bar.

    Returns
    -------
    dict
        ``intervals`` with ``tau2`` and ``c1`` over the pressures at or above ``lowest``.

    Examples
    --------
    >>> from spa.model.laws import Laws
    >>> v = ValveParams(tau2=1.0, c1=0.5, k2=1.0,
    ...                 laws=Laws(log_g=(0, 0), log_h=(0, 0), knots=(0, 1)))
    >>> rec = {"bands": {"grid": [0.2, 0.5, 0.8],
    ...        "open": {"rate": [1, 1, 1], "lo": [.9, .9, .9], "hi": [1.1, 1.1, 1.1]},
    ...        "closed": {"rate": [-1, -1, -1], "lo": [-4, -1.2, -1.2], "hi": [-.25, -.8, -.8]}},
    ...        "visited": {"open": [0, 1], "closed": [0, 1]}}
    >>> whole = laws_box_above(rec, v, {"k2": (0.9, 1.1)}, 0.0)
    >>> above = laws_box_above(rec, v, {"k2": (0.9, 1.1)}, 0.4)
    >>> round(whole["c1"][1] / 0.5, 2), round(above["c1"][1] / 0.5, 2), above["k2"]
    (4.0, 1.25, (0.9, 1.1))
    """
    from spa.identification.identified import laws_intervals

    if not isinstance(record, Mapping) or not isinstance(record.get("bands"), Mapping):
        return dict(intervals)
    visited = dict(record.get("visited") or {})
    grid = [float(v) for v in record["bands"]["grid"]]
    top = max(grid) if grid else math.inf
    for mode in ("open", "closed"):
        span = visited.get(mode) or [min(grid, default=0.0), top]
        lo, hi = (float(v) if v is not None else math.nan for v in span)
        visited[mode] = [max(lo, float(lowest)), hi] if max(lo, float(lowest)) <= hi else span
    laws = laws_intervals({"bands": record["bands"], "visited": visited}, params)
    return {**intervals, **{k: v for k, v in laws.items() if k in ("tau2", "c1")}}
