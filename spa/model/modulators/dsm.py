"""ΔΣM: first-order delta-sigma modulation clocked every ``period`` s (docs/model.md section 2).

``v_k = v_{k-1} + xi_k - u_{k-1}``, ``u_k = [v_k >= 1/2]`` from ``v = u = 0``. Averaged
fractions (Eqs. 18–19, with ``f = 1/T_DS``): ``alpha1 = (1 - xi)*(1 - 2*f*t_off*xi)``,
``alpha2 = xi*(1 - 2*f*t_on*(1 - xi))``; the exact orbit is that of the true first-order
pattern (:func:`spa.model.periodic.dsm_mean`).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any, ClassVar

import numpy as np
import numpy.typing as npt

from spa.model._broadcast import safe_div
from spa.model.modulators import _pulses
from spa.model.modulators.base import ModulatorKind
from spa.model.modulators.trace import Trace, on_grid, sig
from spa.model.params import ValveParams

__all__ = ["DSM"]


class DSM(ModulatorKind):
    """First-order ΔΣ modulation: duty ``xi`` in multiples of the clock ``period``."""

    type = "dsm"
    name = "ΔΣM"
    parameter = "period"
    symbol = "T_ΔΣ"
    axis_name = "T_ΔΣ"
    colour = "#D55E00"  # vermillion
    order = 3.0
    settings: ClassVar[Mapping[str, float | None]] = {"period": None}
    default_grid: ClassVar[Mapping[str, float]] = {"start": 0.0125, "stop": 1.0, "step": 0.001}
    reference = 0.020
    threshold_formulas = ("max(0, 1 - period/(2*t_on))", "min(1, period/(2*t_off))")
    guess_rank = 1.0

    def check_dt(self, s: Mapping[str, float], dt: float) -> None:
        if s["period"] < dt * (1 - _pulses.EPS):
            raise ValueError(
                f"{self.type}: setting 'period' = {s['period']:g} s is shorter than dt = {dt:g} s"
            )

    def pulse(
        self, x: npt.NDArray[np.float64], dt: float, s: Mapping[str, float]
    ) -> npt.NDArray[np.int8]:
        return _pulses.ticks_held(x, dt, s["period"])

    def pulse_times(
        self, x: npt.NDArray[np.float64], s: Mapping[str, Any], p: ValveParams
    ) -> tuple[Any, Any]:
        t_h = safe_div(s["period"], 2.0 * (1.0 - x), np.inf)
        t_l = safe_div(s["period"], 2.0 * x, np.inf)
        return t_h, t_l

    def fractions(
        self, x: npt.NDArray[np.float64], s: Mapping[str, Any], p: ValveParams
    ) -> tuple[Any, Any]:
        f = 1.0 / s["period"]
        a1 = (1.0 - x) * (1.0 - 2.0 * f * p.off_loss * x)
        a2 = x * (1.0 - 2.0 * f * p.on_loss * (1.0 - x))
        return a1, a2

    def thresholds(self, s: Mapping[str, Any], p: ValveParams) -> tuple[Any, Any]:
        # An ideal valve (no delay) has neither: the limits of the formulas as t -> 0.
        period = s["period"]
        dead = 1.0 - period / (2.0 * p.on_loss) if p.on_loss > 0 else 0.0 * period
        sat = period / (2.0 * p.off_loss) if p.off_loss > 0 else 1.0 + 0.0 * period
        return dead, sat

    def periodic_mean(
        self,
        x: npt.NDArray[np.float64],
        s: Mapping[str, Any],
        p: ValveParams,
        max_denominator: int | None = None,
    ) -> Any:
        from spa.model.periodic import dsm_mean

        if max_denominator is None:
            return dsm_mean(x, s["period"], p)
        return dsm_mean(x, s["period"], p, max_denominator=max_denominator)

    def periodic_means(
        self,
        x: npt.NDArray[np.float64],
        settings: Sequence[Mapping[str, Any]],
        valves: Sequence[ValveParams],
        max_denominator: int | None = None,
    ) -> npt.NDArray[np.float64]:
        """Every valve's orbits in one Newton iteration (:func:`spa.model.periodic.dsm_means`)."""
        from spa.model.periodic import dsm_means

        periods = [s["period"] for s in settings]
        if max_denominator is None:
            return dsm_means(x, periods, valves)
        return dsm_means(x, periods, valves, max_denominator=max_denominator)

    def cycle(self, x: npt.NDArray[np.float64], s: Mapping[str, Any], p: ValveParams) -> Any:
        """First-order ΔΣ repeats its minority level once every ``T_DS/min(xi, 1 - xi)``
        (:meth:`pulse_times` gives the paper's approximate mean durations instead)."""
        return safe_div(s["period"], np.minimum(x, 1.0 - x), np.inf)

    def min_pulse(self, moving: npt.NDArray[np.float64], s: Mapping[str, Any]) -> Any:
        """The clock period wherever anything pulses."""
        return np.where(np.isfinite(moving), np.asarray(s["period"])[..., 0], np.inf)

    def feasible(self, v: npt.NDArray[np.float64], p: ValveParams) -> npt.NDArray[np.bool_]:
        return (v > p.off_loss) & (v > p.on_loss)

    def constraint(self, p: ValveParams) -> str:
        on, off = f"{p.on_loss * 1e3:g} ms", f"{p.off_loss * 1e3:g} ms"
        return f"period > {p.loss_label(False)} = {off} and period > {p.loss_label(True)} = {on}"

    def sweep_limits(
        self, values: npt.NDArray[np.float64], p: ValveParams
    ) -> list[tuple[str, float, float, str, str]]:
        return [
            ("t_off", p.off_loss, values[-1], "ΔΣM period", "period > t_off"),
            ("t_on", p.on_loss, values[-1], "ΔΣM period", "period > t_on"),
        ]

    def guess(self, trace: Trace) -> tuple[dict[str, Any], str] | None:
        """Every edge on one clock, high or low times that vary (not a square wave)."""
        tr = trace
        clock = float(min(np.min(tr.highs), np.min(tr.lows)))
        edges = np.sort(np.concatenate([tr.rise, tr.fall]))
        if clock >= 2.5 * tr.dt and on_grid(edges - edges[0], clock, tr.tol) >= 0.98:
            if min(tr.shares) < 0.98:  # not a plain square wave
                c = sig(clock, 4)
                return (
                    {"type": self.type, "period": c},
                    f"every edge on a {c * 1e3:g} ms clock, high or low times vary: ΔΣ "
                    f"({tr.count})",
                )
        return None
