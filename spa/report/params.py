"""The identified parameters (``identification/params.yaml``) as a report table."""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import pandas as pd

from spa.report.html import format_value

__all__ = [
    "PARAM_NAMES",
    "adequacy_notes",
    "fits_note",
    "identification_notes",
    "modulated_assessed",
    "params_table",
]

PARAM_NAMES = ("c1", "k2", "tau2", "t_on", "t_off")
"""The identified valve parameters, in the order of the paper (Section 3.2)."""


def params_table(params: Mapping[str, Any]) -> pd.DataFrame:
    """The identified parameters of a ``params.yaml`` as a table, one row per parameter.

    Parameters
    ----------
    params : mapping
        The content of ``identification/params.yaml``: for each of :data:`PARAM_NAMES` a
        mapping with ``value``, ``lo``, ``hi`` (the 95 % interval), ``unit``, ``method`` and
        ``fallback`` (``None``, or why the nominal value was used).

    Returns
    -------
    pandas.DataFrame
        Columns ``parameter``, ``value``, ``95 % lo``, ``95 % hi``, ``unit``, ``method``,
        ``fallback`` (``"no"`` or the reason), in the order of :data:`PARAM_NAMES`; then
        ``t_off - t_on`` when the file has a ``delay_difference`` (a transport-delay valve).
        A delay marked ``resolved: false`` has no value (NaN): it is its interval.

    Raises
    ------
    ValueError
        If a parameter or one of its fields is missing.

    Examples
    --------
    >>> entry = {"value": 0.5, "lo": 0.4, "hi": 0.6, "unit": "s", "method": "fit",
    ...          "fallback": None}
    >>> print(params_table({n: entry for n in PARAM_NAMES}).head(2).to_string(index=False))
    parameter  value  95 % lo  95 % hi unit method fallback
           c1    0.5      0.4      0.6    s    fit       no
           k2    0.5      0.4      0.6    s    fit       no
    """
    if not isinstance(params, Mapping):
        raise ValueError(f"params must be a mapping, got {type(params).__name__}")
    rows = []
    # a transport-delay valve's delay difference has its own interval: a row of its own
    extra = ("delay_difference",) if isinstance(params.get("delay_difference"), Mapping) else ()
    for name in (*PARAM_NAMES, *extra):
        entry = params.get(name)
        if not isinstance(entry, Mapping):
            raise ValueError(f"params lacks the parameter {name!r}")
        missing = [k for k in ("value", "lo", "hi", "unit", "method") if k not in entry]
        if missing:
            raise ValueError(f"params[{name!r}] lacks {missing}")
        fallback = entry.get("fallback")
        unresolved = entry.get("resolved") is False
        if unresolved:
            # an unresolved delay is its interval: no point value is shown or used
            fallback = "unresolved: designs use the interval"
        rows.append(
            {
                "parameter": "t_off - t_on" if name == "delay_difference" else name,
                "value": math.nan if unresolved else float(entry["value"]),
                # a fallback value has no interval: NaN, shown as a blank
                "95 % lo": math.nan if entry["lo"] is None else float(entry["lo"]),
                "95 % hi": math.nan if entry["hi"] is None else float(entry["hi"]),
                "unit": str(entry["unit"]),
                "method": str(entry["method"]),
                "fallback": "no" if fallback in (None, False, "") else str(fallback),
            }
        )
    return pd.DataFrame(rows)


def fits_note(params: Mapping[str, Any]) -> str:
    """`` R² of the fits: charge 0.9625, discharge 0.9853.`` or ``""``."""
    fits = params.get("fits") or {}
    parts = [
        f"{name} {format_value(fit['r2'])}"
        for name, fit in fits.items()
        if isinstance(fit, Mapping) and "r2" in fit
    ]
    return f" R² of the fits: {', '.join(parts)}." if parts else ""


def modulated_assessed(adequacy: Mapping[str, Any] | None) -> bool:
    """Whether the adequacy check held out runs made through a modulator (the use the model
    is made for): ``modulated_assessed`` of ``params.yaml``'s ``adequacy:`` when present,
    else whether it names a measured modulator (its verdict is taken over the modulated
    runs when there are any, over the others only when there are none).

    Examples
    --------
    >>> modulated_assessed({"measured_modulators": ["pwm"]})
    True
    >>> modulated_assessed({"measured_modulators": [], "heldout_fit": {"median": 96.0}})
    False
    >>> modulated_assessed({"modulated_assessed": False, "measured_modulators": ["pwm"]})
    False
    """
    adequacy = adequacy or {}
    if isinstance(adequacy.get("modulated_assessed"), bool):
        return bool(adequacy["modulated_assessed"])
    return bool(adequacy.get("measured_modulators"))


