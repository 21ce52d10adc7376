"""What the bench can take: the actuator's rated pressure, the valve's switching limits and
the logger's link, and the checks a plan must pass against them.

A plan never promises what its limits cannot carry: :func:`link_check` refuses a logging
step whose lines do not fit the link, and :func:`spa.plan.design.design_session` refuses a
setting faster than the valve switches.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import Any

__all__ = ["BITS_PER_BYTE", "LINE_BYTES", "Limits", "PlanError", "baud_needed", "link_check"]

#: Bytes of the longest sample line the player prints: ``ffff,fff,1,8000`` (tick counter
#: mod 65536, raw ADC counts up to 12 bits, the valve, xi in Q15, all in hex but the valve),
#: 15 characters, and the CR LF that Arduino's ``Serial.println`` ends it with.
LINE_BYTES = 15 + 2

#: Bits a UART sends per byte (start, 8 data, stop).
BITS_PER_BYTE = 10

#: The link is loaded to at most this fraction of its capacity (headroom for run markers).
LINK_LOAD = 0.8


class PlanError(ValueError):
    """A plan its prior and limits cannot support, with what was asked and what fits."""


@dataclass(frozen=True, slots=True)
class Limits:
    """The bench's limits.

    Attributes
    ----------
    p_max : float
        The actuator's rated maximum pressure, bar gauge: the player vents above it and the
        regulator must be set no higher.
    f_switch_max : float or None
        The valve's highest switching frequency, Hz (rising edges per second); None: none
        stated.
    on_time_max : float or None
        The longest the coil may stay energised at once, s (coil heating); None: none stated.
    baud : float or None
        The serial link's baud rate; None when ``samples_per_s`` is given instead.
    samples_per_s : float or None
        The logger's highest rate, lines per second, when it is not a UART.
    """

    p_max: float
    f_switch_max: float | None = None
    on_time_max: float | None = None
    baud: float | None = 115200.0
    samples_per_s: float | None = None

    def __post_init__(self) -> None:
        for name in ("p_max", "f_switch_max", "on_time_max", "baud", "samples_per_s"):
            value = getattr(self, name)
            if value is None and name != "p_max":
                continue
            if not isinstance(value, int | float) or not math.isfinite(value) or value <= 0:
                raise PlanError(f"limits: {name} must be a finite number > 0, got {value!r}")
        if self.baud is None and self.samples_per_s is None:
            raise PlanError("limits: give the link's baud rate or its samples per second")

    def to_mapping(self) -> dict[str, Any]:
        """The limits as plain values (``plan.yaml``'s ``limits``)."""
        return {k: v for k, v in asdict(self).items() if v is not None}


def baud_needed(dt: float, line_bytes: int = LINE_BYTES) -> float:
    """The baud rate a line every ``dt`` s needs, with the link loaded to 80 %.

    Examples
    --------
    >>> baud_needed(0.001)
    212500.0
    >>> baud_needed(0.002) <= 115200
    True
    """
    return line_bytes * BITS_PER_BYTE / dt / LINK_LOAD


def link_check(dt: float, limits: Limits) -> str:
    """Say how the link carries a line every ``dt`` s, or refuse.

    Returns
    -------
    str
        One sentence: the baud rate needed and the link's.

    Raises
    ------
    PlanError
        When the link cannot carry a line per step, naming the shortest step it carries.

    Examples
    --------
    >>> link_check(0.001, Limits(p_max=1.0, baud=115200))  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    spa.plan.limits.PlanError: logging step 1 ms needs 212500 baud ... log every 2 ms or more, ...
    """
    if limits.baud is not None:
        need = baud_needed(dt)
        if need > limits.baud:
            shortest = LINE_BYTES * BITS_PER_BYTE / limits.baud / LINK_LOAD
            step = math.ceil(shortest * 1e3 - 1e-9)
            raise PlanError(
                f"logging step {dt * 1e3:g} ms needs {need:.0f} baud ({LINE_BYTES}-byte lines "
                f"with 20 % headroom) but the link runs at {limits.baud:.0f} baud: log every "
                f"{step} ms or more, or raise the baud rate to {need:.0f} or more"
            )
        return (
            f"{LINE_BYTES}-byte lines every {dt * 1e3:g} ms need {need:.0f} baud; "
            f"the link runs at {limits.baud:.0f}"
        )
    assert limits.samples_per_s is not None
    if 1.0 / dt > limits.samples_per_s * (1 + 1e-9):
        raise PlanError(
            f"logging step {dt * 1e3:g} ms is {1 / dt:.0f} samples/s but the logger takes "
            f"{limits.samples_per_s:.0f}: log every {1e3 / limits.samples_per_s:g} ms or more"
        )
    return f"{1 / dt:.0f} samples/s; the logger takes {limits.samples_per_s:.0f}"
