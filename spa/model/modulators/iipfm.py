"""IIPFM: inverse IPFM (docs/model.md section 2).

High by default; an integrator of ``1 - xi`` fires a low pulse of width ``t_l`` when it
reaches ``gain*t_l``. Steady train: ``t_l*(G/(1 - xi) - 1)`` high, ``t_l`` low. Averaged
fractions (Eqs. 15–16): ``alpha1 = (1/G)*(1 - t_off/t_l)*(1 - xi)``,
``alpha2 = 1 - (1/G)*(1 + t_on/t_l)*(1 - xi)``; ``G = 1 + t_on/t_l`` (Eq. 17) closes the
dead-zone.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any, ClassVar

import numpy as np
import numpy.typing as npt

from spa._docs import fill_doc
from spa.model._broadcast import safe_div
from spa.model.modulators.ipfm import IntegrateAndFire
from spa.model.params import ValveParams, valve_params

__all__ = ["IIPFM", "iipfm_optimal_t_l"]


class IIPFM(IntegrateAndFire):
    """Inverse IPFM: low pulses of ``t_l`` at a rate following ``1 - xi``."""

    type = "iipfm"
    name = "IIPFM"
    parameter = "t_l"
    symbol = "t_l"
    axis_name = "t_l"
    colour = "#009E73"  # bluish green
    order = 2.0
    settings: ClassVar[Mapping[str, float | None]] = {"t_l": None, "gain": 1.0}
    threshold_formulas = ("1 - gain/(1 + t_on/t_l)", "1")
    fires_high = False
    width_limit = "t_off"
    gain_rule = "and gain = 1 + t_on/t_l"
    gain_swept = True
    guess_rank = 3.0

    def pulse_times(
        self, x: npt.NDArray[np.float64], s: Mapping[str, Any], p: ValveParams
    ) -> tuple[Any, Any]:
        t_l = np.broadcast_to(s["t_l"], np.broadcast_shapes(np.shape(x), np.shape(s["t_l"])))
        ratio = safe_div(s["gain"], 1.0 - x, np.inf)
        return t_l * np.maximum(ratio - 1.0, 0.0), t_l

    def fractions(
        self, x: npt.NDArray[np.float64], s: Mapping[str, Any], p: ValveParams
    ) -> tuple[Any, Any]:
        a1 = (1.0 - p.off_loss / s["t_l"]) * (1.0 - x) / s["gain"]
        a2 = 1.0 - (1.0 + p.on_loss / s["t_l"]) * (1.0 - x) / s["gain"]
        return a1, a2

    def thresholds(self, s: Mapping[str, Any], p: ValveParams) -> tuple[Any, Any]:
        dead = 1.0 - s["gain"] / (1.0 + p.on_loss / s["t_l"])
        return dead, np.where(s["t_l"] > p.off_loss, 1.0, 0.0)

    def sweep_settings(
        self, v: npt.NDArray[np.float64], p: ValveParams, gain: Any = None
    ) -> dict[str, Any]:
        return {"t_l": v, "gain": 1.0 + max(p.on_loss, 0.0) / v if gain is None else gain}

    def analytic_optimum(self, p: ValveParams) -> float:
        """Eq. 29's ``t_l*`` in ms; NaN for a valve with its own laws (``p.laws``), which
        Eq. 29, derived from the paper's two laws, does not describe."""
        if p.laws is not None:
            return math.nan
        return iipfm_optimal_t_l(p) * 1e3


@fill_doc
def iipfm_optimal_t_l(params: ValveParams | None = None) -> float:
    """Analytic IIPFM pulse separation that best linearises the valve (Eq. 29).

    Parameters
    ----------
    %(params)s

    Returns
    -------
    float
        ``t_l*`` in s.

    Raises
    ------
    ValueError
        If ``r = c1*sqrt(k2/2)/tau2 >= 1`` (then no positive ``t_l`` matches the ideal ratio).

    Notes
    -----
    Matching the IIPFM fraction ratio ``(t_l - t_off)²/(t_l + t_on)² * (1 - xi)²/xi²`` to the
    ideal ``c1²*k2/tau2² * (1 - xi)²/xi`` (Eq. 20) with ``(1 - xi)²/xi² ≈ 2*(1 - xi)²/xi``
    gives ``(t_l - t_off)/(t_l + t_on) = r`` with ``r = c1*sqrt(k2/2)/tau2``, so
    ``t_l* = (t_off + r*t_on)/(1 - r)``.

    Examples
    --------
    >>> round(iipfm_optimal_t_l() * 1e3, 1)  # ms; the paper prints 19 ms
    19.3
    """
    p = valve_params(params)
    r = p.c1 * np.sqrt(p.k2 / 2.0) / p.tau2
    if r >= 1.0:
        raise ValueError(f"c1*sqrt(k2/2)/tau2 = {r:g} must be < 1 for Eq. 29 to have a solution")
    return float((p.off_loss + r * p.on_loss) / (1.0 - r))
