"""Which delay convention describes a valve: the paper's hold, or transport.

The refinement (:mod:`spa.identification.refine`) fits both; :func:`choose_convention`
picks the one the five identified parameters are given in (``identification.delay_convention``,
docs/explanation/identification.md section 3).
"""

from __future__ import annotations

import math
from collections.abc import Mapping

from spa.model.params import DELAY_CONVENTIONS

__all__ = ["CONVENTION_MARGIN", "choose_convention"]


#: Held-out FIT points by which the transport convention must beat the paper's hold
#: convention to be chosen (``delay_convention: auto``): on a valve the two describe
#: alike, the paper's stays.
CONVENTION_MARGIN = 1.0


def choose_convention(
    modulated: Mapping[str, float], overall: Mapping[str, float], setting: str = "auto"
) -> str:
    """The delay convention of the identified valve.

    Parameters
    ----------
    modulated : mapping
        Convention → median held-out FIT (%) over the modulated runs (the runs the model is
        used for; NaN when there are none).
    overall : mapping
        Convention → median held-out FIT over every run with a valve command (used when no
        modulated run scores).
    setting : {"auto", "hold", "transport"}
        ``identification.delay_convention``; a convention named is kept.

    Returns
    -------
    str
        ``"transport"`` when ``setting`` says so, or (``"auto"``) when it beats ``"hold"``
        by more than :data:`CONVENTION_MARGIN` points; else ``"hold"``.

    Examples
    --------
    >>> choose_convention({"hold": 62.0, "transport": 86.0}, {"hold": 70.0, "transport": 88.0})
    'transport'
    >>> choose_convention({"hold": 92.0, "transport": 92.5}, {"hold": 95.0, "transport": 95.0})
    'hold'
    >>> choose_convention({"hold": 62.0, "transport": 86.0}, {}, "hold")
    'hold'
    """
    if setting in DELAY_CONVENTIONS:
        return setting
    for score in (modulated, overall):
        h = score.get("hold", math.nan)
        t = score.get("transport", math.nan)
        if math.isfinite(h) or math.isfinite(t):
            h = h if math.isfinite(h) else -math.inf
            t = t if math.isfinite(t) else -math.inf
            return "transport" if t > h + CONVENTION_MARGIN else "hold"
    return "hold"
