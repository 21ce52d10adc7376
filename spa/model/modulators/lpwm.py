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

A valve with its own laws (:attr:`~spa.model.params.ValveParams.laws`; docs/model.md, "The
general two-mode model") has the same inverse with the general rates: at ``P = k2*xi`` the
averaged rate ``alpha2*f_open(P) + alpha1*f_closed(P)`` vanishes for the duty
``d = w*(1 - t_off*f_w) + (1 - w)*t_on*f_w`` with ``w = B/(A + B)``, ``A = f_open(P)``,
``B = -f_closed(P)`` (the paper's weight when the laws are the paper's). ``w`` depends on the
valve alone, so it is tabulated once per valve at ``LAW_INTERVALS + 1`` nodes uniform in
``sqrt(xi)`` (:func:`law_weights`) and interpolated linearly; the averaged model, the
closed loop's kernel and the exported C header read the same table. The laws come from the
context valve (the plant's in the averaged analysis, the closed loop's valve in the loop and
the header), the scale ``c1, k2, tau2`` from the setting where it names them.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from functools import lru_cache
from typing import Any, ClassVar

import numpy as np
import numpy.typing as npt

from spa.model.modulators import _pulses
from spa.model.modulators.pwm import PWM
from spa.model.params import ValveParams

__all__ = ["LAW_INTERVALS", "LPWM", "VALVE", "law_duty", "law_weights"]

#: The valve settings LPWM may carry: the parameters it inverts.
VALVE: tuple[str, ...] = ("c1", "k2", "tau2", "t_on", "t_off")


#: Intervals of the law weight table (:func:`law_weights`), uniform in ``sqrt(xi)``: its
#: ``LAW_INTERVALS + 1`` doubles are the flash an exported header spends on the laws.
LAW_INTERVALS = 256


def _valve(s: Mapping[str, Any], p: ValveParams) -> tuple[Any, ...]:
    """The inverted valve: the setting's own parameters where given, else ``p``'s."""
    own = {"t_on": p.on_loss, "t_off": p.off_loss}  # the losses: the delays under "hold"
    return tuple(s.get(name, own.get(name, getattr(p, name))) for name in VALVE)


@lru_cache(maxsize=32)
def _weights(scale: ValveParams) -> npt.NDArray[np.float64]:
    from spa.model.laws.rates import closed_rate, open_rate

    u = np.arange(LAW_INTERVALS + 1, dtype=np.float64) / LAW_INTERVALS
    pressure = scale.k2 * (u * u)
    a = open_rate(pressure, scale)
    b = -closed_rate(pressure, scale)
    w = b / (a + b)
    w[0], w[-1] = 0.0, 1.0  # no exhaust at P = 0, no charge at P = k2
    if not np.all(np.diff(w) > 0.0):
        raise ValueError(
            "LPWM: the valve's laws give an averaged equilibrium that is not monotone in the "
            "duty (the exhaust's weight B/(A + B) falls somewhere in [0, k2]); expected laws "
            "whose ratio -f_closed/f_open grows with the pressure"
        )
    w.flags.writeable = False
    return w


def _invertible(p: ValveParams) -> bool:
    """Whether LPWM can invert ``p``: the paper's laws, or its own with a monotone weight."""
    try:
        law_weights({}, p)
    except ValueError:
        return False
    return True


def law_weights(s: Mapping[str, Any], p: ValveParams) -> npt.NDArray[np.float64] | None:
    """The inverted valve's weight table, or None for the paper's laws (the closed form).

    Parameters
    ----------
    s : mapping
        The LPWM setting; its ``c1``, ``k2``, ``tau2`` (where given) scale the laws.
    p : ValveParams
        The context valve, whose :attr:`~spa.model.params.ValveParams.laws` are inverted.

    Returns
    -------
    numpy.ndarray or None
        ``w`` at ``xi = (i/LAW_INTERVALS)**2``, ``i = 0..LAW_INTERVALS`` (read-only, cached
        per valve): 0 at ``xi = 0``, 1 at ``xi = 1``, strictly increasing.

    Raises
    ------
    ValueError
        If the laws' weight is not strictly increasing (no monotone inverse).
    """
    if p.laws is None:
        return None
    c1, k2, tau2, _, _ = _valve(s, p)
    scale = ValveParams(c1=c1, k2=k2, tau2=tau2, t_on=0.0, t_off=0.0, laws=p.laws)
    return _weights(scale)


def law_duty(
    x: npt.NDArray[np.float64], f: Any, t_on: Any, t_off: Any, w: npt.NDArray[np.float64]
) -> npt.NDArray[np.float64]:
    """The duty of the laws' inverse: ``w(xi)`` interpolated linearly in ``sqrt(xi)`` from
    the table ``w`` (:func:`law_weights`), with the operations of the closed-loop kernel
    (:mod:`spa.model.modulators.kernels.lpwm`) in the same order."""
    n = w.size - 1
    j = np.sqrt(np.clip(x, 0.0, 1.0)) * n
    i = np.minimum(j.astype(np.int64), n - 1)
    s = j - i
    lo = w[i]
    wx = lo + s * (w[i + 1] - lo)
    d = wx * (1.0 - t_off * f) + (1.0 - wx) * (t_on * f)
    d = np.where(x <= 0.0, 0.0, np.where(x >= 1.0, 1.0, d))
    return np.clip(d, 0.0, 1.0)


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
        """The duty ``d(xi)`` that inverts Eq. 5 (or the laws' equilibrium, for a valve
        ``p`` with laws) for the setting's valve (``p`` if none)."""
        c1, k2, tau2, t_on, t_off = _valve(s, p)
        f = s["f_w"]
        w = law_weights(s, p)
        if w is not None:
            return law_duty(np.asarray(x, dtype=np.float64), f, t_on, t_off, w)
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
        table = law_weights(s, p)

        def crossing(target: Any) -> Any:
            with np.errstate(divide="ignore", invalid="ignore"):
                w = np.clip((target - b_lo) / (a_hi - b_lo), 0.0, 1.0)
                if table is not None:  # the laws: invert the table (linear in sqrt(xi))
                    u = np.arange(table.size, dtype=np.float64) / (table.size - 1)
                    return np.where(a_hi > b_lo, np.interp(w, table, u) ** 2, np.nan)
                qa, qb, qc = w * c1, (1.0 - w) * tau2, w * k2 * c1
                disc = np.sqrt(qb * qb + 4.0 * qa * qc)
                root = 2.0 * qc / (qb + disc)
            return np.where(a_hi > b_lo, root * root / k2, np.nan)

        dead, sat = crossing(p.on_loss * f), crossing(1.0 - p.off_loss * f)
        return np.where(np.isnan(dead), 0.0, dead), np.where(np.isnan(sat), 1.0, sat)

    def guess(self, trace: Any) -> None:
        return None

    def feasible(self, v: npt.NDArray[np.float64], p: ValveParams) -> npt.NDArray[np.bool_]:
        """A linear range exists: ``1/f_w > t_on + t_off``, and the valve's laws, if it has
        its own, have a monotone inverse (:func:`law_weights`)."""
        if not _invertible(p):
            return np.zeros(np.shape(v), dtype=bool)
        return v * (p.on_loss + p.off_loss) < 1.0

    def constraint(self, p: ValveParams) -> str:
        if not _invertible(p):
            return (
                "laws whose averaged equilibrium rises with the duty (these laws' exhaust "
                "weight B/(A + B) falls somewhere in [0, k2]: no inverse)"
            )
        if p.on_loss + p.off_loss <= 0.0:  # the transport convention: no hold to fit in
            return "f_w > 0 Hz, inverse of the identified valve"
        limit = 1.0 / (p.on_loss + p.off_loss)
        return f"f_w < 1/(t_on + t_off) = {limit:.4g} Hz, inverse of the identified valve"
