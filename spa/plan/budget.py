"""What a session may take: a bench-time budget (``spa plan --budget``), what the plan gives
up to keep to it, and the exit status of a plan that misses its own precision targets."""

from __future__ import annotations

import re
from typing import Any

from spa.plan.limits import PlanError

__all__ = ["MISSED_STATUS", "first_settings", "parse_duration", "within_budget"]


def first_settings(settings: list[Any], n: int, recommended: Any) -> list[Any]:
    """``n`` of ``settings``: the recommended one and the first others, in their order."""
    others = [m.label for m in settings if recommended is None or m.label != recommended.label]
    keep = set(others[: n - 1 if recommended is not None else n])
    if recommended is not None:
        keep.add(recommended.label)
    return [m for m in settings if m.label in keep]


#: ``spa plan``'s exit status when the plan it wrote misses a precision target.
MISSED_STATUS = 3


def parse_duration(text: str) -> float:
    """Seconds of a duration such as ``90min``, ``1.5h``, ``5400s`` or ``5400``.

    Raises
    ------
    PlanError
        When it is not a positive number with one of the units s, min, h.

    Examples
    --------
    >>> parse_duration("90min"), parse_duration("1.5h"), parse_duration("300")
    (5400.0, 5400.0, 300.0)
    """
    m = re.fullmatch(r"\s*([0-9]*\.?[0-9]+)\s*(s|min|h)?\s*", text)
    if m is None or float(m.group(1)) <= 0:
        raise PlanError(f"--budget {text}: expected a duration such as 90min, 1.5h or 5400s")
    return float(m.group(1)) * {"s": 1.0, "min": 60.0, "h": 3600.0}[m.group(2) or "s"]


def within_budget(
    design: Any,
    replicates: int,
    levels: int,
    settings: int,
    margin: float,
    budget: float,
    pilot: bool,
) -> tuple[Any, dict[str, Any]]:
    """The largest plan that takes at most ``budget`` s of bench time.

    What goes first: replicates above 3 (identification's repeat test needs 3), then, for a
    full session, staircase levels (down to 5), then the settings recorded besides the
    recommended one, the last listed first.

    Parameters
    ----------
    design : callable
        ``(replicates, levels, settings, margin) -> SessionDesign``, ``settings`` the number
        of settings recorded (the recommended one first).
    replicates, levels, settings, margin
        The plan asked for.
    budget : float
        Bench time, s.
    pilot : bool
        A pilot records no setting: only its replicates go.

    Returns
    -------
    plan : SessionDesign
        The first plan tried that fits.
    kept : dict
        ``replicates``, ``levels`` and ``settings`` kept, and ``given_up``: a sentence on
        what was given up ("" when nothing was).

    Raises
    ------
    PlanError
        When even the smallest plan takes longer, naming how long it takes.
    """
    tried = [(r, levels, settings) for r in range(max(3, replicates), 2, -1)]
    if not pilot:
        tried += [(3, n, settings) for n in range(levels - 1, min(levels, 5) - 1, -1)]
        tried += [(3, min(levels, 5), k) for k in range(settings - 1, 0, -1)]
    for r, n, k in tried:
        plan = design(r, n, k, margin)
        if plan.duration <= budget:
            given = []
            if r < replicates:
                given.append(f"{r} replicates of each experiment instead of {replicates}")
            if n < levels:
                given.append(f"{n} staircase levels instead of {levels}")
            if k < settings:
                given.append(f"{k} of the {settings} settings (the recommended one first)")
            said = "; ".join(given)
            if said:
                said += " (the half-widths above are this plan's)"
            return plan, {"replicates": r, "levels": n, "settings": k, "given_up": said}
    raise PlanError(
        f"--budget {budget / 60:g} min: the smallest plan ({tried[-1][0]} replicates"
        + ("" if pilot else f", {tried[-1][1]} levels, {tried[-1][2]} setting")
        + f") takes {plan.duration / 60:.0f} min"
    )
