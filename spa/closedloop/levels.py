"""The closed loop's set-points in the valve's own scale, and the range each setting holds.

The staircase's set-points are fractions of the identified supply ``k2``
(``closed_loop.levels_fraction``) unless absolute ones are given (``closed_loop.levels``, bar).
Every compared setting is then checked on the set-points that all of them hold
(:func:`common_levels`), so that the choice is made on the same pressures; a setting that
holds much less than the others is compared on its own narrower range instead, and that
range is stated. :func:`idle_duty` says why a setting cannot hold low pressures: at
``xi = 0`` some modulators still open the valve.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from spa.model.averaging import pulse_times
from spa.model.modulators import Modulator
from spa.model.params import ValveParams

__all__ = [
    "common_levels",
    "held_range",
    "idle_duty",
    "wanted_levels",
]


def wanted_levels(
    levels: Sequence[float] | None, fractions: Sequence[float] | None, k2: float
) -> list[float]:
    """The set-points asked for, bar: ``levels`` when given, else ``fractions * k2``.

    Parameters
    ----------
    levels : sequence of float or None
        Absolute set-points, bar (``closed_loop.levels``); None: use ``fractions``.
    fractions : sequence of float or None
        Fractions of ``k2`` (``closed_loop.levels_fraction``).
    k2 : float
        The identified supply pressure, bar.

    Returns
    -------
    list of float
        Sorted, distinct, rounded to 3 significant digits when computed from fractions.

    Raises
    ------
    ValueError
        When neither is given, or fewer than two set-points result.

    Examples
    --------
    >>> wanted_levels(None, [0.1, 0.5, 0.9], 4.0)
    [0.4, 2.0, 3.6]
    >>> wanted_levels([0.1, 0.3], [0.5], 4.0)
    [0.1, 0.3]
    """
    if levels is not None:
        out = sorted({float(v) for v in levels})
    elif fractions is not None:
        out = sorted({float(f"{float(f) * k2:.3g}") for f in fractions})
    else:
        raise ValueError("closed_loop: set levels (bar) or levels_fraction (of k2)")
    if len(out) < 2:
        raise ValueError(f"closed_loop: need at least two set-points, got {out} bar")
    return out


def held_range(
    modulator: Modulator | Mapping[str, Any],
    params: ValveParams,
    max_fraction: float = 1.0,
) -> tuple[float, float] | None:
    """The set-points a setting holds on a valve: the rising range of its ``P_eq`` less a
    margin at each end (:data:`spa.closedloop.design.LEVEL_MARGIN`), capped at
    ``max_fraction * k2``; None when it holds nothing.

    Examples
    --------
    >>> lo, hi = held_range({"type": "pwm", "f_w": 20.0}, ValveParams(), 0.95)
    >>> round(lo, 3), round(hi, 3)
    (0.017, 0.795)
    """
    from spa.closedloop.design import LEVEL_MARGIN
    from spa.model.usable import rising_range, unusable_reason

    mod = Modulator.from_mapping(modulator).bind(params)
    if unusable_reason(mod, params):
        return None
    reach = rising_range(mod, params)
    if reach is None:
        return None
    lo, hi = reach
    pad = LEVEL_MARGIN * (hi - lo)
    top = min(hi - pad, max_fraction * params.k2)
    return (lo + pad, top) if top > lo + pad else None


def common_levels(
    wanted: Sequence[float],
    ranges: Mapping[str, tuple[float, float] | None],
    min_share: float = 0.5,
) -> tuple[list[float], list[str]]:
    """The set-points every compared setting holds, and which settings are compared there.

    Parameters
    ----------
    wanted : sequence of float
        The set-points asked for, bar (:func:`wanted_levels`).
    ranges : mapping
        Setting label -> ``(lo, hi)`` it holds (:func:`held_range`), or None.
    min_share : float, default 0.5
        The common set-points must keep at least this share of ``wanted``, and three (or
        as many as are wanted, when fewer): a staircase of two levels is one step up and
        one down, too little to promise a loop on (issue 61). While they do not, the
        setting holding the fewest of ``wanted`` leaves the common group (it is compared
        on its own range).

    Returns
    -------
    levels : list of float
        The wanted set-points strictly inside every grouped setting's range; when fewer than
        two, as many as wanted spread evenly over the common range (3 significant digits).
    group : list of str
        The settings compared on ``levels``, in the order of ``ranges``.

    Examples
    --------
    >>> common_levels([0.5, 1.0, 2.0, 3.0], {"a": (0.1, 3.5), "b": (0.8, 3.5)})
    ([1.0, 2.0, 3.0], ['a', 'b'])
    >>> common_levels([0.5, 1.0, 2.0, 3.0], {"a": (0.1, 3.5), "b": (2.5, 3.5)})
    ([0.5, 1.0, 2.0, 3.0], ['a'])
    >>> common_levels([0.06, 0.12, 0.18], {"a": (0.01, 0.28), "b": (0.01, 0.13)})
    ([0.06, 0.12, 0.18], ['a'])
    """
    group = [k for k, v in ranges.items() if v is not None]

    def inside(labels: list[str]) -> tuple[list[float], float, float]:
        lo = max(ranges[k][0] for k in labels)  # type: ignore[index]
        hi = min(ranges[k][1] for k in labels)  # type: ignore[index]
        return [v for v in wanted if lo < v < hi], lo, hi

    need = max(min(3, len(wanted)), math.ceil(min_share * len(wanted)))
    while len(group) > 1 and len(inside(group)[0]) < need:
        counts = [(len(inside([k])[0]), -i, k) for i, k in enumerate(group)]
        group.remove(min(counts)[2])
    if not group:
        return [], []
    kept, lo, hi = inside(group)
    if len(kept) < 2 and hi > lo:
        n = max(len(wanted), 3)
        kept = sorted({float(f"{v:.3g}") for v in np.linspace(lo, hi, n + 2)[1:-1]})
    return kept, group


def idle_duty(modulator: Modulator | Mapping[str, Any], params: ValveParams) -> float:
    """The share of time the valve is commanded open at ``xi = 0`` (0 for most modulators;
    IIPFM with a gain above 1 keeps pulsing).

    Examples
    --------
    >>> idle_duty({"type": "pwm", "f_w": 20.0}, ValveParams())
    0.0
    >>> round(idle_duty({"type": "iipfm", "t_l": 0.02, "gain": 1.15}, ValveParams()), 3)
    0.13
    """
    mod = Modulator.from_mapping(modulator).bind(params)
    with np.errstate(all="ignore"):
        t_h, t_l = pulse_times(mod.kind, 0.0, params, **mod.settings)
    th, tl = float(np.asarray(t_h)), float(np.asarray(t_l))
    if not (math.isfinite(th) and th > 0.0):
        return 0.0
    if not math.isfinite(tl):
        return 0.0
    return th / (th + tl)
