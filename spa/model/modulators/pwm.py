"""PWM: pulse-width modulation at ``f_w`` Hz (docs/model.md section 2).

``xi`` is sampled at the start of each period and the command is high for ``xi/f_w`` of it.
Averaged fractions (Eqs. 11–12): ``alpha1 = (1 - xi) - t_off*f_w``, ``alpha2 = xi - t_on*f_w``;
thresholds ``t_on*f_w`` and ``1 - t_off*f_w`` (Table 1).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, ClassVar

import numpy as np
import numpy.typing as npt

from spa.model.modulators import _pulses
from spa.model.modulators.base import ModulatorKind
from spa.model.modulators.trace import Trace, duty_matches, on_grid, sig, steady
from spa.model.params import ValveParams

__all__ = ["PWM"]


class PWM(ModulatorKind):
    """Pulse-width modulation: duty ``xi`` at frequency ``f_w``."""

    type = "pwm"
    name = "PWM"
    parameter = "f_w"
    symbol = "f_W"
    unit = "Hz"
    axis_name = "T_W = 1/f_W"
    colour = "#0072B2"  # blue
    order = 0.0
    settings: ClassVar[Mapping[str, float | None]] = {"f_w": None}
    default_grid: ClassVar[Mapping[str, float]] = {"start": 1.0, "stop": 80.0, "step": 0.1}
    reference = 20.0
    threshold_formulas = ("t_on*f_w", "1 - t_off*f_w")
    guess_rank = 0.0

    def check_dt(self, s: Mapping[str, float], dt: float) -> None:
        if 1.0 / s["f_w"] < 2.0 * dt * (1 - _pulses.EPS):
            raise ValueError(
                f"{self.type}: f_w = {s['f_w']:g} Hz is above half the controller rate "
                f"1/(2*dt) = {0.5 / dt:g} Hz (dt = {dt:g} s): a period needs at least two steps"
            )

    def duty(
        self, x: npt.NDArray[np.float64], s: Mapping[str, Any], p: ValveParams
    ) -> npt.NDArray[np.float64]:
        """The duty cycle for the input ``x``: ``x`` itself for plain PWM."""
        return x

    def pulse(
        self, x: npt.NDArray[np.float64], dt: float, s: Mapping[str, float]
    ) -> npt.NDArray[np.int8]:
        return _pulses.pwm(self.duty(x, s, ValveParams()), dt, s["f_w"])

    def pulse_times(
        self, x: npt.NDArray[np.float64], s: Mapping[str, Any], p: ValveParams
    ) -> tuple[Any, Any]:
        d = self.duty(x, s, p)
        return d / s["f_w"], (1.0 - d) / s["f_w"]

    def fractions(
        self, x: npt.NDArray[np.float64], s: Mapping[str, Any], p: ValveParams
    ) -> tuple[Any, Any]:
        d = self.duty(x, s, p)
        return (1.0 - d) - p.off_loss * s["f_w"], d - p.on_loss * s["f_w"]

    def thresholds(self, s: Mapping[str, Any], p: ValveParams) -> tuple[Any, Any]:
        return p.on_loss * s["f_w"], 1.0 - p.off_loss * s["f_w"]

    def constraint(self, p: ValveParams) -> str:
        return "f_w > 0 Hz"

    def sweep_limits(
        self, values: npt.NDArray[np.float64], p: ValveParams
    ) -> list[tuple[str, float, float, str, str]]:
        rule = "t_on + t_off < 1/f_w, else all dead-zone or saturation"
        return [("t_on + t_off", p.on_loss + p.off_loss, 1.0 / values[0], "PWM period 1/f_w", rule)]

    def guess(self, trace: Trace) -> tuple[dict[str, Any], str] | None:
        """Rises on a steady period, widths that vary (and follow ``u`` when logged)."""
        tr = trace
        period = steady(np.diff(tr.rise), tr.tol)[0]  # rises may jitter by a sample
        if (
            on_grid(np.diff(tr.rise), period, 1.01 * tr.dt) >= 0.98
            and steady(tr.highs, tr.tol)[1] < 0.9
            and (
                tr.u is None
                or duty_matches(tr.u[1:][tr.d > 0][tr.ok_h], tr.highs / period, tr.dt / period)
            )
        ):
            f_w = sig(1.0 / period, 4)
            return (
                {"type": self.type, "f_w": f_w},
                f"rising edges every {period * 1e3:.4g} ms (or a multiple), widths vary: "
                f"{self.name} at {f_w:g} Hz ({tr.count})",
            )
        return None
