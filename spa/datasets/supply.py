"""Is a supply pressure in the unit declared: the plausible and the typical supply of a soft
actuator, and the unit a logged number was likelier written in.

:func:`supply_warning` warns when a supply pressure (a charge run's plateau, the identified
``k2``) is outside the plausible range, or when another pressure unit reads it much nearer the
typical supply (:func:`likelier_unit`); :func:`k2_warning` applies it to the identified ``k2``
in the unit its charge runs declared; :func:`typical_readings` gives a draft the readings that
are typical.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

from spa.datasets.contract import _to_bar

__all__ = [
    "LIKELIER_FACTOR",
    "k2_warning",
    "likelier_unit",
    "supply_warning",
    "typical_readings",
]

#: How much nearer (as a factor) the middle of :data:`TYPICAL_SUPPLY_BAR` another unit's
#: reading of the supply must be for that unit to be the likelier.
LIKELIER_FACTOR = 2.0

#: Units in the order a draft prefers them when several readings are typical (the largest
#: reading first).
_UNIT_ORDER = ("bar", "psi", "kPa", "mbar")


def typical_readings(top: float, bounds: tuple[float, float] | None = None) -> dict[str, float]:
    """The readings in bar of a supply pressure ``top`` (in the file's unit) that are typical.

    Parameters
    ----------
    top : float
        The supply pressure (a charge run's plateau) as logged, in an unknown unit.
    bounds : (float, float), optional
        Typical supply in bar; default :data:`TYPICAL_SUPPLY_BAR`.

    Returns
    -------
    dict of str to float
        Unit to ``top`` converted to bar, for the units that put it within ``bounds``, in the
        order bar, psi, kPa, mbar.

    Examples
    --------
    >>> {u: round(b, 2) for u, b in typical_readings(80.0).items()}
    {'psi': 5.52, 'kPa': 0.8}
    """
    from spa.datasets.contract import TYPICAL_SUPPLY_BAR

    lo, hi = bounds if bounds is not None else TYPICAL_SUPPLY_BAR
    readings = {unit: float(_to_bar(abs(top), unit)) for unit in _UNIT_ORDER}
    return {unit: bar for unit, bar in readings.items() if lo <= bar <= hi}


def likelier_unit(
    top: float, declared: str, bounds: tuple[float, float] | None = None
) -> tuple[str, float] | None:
    """Another pressure unit under which a supply pressure is much more typical.

    Parameters
    ----------
    top : float
        The supply pressure (a charge run's plateau) in the ``declared`` unit.
    declared : str
        The unit it is read in (a key of :data:`PRESSURE_UNITS`).
    bounds : (float, float), optional
        Typical supply in bar; default :data:`TYPICAL_SUPPLY_BAR`.

    Returns
    -------
    (str, float) or None
        The unit and its reading in bar, when that reading is typical and its ratio to the
        middle of ``bounds`` (their geometric mean, 1.1 bar) is more than
        :data:`LIKELIER_FACTOR` times smaller than the declared reading's; else None.

    Notes
    -----
    A soft actuator's supply is typically 0.2-6 bar and most often near 1 bar; a number such
    as 80 reads 5.5 bar in psi and 0.8 bar in kPa, both typical, but 5.5 bar is 5.0 times the
    middle and 0.8 bar 1.4 times below it: kPa is likelier. The rule names another unit only
    when its reading is more than twice nearer the middle, so: psi gives way to kPa above
    4.1 bar (59 psi), kPa to mbar above 4.9 bar (490 kPa), bar to psi above 5.9 bar. A real
    supply that high logged in psi, kPa or bar is therefore called likely kPa, mbar or psi:
    a warning to check, not a correction; below those the ranges overlap (40 is 2.8 bar in
    psi or 0.4 bar in kPa) and neither is called likelier.

    Examples
    --------
    >>> unit, bar = likelier_unit(80.0, "psi")
    >>> unit, round(bar, 2)
    ('kPa', 0.8)
    >>> likelier_unit(50.0, "psi") is None  # 3.4 bar: not much further than kPa's 0.5
    True
    """
    from spa.datasets.contract import TYPICAL_SUPPLY_BAR

    lo, hi = bounds if bounds is not None else TYPICAL_SUPPLY_BAR
    middle = math.sqrt(lo * hi)
    mine = float(_to_bar(abs(top), declared))
    if not (math.isfinite(mine) and mine > 0):
        return None
    others = {u: b for u, b in typical_readings(top, bounds).items() if u != declared}
    if not others:
        return None
    unit = min(others, key=lambda u: abs(math.log(others[u] / middle)))
    nearer = abs(math.log(mine / middle)) - abs(math.log(others[unit] / middle))
    return (unit, others[unit]) if nearer > math.log(LIKELIER_FACTOR) else None


def supply_warning(
    value: float,
    what: str,
    declared: str = "bar",
    bounds: tuple[float, float] | None = None,
    likelier: bool = True,
) -> str | None:
    """A warning when a supply pressure is implausible, naming the likely unit mistake.

    Parameters
    ----------
    value : float
        The pressure in bar gauge, as converted from the ``declared`` unit (the identified
        ``k2``, or a charge run's highest pressure).
    what : str
        What it is, for the message (``"k2"``).
    declared : str
        The pressure unit the dataset declared (a key of :data:`PRESSURE_UNITS`).
    bounds : (float, float), optional
        Plausible range in bar; default :data:`PLAUSIBLE_SUPPLY_BAR` (config
        ``datasets.plausible_supply_bar``).
    likelier : bool
        Also warn, inside ``bounds``, when another unit is much likelier
        (:func:`likelier_unit`); False for simulated data, whose unit is known.

    Returns
    -------
    str or None
        None when ``value`` is within ``bounds`` and no other unit is much likelier
        (:func:`likelier_unit`); else the message, with the unit that would put it in range
        or that is likelier.

    Examples
    --------
    >>> supply_warning(0.0115, "k2", "kPa").split(": ")[1]
    'pressure logged in bar but declared kPa?'
    >>> supply_warning(83.7, "k2", "bar").split(": ")[1]
    'pressure logged in kPa but declared bar?'
    >>> supply_warning(0.8, "k2") is None
    True
    >>> supply_warning(5.52, "k2", "psi").split(": ")[1]
    'pressure logged in kPa but declared psi? (set units'
    """
    from spa.datasets.contract import PLAUSIBLE_SUPPLY_BAR, PRESSURE_UNITS

    lo, hi = bounds if bounds is not None else PLAUSIBLE_SUPPLY_BAR
    factor = PRESSURE_UNITS.get(declared)
    if not math.isfinite(value):
        return None
    if lo <= value <= hi:
        other = likelier_unit(value / factor, declared) if likelier and factor else None
        if other is None:
            return None
        unit, bar = other
        shown = "" if declared == "bar" else f" ({value / factor:.4g} {declared})"
        return (
            f"{what} = {value:.3g} bar{shown} is unusual for a soft actuator's supply "
            f"(typically {_typical_text()}); in {unit} it would be {bar:.3g} bar: pressure "
            f"logged in {unit} but declared {declared}? (set units: {{pressure: {unit}}} if so)"
        )
    message = f"{what} = {value:.3g} bar is outside the plausible supply range {lo:g}-{hi:g} bar"
    fits = {  # the units that would put it in range, the likeliest nearest 1 bar
        unit: abs(math.log(value * other / factor))
        for unit, other in PRESSURE_UNITS.items()
        if factor is not None and unit != declared and lo <= value * other / factor <= hi
    }
    if value > 0 and fits:
        unit = min(fits, key=fits.__getitem__)
        return f"{message}: pressure logged in {unit} but declared {declared}?"
    return f"{message}: check the pressure unit and the sensor's calibration"


def _typical_text() -> str:
    from spa.datasets.contract import TYPICAL_SUPPLY_BAR

    lo, hi = TYPICAL_SUPPLY_BAR
    return f"{lo:g}-{hi:g} bar, most often near {math.sqrt(lo * hi):.2g} bar"


def k2_warning(
    k2: float, metas: Mapping[str, Mapping[str, Any]], bounds: tuple[float, float] | None = None
) -> str | None:
    """:func:`supply_warning` for an identified ``k2``, in the unit its charge runs declared.

    Parameters
    ----------
    k2 : float
        The identified supply pressure, bar.
    metas : mapping
        Run id -> run table metadata (:func:`spa.datasets.read_runs`): ``kind``, ``units`` and
        ``origin`` (a simulated dataset, every run ``synthetic``, is only checked against
        ``bounds``: its unit is known; so is a pressure column whose name states the unit
        declared, ``source.columns.p``).
    bounds : (float, float), optional
        As :func:`supply_warning`.

    Examples
    --------
    >>> metas = {"c": {"kind": "charge", "units": {"pressure": "kPa"}}}
    >>> k2_warning(0.0115, metas).split(": ")[1]
    'pressure logged in bar but declared kPa?'
    """
    units = [dict(m.get("units") or {}).get("pressure") for m in metas.values()]
    charge = [
        dict(m.get("units") or {}).get("pressure")
        for m in metas.values()
        if m.get("kind") == "charge"
    ]
    declared = next((u for u in [*charge, *units] if u), "bar")
    from spa.datasets.contract import unit_in_name

    unsure = [
        m
        for m in metas.values()
        if m.get("origin") != "synthetic"
        and unit_in_name(dict(dict(m.get("source") or {}).get("columns") or {}).get("p"))
        != dict(m.get("units") or {}).get("pressure", "bar")
    ]
    return supply_warning(float(k2), "k2", str(declared), bounds, likelier=bool(unsure))
