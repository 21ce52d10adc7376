"""Delays the data do not resolve: what a controller exported on them says.

The identification marks a delay of ``params.yaml`` it could not resolve with
``resolved: false`` (``t_on: {value, lo, hi, ..., resolved: false}``; absent means resolved),
and :func:`spa.identification.identified.read_identified` gives them with their intervals
(``Identified.unresolved``).
A controller designed for such a valve is designed at a value the data do not fix, and its
promise is checked over the delay's interval (the corners of the box). The header's comment
and the closed-loop sentence say so, with what to record (:func:`unresolved_sentence`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping

__all__ = ["DELAYS", "unresolved_sentence"]

#: The delays of ``params.yaml`` that may be unresolved.
DELAYS = ("t_on", "t_off")

#: What resolves a delay: its edge inside the log.
RECORD = (
    "record the valve command on the pressure's clock (with the edge inside the log, the fit "
    "resolves the delay below one logging step) to resolve it"
)


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
