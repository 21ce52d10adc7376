"""A toy sixth modulator for the tests: a square wave of duty ``xi`` clocked at ``rate`` Hz,
high first for half of the duty and again at the end of the period (centred PWM's cousin).

It states only what is its own; everything else comes from ModulatorKind. Registered in one
line by the test that uses it: ``register(Toy)``.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, ClassVar

import numpy as np

from spa.model.modulators import ModulatorKind, _pulses


class Toy(ModulatorKind):
    type = "toy"
    name = "Toy"
    parameter = "rate"
    symbol = "f_T"
    unit = "Hz"
    axis_name = "1/f_T"
    colour = "#56B4E9"
    order = 5.0
    settings: ClassVar[Mapping[str, float | None]] = {"rate": None}
    ranges: ClassVar[Mapping[str, tuple[float, float, str]]] = {"rate": (1e-3, 1e4, "Hz")}
    default_grid: ClassVar[Mapping[str, float]] = {"start": 2.0, "stop": 60.0, "step": 1.0}
    reference = 20.0

    def pulse(self, x, dt, s):
        return _pulses.pwm(x, dt, s["rate"])

    def pulse_times(self, x, s, p):
        return x / s["rate"], (1.0 - x) / s["rate"]

    def fractions(self, x, s, p) -> tuple[Any, Any]:
        return (1.0 - x) - p.t_off * s["rate"], x - p.t_on * s["rate"]

    def thresholds(self, s, p):
        return p.t_on * s["rate"], 1.0 - p.t_off * s["rate"]

    def feasible(self, v, p):
        return np.asarray(v) * (p.t_on + p.t_off) < 1.0
