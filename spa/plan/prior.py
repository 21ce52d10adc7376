"""The valve a plan is made for: the paper's nominal valve, a few numbers a lab knows, or a
previous dataset's identification."""

from __future__ import annotations

import math
from pathlib import Path

from spa.model.params import ValveParams
from spa.plan.limits import PlanError

__all__ = ["prior_from_numbers", "prior_from_params", "scaled"]


def prior_from_numbers(supply: float, fill_time: float) -> ValveParams:
    """The paper's valve brought to a supply pressure and a rough fill time.

    Parameters
    ----------
    supply : float
        The supply pressure the actuator reaches, bar gauge (``k2``).
    fill_time : float
        Roughly how long the actuator takes to fill, s: taken as 5 ``tau2``.

    Returns
    -------
    ValveParams
        ``k2 = supply``, ``tau2 = fill_time/5``; ``c1`` scaled so that the actuator empties
        in the paper's proportion of its fill time (``2 c1 sqrt(k2)`` against ``tau2``); the
        delays the paper's.

    Examples
    --------
    >>> p = prior_from_numbers(2.0, 2.5)
    >>> p.k2, p.tau2
    (2.0, 0.5)
    """
    for name, v in (("supply", supply), ("fill_time", fill_time)):
        if not isinstance(v, int | float) or not math.isfinite(v) or v <= 0:
            raise PlanError(f"prior: {name} must be a finite number > 0, got {v!r}")
    nominal = ValveParams()
    tau2 = float(fill_time) / 5.0
    empty = 2.0 * nominal.c1 * math.sqrt(nominal.k2) * tau2 / nominal.tau2
    c1 = empty / (2.0 * math.sqrt(float(supply)))
    return ValveParams(c1=c1, k2=float(supply), tau2=tau2, t_on=nominal.t_on, t_off=nominal.t_off)


def prior_from_params(path: str | Path) -> ValveParams:
    """A previous identification (``results/<name>/identification/params.yaml``)."""
    from spa.identification.identified import read_identified

    return read_identified(str(path)).params


def scaled(params: ValveParams, factor: float) -> ValveParams:
    """The valve ``factor`` times slower (every time constant and delay times ``factor``;
    ``c1`` is a time constant too), the supply unchanged: the plan's corners.

    Examples
    --------
    >>> scaled(ValveParams(), 3.0).tau2 == 3.0 * ValveParams().tau2
    True
    """
    return ValveParams(
        c1=params.c1 * factor,
        k2=params.k2,
        tau2=params.tau2 * factor,
        t_on=params.t_on * factor,
        t_off=params.t_off * factor,
        delay=params.delay,
    )
