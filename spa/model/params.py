"""Valve and actuator parameters of the four-state model (docs/model.md section 1)."""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, fields
from typing import Any

from spa._checks import ArgumentTypeError
from spa.model.laws.value import Laws, laws_from

__all__ = ["DELAY_CONVENTIONS", "PHYSICAL_RANGE", "ValveParams"]

#: The delay conventions a valve may carry (:attr:`ValveParams.delay`).
DELAY_CONVENTIONS: tuple[str, ...] = ("hold", "transport")

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
    delay : {"hold", "transport"}, optional
        Delay convention. ``"hold"`` (default, the paper's Eq. 3): the pressure holds still
        for ``t_on``/``t_off`` after an edge. ``"transport"``: the command reaches the plant
        ``t_on`` after a rising and ``t_off`` after a falling edge and the valve keeps its
        previous connection meanwhile, as a solenoid valve's armature does during its dead
        time (docs/model.md section 1). Every simulation, averaged formula, tuning and closed
        loop of spa follows the convention the parameters carry.

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
    delay: str = "hold"
    laws: Laws | None = None

    def __post_init__(self) -> None:
        if self.delay not in DELAY_CONVENTIONS:
            raise ValueError(
                f"ValveParams.delay must be one of {', '.join(DELAY_CONVENTIONS)}, "
                f"got {self.delay!r}"
            )
        if self.laws is not None:
            object.__setattr__(self, "laws", laws_from(self.laws))
        for f in fields(self):
            if f.name in ("delay", "laws"):
                continue
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

    def as_dict(self) -> dict[str, Any]:
        """Return the parameters as a plain ``{name: value}`` dictionary.

        ``delay`` is included only when it is not the default ``"hold"`` and ``laws`` (as
        :meth:`~spa.model.laws.Laws.as_dict`) only when they are not the paper's, so the
        paper's valves keep their five-number form; ``ValveParams(**p.as_dict()) == p``
        always.
        """
        out = asdict(self)
        if self.delay == "hold":
            del out["delay"]
        if self.laws is None:
            del out["laws"]
        else:
            out["laws"] = self.laws.as_dict()
        return out

    @property
    def on_loss(self) -> float:
        """Charging time a high pulse loses to the delays, s (the averaged model's ``t_on``).

        ``t_on`` under the hold convention; ``t_on - t_off`` under the transport convention
        (the plant charges from ``t_on`` after the rising edge to ``t_off`` after the falling
        one), which may be negative.
        """
        return self.t_on if self.delay == "hold" else self.t_on - self.t_off

    @property
    def off_loss(self) -> float:
        """Discharging time a low pulse loses to the delays, s (the averaged model's ``t_off``).

        ``t_off`` under the hold convention; ``t_off - t_on`` under the transport convention.
        """
        return self.t_off if self.delay == "hold" else self.t_off - self.t_on

    def loss_label(self, rising: bool) -> str:
        """How :attr:`on_loss` (``rising``) or :attr:`off_loss` is written in a sentence."""
        if self.delay == "hold":
            return "t_on" if rising else "t_off"
        return "t_on - t_off" if rising else "t_off - t_on"

    def hold_time(self, rising: bool) -> float:
        """How long the pressure holds still after an edge, s: the delay under the hold
        convention, 0 under the transport convention (the previous connection persists)."""
        if self.delay != "hold":
            return 0.0
        return self.t_on if rising else self.t_off


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
