"""Delays the data do not resolve: what a controller exported on them says.

The identification marks a delay of ``params.yaml`` it could not resolve with
``resolved: false`` (``t_on: {value, lo, hi, ..., resolved: false}``; absent means resolved).
A controller designed for such a valve is designed at a value the data do not fix, and its
promise is checked over the delay's interval (the corners of the box). The header's comment
and the closed-loop sentence say so, with what to record (:func:`unresolved_sentence`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

__all__ = ["DELAYS", "unresolved_delays", "unresolved_sentence"]

#: The delays of ``params.yaml`` that may be unresolved.
DELAYS = ("t_on", "t_off")

#: What resolves a delay: its edge inside the log.
RECORD = (
    "record the valve command on the pressure's clock (with the edge inside the log, the fit "
    "resolves the delay below one logging step) to resolve it"
)


def _bound(value: Any) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        return math.nan
    return v if math.isfinite(v) else math.nan


def unresolved_delays(identified: Mapping[str, Any] | None) -> dict[str, tuple[float, float]]:
    """The delays ``params.yaml`` marks ``resolved: false``, with their intervals, s.

    Parameters
    ----------
    identified : mapping or None
        ``params.yaml``'s content; a delay without ``resolved`` is resolved.

    Returns
    -------
    dict
        ``name -> (lo, hi)`` in s (NaN for a bound not given), in :data:`DELAYS` order.

    Examples
    --------
    >>> unresolved_delays({"t_on": {"value": 0.0515, "lo": 0.0, "hi": 0.05, "resolved": False},
    ...                    "t_off": {"value": 0.009, "lo": 0.008, "hi": 0.01}})
    {'t_on': (0.0, 0.05)}
    >>> unresolved_delays(None)
    {}
    """
    out = {}
    for name in DELAYS:
        entry = (identified or {}).get(name)
        if isinstance(entry, Mapping) and entry.get("resolved", True) is False:
            out[name] = (_bound(entry.get("lo")), _bound(entry.get("hi")))
    return out


def unresolved_sentence(unresolved: Mapping[str, tuple[float, float]], checked: bool = True) -> str:
    """One sentence naming each unresolved delay, its interval and what to record; ``""``
    when every delay is resolved.

    ``checked``: the controller's promise was checked over the intervals (the
    ``closed_loop`` stage); False for a controller designed at the estimate alone
    (``spa export-controller``), which the sentence says was checked over nothing.

    Examples
    --------
    >>> print(unresolved_sentence({"t_on": (0.0, 0.05)}))
    t_on is not resolved by the data (interval [0, 50] ms): this controller was designed over that interval (its promise is checked at its ends, the corners of the box), not at one value of it; record the valve command on the pressure's clock (with the edge inside the log, the fit resolves the delay below one logging step) to resolve it.
    >>> unresolved_sentence({"t_on": (0.0, 0.05)}, checked=False)[56:129]
    'this controller was designed at the estimate, a value the data do not fix'
    >>> unresolved_sentence({})
    ''
    """  # noqa: E501
    if not unresolved:
        return ""

    def ms(v: float) -> str:
        return f"{v * 1e3:.3g}" if math.isfinite(v) else "?"

    said = [
        f"{k} is not resolved by the data (interval [{ms(lo)}, {ms(hi)}] ms)"
        for k, (lo, hi) in unresolved.items()
    ]
    one = len(said) == 1
    record = RECORD if one else RECORD.replace("the delay", "the delays")[: -len("it")] + "them"
    if not checked:
        return (
            f"{' and '.join(said)}: this controller was designed at the estimate, a value the "
            f"data do not fix, and is not checked over {'it' if one else 'them'}; {record}."
        )
    return (
        f"{' and '.join(said)}: this controller was designed over "
        f"{'that interval' if one else 'those intervals'} (its promise is checked at "
        f"{'its' if one else 'their'} ends, the corners of the box), not at one value of "
        f"{'it' if one else 'each'}; "
        f"{record}."
    )
