"""LPWM: model-inverse PWM, whose averaged equilibrium is the line ``k2*xi`` (docs/model.md).

PWM at ``f_w`` Hz whose duty ``d(xi)`` inverts the averaged equilibrium (Eq. 5) of a valve
``(c1, k2, tau2, t_on, t_off)``. With PWM's fractions ``alpha1 = 1 - d - t_off*f_w`` and
``alpha2 = d - t_on*f_w``, the equilibrium condition ``alpha1*sqrt(P)/c1 = alpha2*(k2 - P)/tau2``
at ``P = k2*xi`` (``s = sqrt(k2*xi)``) is linear in ``d``:

    d = (s*tau2*(1 - t_off*f_w) + (k2 - s²)*c1*t_on*f_w) / (s*tau2 + (k2 - s²)*c1),

a weighted mean of the PWM thresholds ``t_on*f_w`` and ``1 - t_off*f_w`` with weight
``w = s*tau2/(s*tau2 + (k2 - s²)*c1)`` rising from 0 to 1. It equals the closed form
``((1 - t_off*f_w) + rho*t_on*f_w)/(1 + rho)`` with ``rho = c1*(k2 - s²)/(s*tau2)`` but has no
division by ``s`` or ``k2 - s²``. The command is 0 at ``xi = 0`` and 1 at ``xi = 1``.

The valve settings are optional: a setting without them inverts the valve of its context
(the plant's parameters in the averaged analysis and the tuning; :meth:`LPWM.bind`), and
:func:`~spa.model.modulators.modulate` without them inverts the nominal valve.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any, ClassVar

import numpy as np
import numpy.typing as npt

from spa.model.modulators import _pulses
from spa.model.modulators.pwm import PWM
from spa.model.params import ValveParams

__all__ = ["LPWM", "VALVE"]

#: The valve settings LPWM may carry: the parameters it inverts.
VALVE: tuple[str, ...] = ("c1", "k2", "tau2", "t_on", "t_off")


def _valve(s: Mapping[str, Any], p: ValveParams) -> tuple[Any, ...]:
    """The inverted valve: the setting's own parameters where given, else ``p``'s."""
    own = {"t_on": p.on_loss, "t_off": p.off_loss}  # the losses: the delays under "hold"
    return tuple(s.get(name, own.get(name, getattr(p, name))) for name in VALVE)


class LPWM(PWM):
    """Model-inverse PWM: the duty that makes the averaged ``P_eq(xi)`` equal ``k2*xi``."""

    type = "lpwm"
    name = "LPWM"
    colour = "#CC79A7"  # reddish purple
    order = 4.0
    settings: ClassVar[Mapping[str, float | None]] = {"f_w": None}
    optional = VALVE
    ranges: ClassVar[Mapping[str, tuple[float, float, str]]] = {
        "c1": (1e-4, 1e4, "s·bar^-0.5"),
        "k2": (1e-4, 1e3, "bar"),
        "tau2": (1e-5, 1e4, "s"),
        "t_on": (-1.0, 1.0, "s"),
        "t_off": (-1.0, 1.0, "s"),
    }
    zero_allowed = ("t_on", "t_off")
    #: The inverted valve's delays are the charging and discharging times a pulse loses
    #: (:attr:`~spa.model.params.ValveParams.on_loss`): negative for a transport-delay valve
    #: whose closing delay exceeds its opening delay.
    signed = ("t_on", "t_off")
    default_grid: ClassVar[Mapping[str, float]] = {"start": 1.0, "stop": 76.0, "step": 0.1}
    reference = 20.0
    threshold_formulas = ("inverse of d(xi) = t_on*f_w", "inverse of d(xi) = 1 - t_off*f_w")
    guess_rank = math.inf  # its pulses are PWM's; the valve it inverts is not in the log

    def bind(self, s: Mapping[str, float], params: ValveParams) -> dict[str, float]:
        """The settings with the valve ``params`` filled in where not given."""
        return {**dict(s), **{k: v for k, v in zip(VALVE, _valve(s, params), strict=True)}}

    def duty(
        self, x: npt.NDArray[np.float64], s: Mapping[str, Any], p: ValveParams
    ) -> npt.NDArray[np.float64]:
        """The duty ``d(xi)`` that inverts Eq. 5 for the setting's valve (``p`` if none)."""
        c1, k2, tau2, t_on, t_off = _valve(s, p)
        f = s["f_w"]
        root = np.sqrt(k2 * x)
        a = root * tau2
        b = (k2 - root * root) * c1
        d = (a * (1.0 - t_off * f) + b * (t_on * f)) / (a + b)
        d = np.where(x <= 0.0, 0.0, np.where(x >= 1.0, 1.0, d))
        return np.clip(d, 0.0, 1.0)

    def pulse(
        self, x: npt.NDArray[np.float64], dt: float, s: Mapping[str, float]
    ) -> npt.NDArray[np.int8]:
        return _pulses.pwm(self.duty(x, s, ValveParams()), dt, s["f_w"])

    def thresholds(self, s: Mapping[str, Any], p: ValveParams) -> tuple[Any, Any]:
        """Where ``d(xi)`` crosses the plant's PWM thresholds ``t_on*f_w``, ``1 - t_off*f_w``.

        ``d = B + w*(A - B)`` with ``A = 1 - t_off*f_w``, ``B = t_on*f_w`` of the inverted
        valve and ``w(s) = s*tau2/(s*tau2 + (k2 - s²)*c1)``; for a target ``d`` the weight
        ``w = (d - B)/(A - B)`` gives ``w*c1*s² + (1 - w)*tau2*s - w*k2*c1 = 0``, whose
        positive root is ``s = sqrt(k2*xi)``. With the plant's own valve: 0 and 1.
        """
        c1, k2, tau2, t_on, t_off = _valve(s, p)
        f = np.asarray(s["f_w"], dtype=np.float64)
        a_hi, b_lo = 1.0 - t_off * f, t_on * f

        def crossing(target: Any) -> Any:
            with np.errstate(divide="ignore", invalid="ignore"):
                w = np.clip((target - b_lo) / (a_hi - b_lo), 0.0, 1.0)
                qa, qb, qc = w * c1, (1.0 - w) * tau2, w * k2 * c1
                disc = np.sqrt(qb * qb + 4.0 * qa * qc)
                root = 2.0 * qc / (qb + disc)
            return np.where(a_hi > b_lo, root * root / k2, np.nan)

        dead, sat = crossing(p.on_loss * f), crossing(1.0 - p.off_loss * f)
        return np.where(np.isnan(dead), 0.0, dead), np.where(np.isnan(sat), 1.0, sat)

    def guess(self, trace: Any) -> None:
        return None

    def feasible(self, v: npt.NDArray[np.float64], p: ValveParams) -> npt.NDArray[np.bool_]:
        """A linear range exists: ``1/f_w > t_on + t_off``."""
        return v * (p.on_loss + p.off_loss) < 1.0

    def constraint(self, p: ValveParams) -> str:
        if p.on_loss + p.off_loss <= 0.0:  # the transport convention: no hold to fit in
            return "f_w > 0 Hz, inverse of the identified valve"
        limit = 1.0 / (p.on_loss + p.off_loss)
        return f"f_w < 1/(t_on + t_off) = {limit:.4g} Hz, inverse of the identified valve"
