"""The interface every modulator kind implements, and the registry of kinds.

A kind (``pwm``, ``ipfm``, …) is one subclass of :class:`ModulatorKind` in its own module of
this package. Like a ``scipy.stats`` distribution, it states only what is its own (its
settings, pulse law, averaged fractions, thresholds, tuning grid, names and colour) and
inherits the rest. :func:`register` adds it to :data:`REGISTRY`; everything outside this
package asks a kind (through :class:`~spa.model.modulators.Modulator` or :func:`get_kind`)
and never branches on its name.
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping, Sequence
from typing import Any, ClassVar

import numpy as np
import numpy.typing as npt

from spa.model.params import ValveParams

__all__ = ["REGISTRY", "ModulatorKind", "get_kind", "kinds", "register"]

#: Plausible ranges of the common settings: outside them a value is a typo or a unit slip (a
#: frequency of 1e-300 Hz, a width of 20 s given as 20 for 20 ms), not a modulator a
#: solenoid valve can follow. ``name -> (low, high, unit)``.
RANGES: Mapping[str, tuple[float, float, str]] = {
    "f_w": (1e-3, 1e4, "Hz"),
    "t_h": (1e-5, 1e2, "s"),
    "t_l": (1e-5, 1e2, "s"),
    "period": (1e-5, 1e2, "s"),
    "gain": (1e-3, 1e3, ""),
}


class ModulatorKind:
    """One kind of pulse modulator: what it is called, what it takes, how it pulses.

    Subclasses set the class attributes and implement :meth:`pulse`, :meth:`pulse_times`,
    :meth:`fractions` and :meth:`thresholds`; the other methods have defaults. ``s`` is
    always the complete settings mapping (values may be arrays that broadcast with ``x``)
    and ``p`` the valve (:class:`~spa.model.params.ValveParams`) the plant has.
    """

    #: The ``type`` key of a setting, e.g. ``"pwm"``.
    type: ClassVar[str] = ""
    #: Display name, e.g. ``"PWM"``.
    name: ClassVar[str] = ""
    #: The characteristic (swept) setting, its display symbol and its unit (``Hz`` or ``s``).
    parameter: ClassVar[str] = ""
    symbol: ClassVar[str] = ""
    unit: ClassVar[str] = "s"
    #: Symbol of the common time axis of Fig. 4 (``T_W = 1/f_W`` for a frequency).
    axis_name: ClassVar[str] = ""
    #: Colour in every figure (Okabe–Ito).
    colour: ClassVar[str] = "#000000"
    #: Rank in tables and legends (smaller first).
    order: ClassVar[float] = 99.0
    #: Settings and their defaults (``None``: required).
    settings: ClassVar[Mapping[str, float | None]] = {}
    #: Settings that may be left out (no default: the context supplies them).
    optional: ClassVar[tuple[str, ...]] = ()
    #: Ranges of the own settings beyond :data:`RANGES`: ``name -> (low, high, unit)``.
    ranges: ClassVar[Mapping[str, tuple[float, float, str]]] = {}
    #: Settings that may be 0 (delays).
    zero_allowed: ClassVar[tuple[str, ...]] = ()
    signed: ClassVar[tuple[str, ...]] = ()
    #: Default tuning grid of :attr:`parameter`: ``{start, stop, step}``.
    default_grid: ClassVar[Mapping[str, float]] = {}
    #: Reference value of :attr:`parameter` (the paper's choice: 20 Hz or 20 ms).
    reference: ClassVar[float] = math.nan
    #: Table 1 as text: (dead-zone, saturation) closed forms of ``xi``.
    threshold_formulas: ClassVar[tuple[str, str]] = ("", "")
    #: Whether the kind takes a threshold gain (IPFM, IIPFM).
    has_gain: ClassVar[bool] = False
    #: Order in which ``spa init`` asks the kinds to recognise a logged command (:meth:`guess`).
    guess_rank: ClassVar[float] = math.inf
    #: Whether the tuning also sweeps the gain (``tuning.gain_sweep``: IIPFM).
    gain_swept: ClassVar[bool] = False

    # --- settings -------------------------------------------------------------------------
    def range(self, setting: str) -> tuple[float, float, str]:
        """Plausible ``(low, high, unit)`` of one setting."""
        return {**RANGES, **self.ranges}[setting]

    def check_dt(self, s: Mapping[str, float], dt: float) -> None:
        """Raise ValueError when the settings cannot run at the step ``dt``."""

    def bind(self, s: Mapping[str, float], params: ValveParams) -> dict[str, float]:
        """The settings completed from the valve ``params`` (kinds that use the valve)."""
        return dict(s)

    # --- pulse law ------------------------------------------------------------------------
    def pulse(
        self, x: npt.NDArray[np.float64], dt: float, s: Mapping[str, float]
    ) -> npt.NDArray[np.int8]:
        """The 0/1 command for the sampled, clipped input ``x`` (:func:`modulate`)."""
        raise NotImplementedError

    # --- averaged model -------------------------------------------------------------------
    def pulse_times(
        self, x: npt.NDArray[np.float64], s: Mapping[str, Any], p: ValveParams
    ) -> tuple[Any, Any]:
        """Steady high and low durations for a constant input (Appendix A)."""
        raise NotImplementedError

    def fractions(
        self, x: npt.NDArray[np.float64], s: Mapping[str, Any], p: ValveParams
    ) -> tuple[Any, Any]:
        """Averaged discharging and charging fractions ``alpha1``, ``alpha2`` (Eqs. 11–19)."""
        raise NotImplementedError

    def thresholds(self, s: Mapping[str, Any], p: ValveParams) -> tuple[Any, Any]:
        """Dead-zone and saturation thresholds of ``xi`` (Table 1; clipped by the caller)."""
        raise NotImplementedError

    def periodic_mean(
        self,
        x: npt.NDArray[np.float64],
        s: Mapping[str, Any],
        p: ValveParams,
        max_denominator: int | None = None,
    ) -> Any:
        """Exact time mean of the periodic orbit: the train of :meth:`pulse_times`."""
        from spa.model.periodic import train_mean

        return train_mean(*self.pulse_times(x, s, p), p)

    def periodic_means(
        self,
        x: npt.NDArray[np.float64],
        settings: Sequence[Mapping[str, Any]],
        valves: Sequence[ValveParams],
        max_denominator: int | None = None,
    ) -> npt.NDArray[np.float64]:
        """:meth:`periodic_mean` of several valves, each with its own settings: one row a
        valve, each row bit for bit that valve's :meth:`periodic_mean` (a kind whose orbit
        is iterated computes them in one batch)."""
        return np.stack(
            [
                np.asarray(self.periodic_mean(x, s, p, max_denominator), dtype=np.float64)
                for s, p in zip(settings, valves, strict=True)
            ]
        )

    def cycle(self, x: npt.NDArray[np.float64], s: Mapping[str, Any], p: ValveParams) -> Any:
        """The time after which the train repeats at a constant input, s: the pulse period
        ``t_h + t_l`` of :meth:`pulse_times` (``inf`` where it never pulses). The window of a
        cycle-mean pressure (:func:`spa.closedloop.experiments.cycle_period`)."""
        t_h, t_l = self.pulse_times(x, s, p)
        return np.asarray(t_h, dtype=np.float64) + np.asarray(t_l, dtype=np.float64)

    def min_pulse(self, moving: npt.NDArray[np.float64], s: Mapping[str, Any]) -> Any:
        """Shortest pulse that moves the pressure, from the steady durations' ``moving``."""
        return moving

    # --- tuning ---------------------------------------------------------------------------
    def sweep_settings(
        self, v: npt.NDArray[np.float64], p: ValveParams, gain: Any = None
    ) -> dict[str, Any]:
        """Settings for values ``v`` of :attr:`parameter` (the tuning sweep)."""
        if gain is not None:
            raise ValueError(f"{self.type}: has no gain; only kinds with a threshold take one")
        return {self.parameter: v}

    def feasible(self, v: npt.NDArray[np.float64], p: ValveParams) -> npt.NDArray[np.bool_]:
        """Whether values of :attr:`parameter` meet the kind's constraint (Section 5.1)."""
        return np.ones(v.shape, dtype=bool)

    def constraint(self, p: ValveParams) -> str:
        """The constraint of :meth:`feasible` as text."""
        return f"{self.parameter} > 0"

    def sweep_limits(
        self, values: npt.NDArray[np.float64], p: ValveParams
    ) -> list[tuple[str, float, float, str, str]]:
        """``(delay name, delay, limit, what, rule)``: a delay at least ``limit`` leaves no
        value of the grid ``values`` feasible (:func:`spa.tuning.cost.check_sweeps`)."""
        return []

    def analytic_optimum(self, p: ValveParams) -> float:
        """A closed-form optimum of :attr:`parameter` in display units, or NaN."""
        return math.nan

    def guess(self, trace: Any) -> tuple[dict[str, Any], str] | None:
        """This kind's setting and the reason, if a logged command
        (:class:`~spa.model.modulators.trace.Trace`) looks like its pulses; else None."""
        return None

    # --- names ----------------------------------------------------------------------------
    @property
    def scale(self) -> float:
        """Factor from :attr:`unit` to the display unit (Hz stays, s becomes ms)."""
        return 1.0 if self.unit == "Hz" else 1e3

    @property
    def unscale(self) -> float:
        """Factor from the display unit back to :attr:`unit` (1 for Hz, 1e-3 for ms)."""
        return 1.0 if self.unit == "Hz" else 1e-3

    @property
    def display_unit(self) -> str:
        """``Hz`` or ``ms``."""
        return "Hz" if self.unit == "Hz" else "ms"

    def axis_ms(self, values: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
        """The common time axis of Fig. 4 in ms: a period for a frequency, else the value."""
        return 1e3 / values if self.unit == "Hz" else 1e3 * values

    def label(self, s: Mapping[str, float]) -> str:
        """Short file-safe name, e.g. ``pwm-20Hz``, ``iipfm-20ms-G1.15``."""
        label = f"{self.type}-{s[self.parameter] * self.scale:g}{self.display_unit}"
        if self.has_gain and not math.isclose(s["gain"], 1.0):
            label += f"-G{s['gain']:g}"
        return label

    def description(self, s: Mapping[str, float]) -> str:
        """Human description, e.g. ``PWM, f_W = 20 Hz``."""
        text = f"{self.name}, {self.symbol} = {s[self.parameter] * self.scale:g} "
        text += self.display_unit
        if self.has_gain and not math.isclose(s["gain"], 1.0):
            text += f", G = {s['gain']:g}"
        return text

    def parse_label(self, label: str) -> dict[str, float] | None:
        """The settings a :meth:`label` names, or None when it is not one of this kind's."""
        m = re.match(
            rf"^{re.escape(self.type)}-(?P<value>[0-9.eE+-]+){self.display_unit}"
            r"(?:-G(?P<gain>[0-9.]+))?$",
            str(label),
        )
        if m is None or (m["gain"] is not None and not self.has_gain):
            return None
        out = {self.parameter: float(m["value"]) * self.unscale}
        if m["gain"] is not None:
            out["gain"] = float(m["gain"])
        return out

    def example(self) -> str:
        """The setting as ``dataset.yaml`` writes it, with units in place of values.

        Examples
        --------
        >>> from spa.model.modulators import get_kind
        >>> get_kind("iipfm").example()
        '{type: iipfm, t_l: <s>, gain: <G>}'
        >>> get_kind("lpwm").example()
        '{type: lpwm, f_w: <Hz>, c1: <s·bar^-0.5>, k2: <bar>, tau2: <s>, t_on: <s>, t_off: <s>}'
        """
        names = (*self.settings, *self.optional)
        values = [f"{n}: <{self.range(n)[2] or 'G'}>" for n in names]
        return "{" + ", ".join([f"type: {self.type}", *values]) + "}"

    def schema(self) -> dict[str, Any]:
        """This kind's part of the JSON schema of a modulator setting."""
        props: dict[str, Any] = {"type": {"const": self.type}}
        for key in (*self.settings, *self.optional):
            props[key] = {"type": "number", "exclusiveMinimum": 0}
        required = ["type", *(k for k, v in self.settings.items() if v is None)]
        return {
            "type": "object",
            "required": required,
            "properties": props,
            "additionalProperties": False,
        }


#: ``type -> kind``: every registered modulator kind.
REGISTRY: dict[str, ModulatorKind] = {}


def register(cls: type[ModulatorKind]) -> type[ModulatorKind]:
    """Register a kind (usable as a class decorator); its ``type`` must be new."""
    if not cls.type or not re.fullmatch(r"[a-z][a-z0-9]*", cls.type):
        raise ValueError(f"modulator kind type must be lower-case letters/digits, got {cls.type!r}")
    if cls.type in REGISTRY:
        raise ValueError(f"modulator kind {cls.type!r} is already registered")
    REGISTRY[cls.type] = cls()
    return cls


def kinds() -> tuple[str, ...]:
    """The registered kinds in table order."""
    return tuple(sorted(REGISTRY, key=lambda k: REGISTRY[k].order))


def get_kind(kind: str) -> ModulatorKind:
    """The registered kind of a ``type``.

    Raises
    ------
    ValueError
        For an unknown kind; the message lists the known ones.
    """
    try:
        return REGISTRY[kind]
    except (KeyError, TypeError):
        raise ValueError(
            f"unknown modulator kind {kind!r}; expected one of {sorted(REGISTRY)}"
        ) from None
