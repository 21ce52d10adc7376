"""IPFM: integral pulse-frequency modulation (docs/model.md section 2).

An integrator of ``xi`` fires a high pulse of width ``t_h`` when it reaches ``gain*t_h`` and
subtracts that threshold; the firing count is ``floor(∫xi/(gain*t_h))``. Steady train:
``t_h`` high, ``t_h*(G/xi - 1)`` low. Averaged fractions (Eqs. 13–14, general ``G``):
``alpha1 = 1 - (1 + t_off/t_h)*xi/G``, ``alpha2 = (1 - t_on/t_h)*xi/G``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any, ClassVar

import numpy as np
import numpy.typing as npt

from spa.model._broadcast import safe_div
from spa.model.modulators import _pulses
from spa.model.modulators.base import ModulatorKind
from spa.model.modulators.trace import Trace, sig, threshold_gain
from spa.model.params import ValveParams

__all__ = ["IPFM", "IntegrateAndFire", "check_threshold", "guess_fired"]


def check_threshold(kind: ModulatorKind, s: Mapping[str, float], dt: float) -> None:
    """A pulse width and its threshold ``gain*width`` must last at least one step."""
    width = kind.parameter
    if s[width] < dt * (1 - _pulses.EPS):
        raise ValueError(
            f"{kind.type}: setting {width!r} = {s[width]:g} s is shorter than dt = {dt:g} s"
        )
    if s["gain"] * s[width] < dt * (1 - _pulses.EPS):
        raise ValueError(
            f"{kind.type}: threshold gain*{width} = {s['gain'] * s[width]:g} s is shorter than "
            f"dt = {dt:g} s; increase 'gain' or {width!r}"
        )


def guess_fired(kind: ModulatorKind, tr: Trace, high: bool) -> tuple[dict[str, Any], str] | None:
    """An integrate-and-fire kind whose fired pulses (high for IPFM, low for IIPFM) have one
    width while the other level varies; the gain from ``u`` when it is logged."""
    h_share, l_share = tr.shares
    share, other = (h_share, l_share) if high else (l_share, h_share)
    if not (share >= 0.9 and other < 0.9):
        return None
    pulses = tr.highs if high else tr.lows
    w = sig(float(np.median(pulses)), 4)
    mod: dict[str, Any] = {"type": kind.type, kind.parameter: w}
    gain_text = "gain unknown without u, left at 1"
    if tr.u is not None:
        drive = tr.u if high else 1.0 - tr.u
        on = tr.v if high else 1.0 - tr.v
        starts = np.flatnonzero(tr.d > 0 if high else tr.d < 0) + 1
        gain = sig(threshold_gain(drive, on, starts), 3)
        ratio = "∫u / ∫valve" if high else "∫(1 - u) / ∫(1 - valve)"
        gain_text = f"gain {gain:g} = {ratio} from the first pulse to the last"
        if not math.isclose(gain, 1.0):
            mod["gain"] = gain
    what = "high" if high else "low"
    return (
        mod,
        f"{what} time constant at {w * 1e3:g} ms in {share:.0%} of pulses, the other "
        f"varies: {kind.type.upper()}; {gain_text} ({tr.count})",
    )


class IntegrateAndFire(ModulatorKind):
    """What IPFM and IIPFM share: an integrator of ``xi`` (high pulses, :attr:`fires_high`)
    or of ``1 - xi`` (low pulses) fires a pulse of the width ``parameter`` each time it
    reaches ``gain`` times that width. Not a kind by itself (never registered)."""

    #: Whether the fired pulses are high (IPFM) or low (IIPFM, on ``1 - xi``).
    fires_high: ClassVar[bool] = True
    #: The valve delay the pulse width must exceed, and what the constraint says of the gain.
    width_limit: ClassVar[str] = "t_on"
    gain_rule: ClassVar[str] = "(gain = 1)"
    default_grid: ClassVar[Mapping[str, float]] = {"start": 0.0125, "stop": 1.0, "step": 0.001}
    reference = 0.020
    has_gain = True

    def check_dt(self, s: Mapping[str, float], dt: float) -> None:
        check_threshold(self, s, dt)

    def pulse(
        self, x: npt.NDArray[np.float64], dt: float, s: Mapping[str, float]
    ) -> npt.NDArray[np.int8]:
        width = s[self.parameter]
        if self.fires_high:
            return _pulses.fire_pulses(x, dt, s["gain"] * width, width)
        return 1 - _pulses.fire_pulses(1.0 - x, dt, s["gain"] * width, width)

    def guess(self, trace: Trace) -> tuple[dict[str, Any], str] | None:
        return guess_fired(self, trace, high=self.fires_high)

    def feasible(self, v: npt.NDArray[np.float64], p: ValveParams) -> npt.NDArray[np.bool_]:
        return v > _loss(p, self.width_limit)

    def constraint(self, p: ValveParams) -> str:
        limit = _loss(p, self.width_limit)
        label = p.loss_label(self.width_limit == "t_on")
        return f"{self.parameter} > {label} = {limit * 1e3:g} ms {self.gain_rule}"

    def sweep_limits(
        self, values: npt.NDArray[np.float64], p: ValveParams
    ) -> list[tuple[str, float, float, str, str]]:
        w, limit = self.parameter, self.width_limit
        return [(limit, _loss(p, limit), values[-1], f"{self.name} {w}", f"{w} > {limit}")]


def _loss(p: ValveParams, name: str) -> float:
    """What a pulse loses to the delay ``name`` (``t_on``: a high pulse, ``t_off``: a low
    one) under the valve's convention (:attr:`ValveParams.on_loss`)."""
    return p.on_loss if name == "t_on" else p.off_loss


class IPFM(IntegrateAndFire):
    """Integral pulse-frequency modulation: pulses of ``t_h`` at a rate following ``xi``."""

    type = "ipfm"
    name = "IPFM"
    parameter = "t_h"
    symbol = "t_h"
    axis_name = "t_h"
    colour = "#E69F00"  # orange
    order = 1.0
    settings: ClassVar[Mapping[str, float | None]] = {"t_h": None, "gain": 1.0}
    threshold_formulas = ("0", "gain*t_h/(t_h + t_off)")
    guess_rank = 2.0

    def pulse_times(
        self, x: npt.NDArray[np.float64], s: Mapping[str, Any], p: ValveParams
    ) -> tuple[Any, Any]:
        t_h = np.broadcast_to(s["t_h"], np.broadcast_shapes(np.shape(x), np.shape(s["t_h"])))
        ratio = safe_div(s["gain"], x, np.inf)
        return t_h, t_h * np.maximum(ratio - 1.0, 0.0)

    def fractions(
        self, x: npt.NDArray[np.float64], s: Mapping[str, Any], p: ValveParams
    ) -> tuple[Any, Any]:
        a1 = 1.0 - (1.0 + p.off_loss / s["t_h"]) * x / s["gain"]
        a2 = (1.0 - p.on_loss / s["t_h"]) * x / s["gain"]
        return a1, a2

    def thresholds(self, s: Mapping[str, Any], p: ValveParams) -> tuple[Any, Any]:
        dead = np.where(s["t_h"] > p.on_loss, 0.0, 1.0)
        return dead, s["gain"] * s["t_h"] / (s["t_h"] + p.off_loss)

    def sweep_settings(
        self, v: npt.NDArray[np.float64], p: ValveParams, gain: Any = None
    ) -> dict[str, Any]:
        return {"t_h": v, "gain": np.ones_like(v) if gain is None else gain}