def adequacy_notes(adequacy: Mapping[str, Any] | None) -> list[str]:
    """What the adequacy check held out, in words: the runs by name (``heldout_runs`` of
    ``params.yaml``'s ``adequacy:`` when present), and, when none of them was made through a
    modulator, that they are repeats of the identification's experiments, which say nothing
    about modulated use: that use is not assessed.

    Examples
    --------
    >>> adequacy_notes({"heldout_runs": ["c1", "c2"], "modulated_assessed": False,
    ...                 "heldout_fit": {"median": 97.0}})[0]
    'Held out: runs c1, c2 (each predicted by the model fitted without it).'
    >>> print(adequacy_notes({"measured_modulators": [], "heldout_fit": {"median": 96.0}})[-1][:60])
    Modulated use not assessed: none of the runs held out was ma
    >>> adequacy_notes({"heldout_runs": [], "modulated_assessed": False})
    ['Modulated use not assessed: no run was held out.']
    >>> adequacy_notes({"heldout_runs": ["s1"], "modulated_assessed": True})
    ['Held out: the modulated runs s1 (each predicted by the model fitted without it).']
    >>> adequacy_notes(None)
    []
    """
    if not isinstance(adequacy, Mapping) or not adequacy:
        return []
    modulated = modulated_assessed(adequacy)
    runs = [str(r) for r in adequacy.get("heldout_runs") or []]
    out = []
    if runs:
        which = "the modulated runs" if modulated else "runs"
        out.append(
            f"Held out: {which} {', '.join(runs)} (each predicted by the model fitted without it)."
        )
    if modulated:
        return out
    held = adequacy.get("heldout_fit")
    median = held.get("median") if isinstance(held, Mapping) else None
    # runs were held out: named, or (an older params.yaml) a held-out FIT to show for them
    some = bool(runs) if "heldout_runs" in adequacy else isinstance(median, int | float)
    if some:
        out.append(
            "Modulated use not assessed: none of the runs held out was made through a "
            "modulator. They repeat the identification's own experiments, so their FIT says "
            "how well the model reproduces those experiments, not how it predicts a modulated "
            "valve; record a staircase through a modulator to assess that."
        )
    elif "modulated use is not assessed" not in str(adequacy.get("sentence") or ""):
        out.append("Modulated use not assessed: no run was held out.")
    return out


def identification_notes(params: Mapping[str, Any]) -> list[str]:
    """The adequacy verdict and what it held out (:func:`adequacy_notes`), the delay
    convention and every warning of ``params.yaml``.

    Returns
    -------
    list of str
        Plain sentences (no NaN: missing numbers are left out), in that order.

    Examples
    --------
    >>> identification_notes({"delay_convention": {"chosen": "hold", "heldout_fit":
    ...     {"hold": 98.0, "transport": None}}, "warnings": ["t_off is not resolved"]})
    ['Delay convention: hold (chosen; held-out FIT: hold 98.0 %, transport n/a).', \
'Warning: t_off is not resolved']
    """
    out = []
    adequacy = params.get("adequacy") or {}
    if adequacy.get("sentence"):
        out.append(str(adequacy["sentence"]))
    out += adequacy_notes(adequacy)
    conv = params.get("delay_convention") or {}
    if conv.get("chosen"):
        fits = conv.get("heldout_fit_modulated") or {}
        which = "on the modulated runs"
        # "the modulated runs" only when there are some: never of repeats without a modulator
        none = adequacy and not modulated_assessed(adequacy)
        if none or not any(isinstance(v, int | float) for v in fits.values()):
            fits, which = conv.get("heldout_fit") or {}, ""
        said = ", ".join(
            f"{k} {v:.1f} %" if isinstance(v, int | float) and math.isfinite(v) else f"{k} n/a"
            for k, v in fits.items()
        )
        how = "set by the config" if conv.get("setting") in ("hold", "transport") else "chosen"
        out.append(
            f"Delay convention: {conv['chosen']} ({how}; held-out FIT"
            f"{' ' + which if which else ''}: {said})."
        )
    out += [f"Warning: {w}" for w in params.get("warnings") or []]
    return out
