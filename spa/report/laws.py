"""Where a stage uses the valve outside the pressures its laws were identified at: a sentence
for the page beside the open-loop recommendation and the closed loop's PI
(:func:`laws_use_note`)."""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from spa.identification.laws_bands import outside_visited_clause

__all__ = ["laws_use_note", "recommended_levels"]

#: Input fractions at which a recommended setting's levels are evaluated, between its
#: dead-zone and its saturation.
_LEVELS = 8


def recommended_levels(rec: Mapping[str, Any], params: Any) -> list[float]:
    """The pressures a recommended setting holds: the averaged equilibrium ``P_eq(xi)`` at
    evenly spaced ``xi`` from its dead-zone to its saturation (``recommended.predicted``).

    Parameters
    ----------
    rec : mapping
        ``tuning/recommendation.yaml``'s content.
    params : ValveParams
        The identified valve (with its laws, when chosen).

    Returns
    -------
    list of float
        Bar; empty without a recommended setting or its thresholds.
    """
    from spa.model.averaging import equilibrium

    best = rec.get("recommended")
    if not isinstance(best, Mapping):
        return []
    setting = dict(best.get("setting") or {})
    pred = best.get("predicted") or {}
    lo, hi = pred.get("dead_zone"), pred.get("saturation")
    kind = setting.pop("type", None)
    if kind is None or not all(isinstance(v, int | float) and math.isfinite(v) for v in (lo, hi)):
        return []
    xi = np.linspace(float(lo), float(hi), _LEVELS)
    return [float(p) for p in np.atleast_1d(equilibrium(str(kind), xi, params, **setting))]


def laws_use_note(rec: Mapping[str, Any], identified: Mapping[str, Any] | None) -> str:
    """A sentence when a recommendation's levels or a loop's set-points lie outside the
    pressures the identified laws were seen at; ``""`` otherwise.

    Parameters
    ----------
    rec : mapping
        ``tuning/recommendation.yaml`` (its ``recommended`` setting's levels,
        :func:`recommended_levels`) or ``closed_loop/controllers.yaml`` (its set-points:
        ``levels``, and the chosen setting's own ``levels``).
    identified : mapping or None
        The dataset's ``params.yaml``. Only when its ``laws:`` were chosen (``identified``)
        is anything said: the paper's laws are a physical law, the identified ones a fit
        that holds where the runs went (``laws: visited``).

    Returns
    -------
    str

    Examples
    --------
    >>> ident = {"laws": {"chosen": "identified", "visited": {"open": [0, .5],
    ...          "closed": [0, .55]}}}
    >>> laws_use_note({"levels": [0.2, 0.4, 0.52]}, ident)[:50]
    "The closed loop's set-points at 0.52 bar lie outsi"
    >>> laws_use_note({"levels": [0.2, 0.4]}, ident)
    ''
    """
    record = (identified or {}).get("laws")
    if not isinstance(record, Mapping) or record.get("chosen") != "identified":
        return ""
    visited = record.get("visited")
    if "levels" in rec or "controllers" in rec:
        levels = [float(v) for v in rec.get("levels") or []]
        setting = rec.get("setting")
        for entry in dict(rec.get("controllers") or {}).values():
            if isinstance(entry, Mapping) and entry.get("setting") == setting:
                levels += [float(v) for v in entry.get("levels") or []]
        return outside_visited_clause(
            sorted(dict.fromkeys(levels)), visited, "the closed loop's set-points"
        )
    from spa.identification.results import load_params

    try:
        params = load_params(identified or {})
    except ValueError:
        return ""
    return outside_visited_clause(
        recommended_levels(rec, params), visited, "the recommended setting's levels"
    )
