"""The recommendation in one sentence a person can act on (:func:`recommendation_sentence`)."""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

__all__ = ["recommendation_sentence"]


def recommendation_sentence(rec: Mapping[str, Any]) -> str:
    """The recommendation in one sentence a person can act on.

    Parameters
    ----------
    rec : mapping
        :func:`recommend`'s result (or the content of ``recommendation.yaml``).

    Returns
    -------
    str

    Examples
    --------
    >>> recommendation_sentence({"recommended": None, "n_candidates": 0})[:62]
    'No setting of any swept modulator works on this valve: nothing'

    A recommendation that breaks a constraint (no setting meets them all) names it first:

    >>> best = {"description": "PWM at 20 Hz", "setting": {"type": "pwm", "f_w": 20.0},
    ...     "J": 0.1, "J_exact": 0.1, "predicted": {"dead_zone": 0.1, "saturation": 0.9,
    ...     "switching_rate": 40.0, "chattering": 0.06, "fit": 95.0, "tau_m": {"max": 1.0}},
    ...     "violates": {"max_chattering": {"value": 0.06, "limit": 0.05, "excess": 0.2}}}
    >>> text = recommendation_sentence({"recommended": best})
    >>> text[:66]
    'No setting meets every constraint; the least-violating one breaks '
    >>> text[66:119]
    'max_chattering (0.06 bar, limit 0.05 bar, 20 % over).'
    """
    best = rec.get("recommended")
    unresolved = _unresolved_note(rec)
    if not best:
        if unresolved:
            return (
                "No setting of any swept modulator can be recommended: "
                + unresolved
                + ", and no setting works over the whole interval. Record the valve command "
                "on the pressure's clock (a pulse train logged with its valve column) and "
                "identify again."
            )
        return (
            "No setting of any swept modulator works on this valve: nothing to recommend "
            "(every setting's pulses are shorter than the valve's delays, or leave no input "
            "range that moves the pressure)."
        )
    pred = best["predicted"]
    n = _fmt
    setting = ", ".join(
        f"{k}: {v:.6g}" if isinstance(v, float) else f"{k}: {v}" for k, v in best["setting"].items()
    )
    score = rec.get("score", "J")
    j, other = (best["J"], best["J_exact"]) if score == "J" else (best["J_exact"], best["J"])
    other_name = "J_exact" if score == "J" else "J"
    lead = ""
    if unresolved:
        items = dict(rec.get("unresolved") or {})
        names = " and ".join(items)
        spans = ", ".join(
            f"{n} in [{1e3 * lo:.3g}, {1e3 * hi:.3g}] ms" for n, (lo, hi) in items.items()
        )
        verb = "is" if len(items) == 1 else "are"
        lead = (
            f"{names} {verb} not resolved by the data: this is designed for the worst case of "
            f"{spans}. Record the valve command on the pressure's clock (a pulse train logged "
            "with its valve column) and identify again before relying on it. "
        )
    return (
        lead
        + _violation_note(best)
        + f"Use {best['description']} (dataset.yaml modulator: {{{setting}}}): "
        f"{score} = {n(j, '.2f', ' bar')} ({other_name} = {n(other, '.2f')}), dead-zone up to "
        f"xi = {n(pred['dead_zone'], '.2f')}, saturation from xi = "
        f"{n(pred['saturation'], '.2f')}, at most {n(pred['switching_rate'], '.0f')} valve "
        f"switchings/s and {n(_scaled(pred['chattering'], 1e3), '.1f', ' mbar')} chattering, "
        f"time constant up to {_fmt_tau(pred)}; a simulated staircase fits its line to FIT = "
        f"{n(pred['fit'], '.1f', ' %')}."
        + _edge_note(best)
        + _passed_note(rec)
        + _adequacy_note(rec, best)
    )


def _unresolved_note(rec: Mapping[str, Any]) -> str:
    """The delays the data do not resolve and the interval designed over (``""``: none)."""
    from spa.identification.identified import unresolved_clause

    return unresolved_clause(rec.get("unresolved"))


#: Units of the limits a recommendation can break, for its sentence.
_LIMIT_UNITS = {
    "max_switching_rate": "switchings/s",
    "max_chattering": "bar",
    "min_pulse_width": "s",
    "max_time_constant": "s",
    "setting_range": "",
}


def _violation_note(best: Mapping[str, Any]) -> str:
    """The constraints a least-violating recommendation breaks, each with its numbers."""
    broken = dict(best.get("violates") or {})
    if not broken:
        return ""
    said = []
    for name, v in broken.items():
        unit = _LIMIT_UNITS.get(name, "")
        limit = v.get("limit")
        if isinstance(limit, list | tuple):
            limit_text = f"range [{limit[0]:.4g}, {limit[1]:.4g}]"
        else:
            limit_text = f"limit {float(limit):.4g} {unit}".rstrip()
        value = f"{float(v['value']):.4g} {unit}".rstrip()
        said.append(f"{name} ({value}, {limit_text}, {100 * float(v['excess']):.0f} % over)")
    return (
        "No setting meets every constraint; the least-violating one breaks "
        + " and ".join(said)
        + ". "
    )


def _scaled(x: Any, factor: float) -> Any:
    return x * factor if isinstance(x, int | float) else x


def _fmt(x: Any, spec: str, unit: str = "") -> str:
    """``x`` formatted with ``spec`` and ``unit``; "n/a" for a missing, NaN or infinite value
    (no NaN or inf ever reaches a sentence)."""
    if not isinstance(x, int | float) or not math.isfinite(x):
        return "n/a"
    return f"{x:{spec}}{unit}"


def _fmt_tau(pred: Mapping[str, Any]) -> str:
    tau = (pred.get("tau_m") or {}).get("max")
    return _fmt(tau, ".2f", " s")


def _adequacy_note(rec: Mapping[str, Any], best: Mapping[str, Any]) -> str:
    """The identification's adequacy clause for the recommended modulator, as a sentence."""
    if rec.get("adequacy") is None:
        return ""
    from spa.identification.adequacy import adequacy_clause

    kind = str((best.get("setting") or {}).get("type", ""))
    clause = adequacy_clause(rec["adequacy"], kind)
    if not clause:
        return ""
    return f" Not verified: {clause}."


def _edge_note(best: Mapping[str, Any]) -> str:
    edge = best.get("at_feasible_edge")
    if not edge:
        return ""
    bound = ", ".join(edge.get("bounded_by") or [])
    return (
        f" It is the {edge['side']} feasible setting of its kind (bounded by {bound}): "
        "a valve a little different from the identified one may leave it outside."
    )


def _passed_note(rec: Mapping[str, Any]) -> str:
    passed = [r for r in rec.get("runners_up") or [] if r.get("passed_over")]
    if not passed:
        return ""
    said = "; ".join(f"{r['label']}: {r['passed_over']}" for r in passed)
    return f" Passed over despite a better score: {said}."
