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
    >>> text = recommendation_sentence({"recommended": None, "excluded_by": ["max_chattering"],
    ...                                 "constraints": {"max_chattering": 0.001}})
    >>> text[:80]
    'No setting of any modulator meets the constraints: max_chattering = 0.001 rules '
    """
    best = rec.get("recommended")
    if not best:
        names = list(rec.get("excluded_by") or [])
        limits = rec.get("constraints", {})
        said = " and ".join(f"{n} = {limits.get(n)}" for n in names) or "the constraints"
        verb, them = ("rules", "it") if len(names) == 1 else ("rule", "them")
        return (
            f"No setting of any modulator meets the constraints: {said} {verb} out every one; "
            f"relax {them} in the tuning: section of the config."
        )
    pred = best["predicted"]
    n = _fmt
    setting = ", ".join(
        f"{k}: {v:.6g}" if isinstance(v, float) else f"{k}: {v}" for k, v in best["setting"].items()
    )
    score = rec.get("score", "J")
    j, other = (best["J"], best["J_exact"]) if score == "J" else (best["J_exact"], best["J"])
    other_name = "J_exact" if score == "J" else "J"
    return (
        f"Use {best['description']} (dataset.yaml modulator: {{{setting}}}): "
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
