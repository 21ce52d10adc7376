"""Valve and actuator parameters of the four-state model (docs/model.md section 1)."""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, fields

from spa._checks import ArgumentTypeError

__all__ = ["PHYSICAL_RANGE", "ValveParams"]

#: The valves every stage is made and tested for (README, "Any valve"): ``name -> (lo, hi)``
#: in s·bar^-1/2, bar, s, s, s. The tests draw valves from it; a valve outside it still runs.
PHYSICAL_RANGE: dict[str, tuple[float, float]] = {
    "c1": (0.1, 2.0),
    "k2": (0.2, 6.0),
    "tau2": (0.05, 3.0),
    "t_on": (0.0005, 0.020),
    "t_off": (0.001, 0.040),
}


@dataclass(frozen=True, slots=True)
class ValveParams:
    """Parameters of the four-state valve + actuator model.

    Parameters
    ----------
    c1 : float
        Discharge constant in s·bar^-0.5: ``dP/dt = -sqrt(P)/c1`` while exhausting (Eq. 1).
    k2 : float
        Supply pressure seen at the actuator, in bar (gauge): the charging asymptote (Eq. 2).
    tau2 : float
        Charging time constant in s: ``dP/dt = (k2 - P)/tau2`` while charging (Eq. 2).
    t_on : float
        Opening delay in s: the pressure holds for ``t_on`` after a 0→1 command edge (Eq. 3).
    t_off : float
        Closing delay in s: the pressure holds for ``t_off`` after a 1→0 command edge (Eq. 3).

    Raises
    ------
    ValueError
        If any value is not a finite positive number; the message names the field.

    Notes
    -----
    The defaults are the values identified in the paper (Section 3.2):
    ``c1 = 0.533``, ``k2 = 0.837``, ``tau2 = 0.826``, ``t_on = 3 ms``, ``t_off = 10 ms``.

    Examples
    --------
    >>> ValveParams().k2
    0.837
    >>> ValveParams(c1=0.4, t_on=0.005).t_on
    0.005
    """

    c1: float = 0.533
    k2: float = 0.837
    tau2: float = 0.826
    t_on: float = 0.003
    t_off: float = 0.010

    def __post_init__(self) -> None:
        for f in fields(self):
            value = getattr(self, f.name)
            try:
                number = float(value)
            except (TypeError, ValueError):
                raise ValueError(f"ValveParams.{f.name} must be a number, got {value!r}") from None
            delay = f.name in ("t_on", "t_off")  # a valve may switch without delay
            if not math.isfinite(number) or number < 0.0 or (number == 0.0 and not delay):
                allowed = ">= 0" if delay else "> 0"
                raise ValueError(
                    f"ValveParams.{f.name} must be finite and {allowed}, got {value!r}"
                )
            object.__setattr__(self, f.name, number)

    def as_dict(self) -> dict[str, float]:
        """Return the parameters as a plain ``{name: value}`` dictionary."""
        return asdict(self)


def valve_params(params: ValveParams | None, name: str = "params") -> ValveParams:
    """``params``, or the nominal :class:`~spa.model.params.ValveParams` when None.

    Raises
    ------
    ArgumentTypeError
        If ``params`` is neither None nor a ValveParams.
    """
    if params is None:
        return ValveParams()
    if not isinstance(params, ValveParams):
        raise ArgumentTypeError(f"{name} must be a ValveParams, got {type(params).__name__}")
    return params
