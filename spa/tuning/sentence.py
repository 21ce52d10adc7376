"""The recommendation in one sentence a person can act on (:func:`recommendation_sentence`)."""

from __future__ import annotations

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
    setting = ", ".join(
        f"{k}: {v:.6g}" if isinstance(v, float) else f"{k}: {v}" for k, v in best["setting"].items()
    )
    score = rec.get("score", "J")
    j, other = (best["J"], best["J_exact"]) if score == "J" else (best["J_exact"], best["J"])
    other_name = "J_exact" if score == "J" else "J"
    return (
        f"Use {best['description']} (dataset.yaml modulator: {{{setting}}}): "
        f"{score} = {j:.2f} bar ({other_name} = {other:.2f}), dead-zone up to "
        f"xi = {pred['dead_zone']:.2f}, saturation from xi = {pred['saturation']:.2f}, "
        f"at most {pred['switching_rate']:.0f} valve switchings/s and "
        f"{pred['chattering'] * 1e3:.1f} mbar chattering, time constant up to "
        f"{_fmt_tau(pred)}; a simulated staircase fits its line to FIT = {pred['fit']:.1f} %."
        + _edge_note(best)
        + _passed_note(rec)
    )


def _fmt_tau(pred: Mapping[str, Any]) -> str:
    tau = (pred.get("tau_m") or {}).get("max")
    return "n/a" if tau is None else f"{tau:.2f} s"


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
