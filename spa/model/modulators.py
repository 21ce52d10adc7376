"""Digital pulse modulators: PWM, IPFM, inverse IPFM and first-order ΔΣ (docs/model.md section 2).

Every modulator runs at a fixed step ``dt``. ``xi[k]`` is the input fraction sampled at
``t = k*dt`` and ``u[k]`` the valve command held over ``[k*dt, (k+1)*dt)``. Event times are
quantised to the step: a pulse of width ``w`` lasts ``round(w/dt)`` steps (at least one).

None of them loops over samples in Python: each has a closed form in terms of cumulative
sums of the input.

* IPFM: the integrator with reset-by-subtraction fires exactly when the running integral
  ``C(t) = ∫ xi`` crosses a multiple of the threshold ``G*t_h``, so the firing count is
  ``floor(C/(G*t_h))``.
* IIPFM: the same on ``1 - xi`` with low pulses.
* ΔΣ: with ``v_k = v_{k-1} + xi_k - u_{k-1}``, ``u_k = [v_k >= 1/2]`` from ``v = u = 0``, the
  number of ones up to tick ``m`` is ``floor(S_m + 1/2)`` with ``S_m = xi_0 + ... + xi_m``
  (induction on ``m``, valid for ``xi`` in [0, 1]); ``u_m`` is its increment.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt

from spa import _checks as checks

__all__ = [
    "MODULATORS",
    "MODULATOR_ORDER",
    "Modulator",
    "check_settings",
    "modulate",
    "parse_modulator",
]

#: Modulator kinds and their settings with defaults (``None`` = required).
MODULATORS: Mapping[str, Mapping[str, float | None]] = {
    "pwm": {"f_w": None},
    "ipfm": {"t_h": None, "gain": 1.0},
    "iipfm": {"t_l": None, "gain": 1.0},
    "dsm": {"period": None},
}

#: The order in which modulators are listed in tables and legends.
MODULATOR_ORDER: tuple[str, ...] = ("pwm", "ipfm", "iipfm", "dsm")

#: The setting that characterises each modulator (its swept parameter) and its unit.
PARAMETER: Mapping[str, tuple[str, str]] = {
    "pwm": ("f_w", "Hz"),
    "ipfm": ("t_h", "s"),
    "iipfm": ("t_l", "s"),
    "dsm": ("period", "s"),
}

_NAMES = {"pwm": "PWM", "ipfm": "IPFM", "iipfm": "IIPFM", "dsm": "ΔΣM"}
_SYMBOLS = {"f_w": "f_W", "t_h": "t_h", "t_l": "t_l", "period": "T_ΔΣ"}

#: Plausible ranges of the settings (Hz for f_w, s for durations, 1 for the gain): outside
#: them a value is a typo or a unit slip (a frequency of 1e-300 Hz, a width of 20 s given as
#: 20 for 20 ms), not a modulator a solenoid valve can follow.
_RANGES: Mapping[str, tuple[float, float, str]] = {
    "f_w": (1e-3, 1e4, "Hz"),
    "t_h": (1e-5, 1e2, "s"),
    "t_l": (1e-5, 1e2, "s"),
    "period": (1e-5, 1e2, "s"),
    "gain": (1e-3, 1e3, ""),
}

# Relative tolerance used when comparing accumulated floating-point times to event times.
_EPS = 1e-9


def parse_modulator(mod: Mapping[str, Any]) -> tuple[str, dict[str, float]]:
    """Split a modulator mapping such as ``{"type": "pwm", "f_w": 20}`` into kind and settings.

    Returns
    -------
    kind : str
        ``mod["type"]``.
    settings : dict
        :func:`check_settings` of the other keys: complete, validated, as floats.

    Raises
    ------
    ValueError
        If ``mod`` is not a mapping with a ``type``, or as :func:`check_settings`.

    Examples
    --------
    >>> parse_modulator({"type": "iipfm", "t_l": 0.02})
    ('iipfm', {'t_l': 0.02, 'gain': 1.0})
    """
    if not isinstance(mod, Mapping) or "type" not in mod:
        raise ValueError(f"modulator must be a mapping with a 'type', got {mod!r}")
    kind = str(mod["type"])
    settings = {str(k): v for k, v in mod.items() if k != "type"}
    if kind in MODULATORS:
        unknown = sorted(set(settings) - set(MODULATORS[kind]))
        if unknown:  # also keeps 'dt' from reaching check_settings' own argument
            raise ValueError(
                f"{kind}: unknown setting(s) {unknown}; expected {sorted(MODULATORS[kind])}"
            )
    return kind, check_settings(kind, **settings)


def check_settings(kind: str, dt: float | None = None, **settings: Any) -> dict[str, float]:
    """Validate a modulator's settings and fill in defaults.

    Parameters
    ----------
    kind : {"pwm", "ipfm", "iipfm", "dsm"}
        Modulator type.
    dt : float, optional
        Step of the digital modulator in s. When given, settings are also checked against it
        (a period or pulse must last at least one step).
    **settings
        ``f_w`` (Hz) for PWM; ``t_h`` (s) and ``gain`` for IPFM; ``t_l`` (s) and ``gain`` for
        IIPFM; ``period`` (s) for ΔΣ.

    Returns
    -------
    dict
        The complete settings as floats.

    Raises
    ------
    ValueError
        For an unknown kind, an unknown or missing setting, or a value outside its range; the
        message names the setting and the allowed range.
    """
    if kind not in MODULATORS:
        raise ValueError(f"unknown modulator kind {kind!r}; expected one of {sorted(MODULATORS)}")
    spec = MODULATORS[kind]
    unknown = sorted(set(settings) - set(spec))
    if unknown:
        raise ValueError(f"{kind}: unknown setting(s) {unknown}; expected {sorted(spec)}")
    out: dict[str, float] = {}
    for name, default in spec.items():
        value = settings.get(name, default)
        if value is None:
            raise ValueError(f"{kind}: missing setting {name!r}")
        # Booleans and strings are refused (YAML ``true`` is not 1 Hz).
        out[name] = checks.positive(f"{kind}: setting {name!r}", value)
        lo, hi, unit = _RANGES[name]
        if not lo <= out[name] <= hi:
            raise ValueError(
                f"{kind}: setting {name!r} = {value!r} is outside the range a solenoid-valve "
                f"modulator can have, [{lo:g}, {hi:g}] {unit}"
            )
    if dt is not None:
        dt = checks.positive("dt", dt)
        if kind == "pwm" and 1.0 / out["f_w"] < 2.0 * dt * (1 - _EPS):
            raise ValueError(
                f"pwm: f_w = {out['f_w']:g} Hz is above half the controller rate 1/(2*dt) = "
                f"{0.5 / dt:g} Hz (dt = {dt:g} s): a period needs at least two steps"
            )
        width = {"ipfm": "t_h", "iipfm": "t_l", "dsm": "period"}.get(kind)
        if width is not None and out[width] < dt * (1 - _EPS):
            raise ValueError(
                f"{kind}: setting {width!r} = {out[width]:g} s is shorter than dt = {dt:g} s"
            )
        if kind in ("ipfm", "iipfm") and out["gain"] * out[width] < dt * (1 - _EPS):
            raise ValueError(
                f"{kind}: threshold gain*{width} = {out['gain'] * out[width]:g} s is shorter than "
                f"dt = {dt:g} s; increase 'gain' or {width!r}"
            )
    return out


@dataclass(frozen=True)
class Modulator:
    """One modulator setting: the type and its complete, validated settings.

    Built once where a setting enters (the config, a ``dataset.yaml``, a notebook) with
    :meth:`from_mapping`; every later stage passes this value around and never re-parses a
    mapping. ``label`` is the one name used in run ids, file names, tables, legends and the
    report.

    Parameters
    ----------
    kind : {"pwm", "ipfm", "iipfm", "dsm"}
        Modulator type.
    settings : mapping
        As :func:`check_settings` (missing defaults are filled in, values checked).

    Examples
    --------
    >>> m = Modulator.from_mapping({"type": "iipfm", "t_l": 0.02, "gain": 1.15})
    >>> m.label, m.description
    ('iipfm-20ms-G1.15', 'IIPFM, t_l = 20 ms, G = 1.15')
    >>> m.to_mapping()
    {'type': 'iipfm', 't_l': 0.02, 'gain': 1.15}
    >>> sorted(Modulator.from_mapping({"type": "ipfm", "t_h": t}).label for t in (0.1, 0.01))
    ['ipfm-100ms', 'ipfm-10ms']
    >>> [m.label for m in sorted(Modulator.from_mapping({"type": "ipfm", "t_h": t})
    ...                          for t in (0.1, 0.01))]
    ['ipfm-10ms', 'ipfm-100ms']
    """

    kind: str
    settings: Mapping[str, float] = field(compare=False)
    _key: tuple[Any, ...] = field(init=False, repr=False, compare=True)

    def __post_init__(self) -> None:
        full = check_settings(self.kind, **dict(self.settings))
        object.__setattr__(self, "settings", full)
        object.__setattr__(self, "_key", self.sort_key)

    @classmethod
    def from_mapping(cls, mod: Mapping[str, Any] | Modulator) -> Modulator:
        """The value of a mapping such as ``{"type": "pwm", "f_w": 20}`` (or a Modulator)."""
        if isinstance(mod, Modulator):
            return mod
        kind, settings = parse_modulator(mod)
        return cls(kind, settings)

    def to_mapping(self) -> dict[str, Any]:
        """The mapping form, as a ``dataset.yaml`` or the config writes it (gain 1 omitted)."""
        out: dict[str, Any] = {"type": self.kind}
        for name, value in self.settings.items():
            if name == "gain" and value == 1.0:
                continue
            out[name] = value
        return out

    @property
    def parameter(self) -> str:
        """Name of the characteristic setting: ``f_w``, ``t_h``, ``t_l`` or ``period``."""
        return PARAMETER[self.kind][0]

    @property
    def value(self) -> float:
        """Value of the characteristic setting, in Hz (PWM) or s."""
        return self.settings[self.parameter]

    @property
    def gain(self) -> float:
        """Threshold gain G (1 for PWM and ΔΣM)."""
        return self.settings.get("gain", 1.0)

    @property
    def name(self) -> str:
        """Display name of the type: PWM, IPFM, IIPFM or ΔΣM."""
        return _NAMES[self.kind]

    @property
    def label(self) -> str:
        """Short file-safe name, e.g. ``pwm-20Hz``, ``ipfm-20ms``, ``iipfm-20ms-G1.15``."""
        if self.kind == "pwm":
            return f"pwm-{self.value:g}Hz"
        label = f"{self.kind}-{self.value * 1e3:g}ms"
        if not math.isclose(self.gain, 1.0):
            label += f"-G{self.gain:g}"
        return label

    @property
    def description(self) -> str:
        """Human description, e.g. ``PWM, f_W = 20 Hz`` or ``IIPFM, t_l = 20 ms, G = 1.15``."""
        symbol = _SYMBOLS[self.parameter]
        if self.kind == "pwm":
            text = f"{self.name}, {symbol} = {self.value:g} Hz"
        else:
            text = f"{self.name}, {symbol} = {self.value * 1e3:g} ms"
        if self.kind in ("ipfm", "iipfm") and not math.isclose(self.gain, 1.0):
            text += f", G = {self.gain:g}"
        return text

    @property
    def sort_key(self) -> tuple[int, float, float]:
        """Numeric order: by type (PWM, IPFM, IIPFM, ΔΣM), then setting value, then gain."""
        return (MODULATOR_ORDER.index(self.kind), self.value, self.gain)

    def __lt__(self, other: Modulator) -> bool:
        return self.sort_key < other.sort_key

    def modulate(self, xi: npt.ArrayLike, dt: float) -> npt.NDArray[np.int8]:
        """:func:`modulate` with this setting."""
        return modulate(self.kind, xi, dt, **self.settings)


def _steps(width: float, dt: float) -> int:
    """Number of steps a pulse of ``width`` seconds lasts (at least one)."""
    return max(1, math.floor(width / dt + 0.5))


def _first_steps(times: npt.NDArray[np.float64], dt: float) -> npt.NDArray[np.int64]:
    """Index of the first step at or after each event time (to a relative tolerance)."""
    return np.ceil(times / dt - _EPS).astype(np.int64)


def _from_edges(
    n: int, rise: npt.NDArray[np.int64], fall: npt.NDArray[np.int64]
) -> npt.NDArray[np.int8]:
    """0/1 signal high on the union of the intervals ``[rise[i], fall[i])`` (clipped to n)."""
    d = np.zeros(n + 1, dtype=np.int32)
    np.add.at(d, np.minimum(rise, n), 1)
    np.subtract.at(d, np.minimum(fall, n), 1)
    return (np.cumsum(d[:-1]) > 0).view(np.int8)


def _period_starts(n: int, dt: float, period: float) -> npt.NDArray[np.int64]:
    """First step of each clock period ``m*period`` that starts within ``n`` steps."""
    m = np.arange(math.floor(n * dt / period) + 2)
    starts = _first_steps(m * period, dt)
    starts = starts[starts < n]
    return np.unique(starts)


def _pwm(x: npt.NDArray[np.float64], dt: float, f_w: float) -> npt.NDArray[np.int8]:
    period = 1.0 / f_w
    starts = _period_starts(x.size, dt, period)  # xi is sampled at these steps
    t_start = np.arange(starts.size) * period
    ends = _first_steps(t_start + x[starts] * period, dt)
    nxt = np.append(starts[1:], x.size)
    ends = np.clip(ends, starts, nxt)
    return _from_edges(x.size, starts, ends)


def _firings(x: npt.NDArray[np.float64], dt: float, threshold: float) -> npt.NDArray[np.int64]:
    """Steps at which an integrate-and-fire modulator with reset-by-subtraction fires.

    The integral up to ``t_k`` (exclusive, in units of ``dt``) crosses the m-th multiple of
    the threshold exactly where the integrator with subtraction reaches the threshold.
    """
    steps = threshold / dt
    c = np.cumsum(x)  # c[k] = integral up to t_{k+1}
    total = math.floor(c[-1] / steps + _EPS) if c.size else 0
    targets = (np.arange(1, total + 1) - _EPS) * steps
    fire = np.searchsorted(c, targets, side="left") + 1  # first k with integral(t_k) >= target
    return np.unique(fire[fire < x.size])


def _dsm(x: npt.NDArray[np.float64], dt: float, period: float) -> npt.NDArray[np.int8]:
    ticks = _period_starts(x.size, dt, period)
    s = np.cumsum(x[ticks])
    ones = np.floor(s + 0.5 + _EPS)
    u_tick = np.diff(ones, prepend=0.0).astype(np.int8)
    lengths = np.diff(np.append(ticks, x.size))
    return np.repeat(u_tick, lengths)


def modulate(kind: str, xi: npt.ArrayLike, dt: float, **settings: float) -> npt.NDArray[np.int8]:
    """Turn an input fraction into a 0/1 valve command with a digital pulse modulator.

    Parameters
    ----------
    kind : {"pwm", "ipfm", "iipfm", "dsm"}
        ``"pwm"``: pulse-width modulation at ``f_w`` Hz; ``xi`` is sampled at the start of
        each period and the output is high for ``xi/f_w`` of it.
        ``"ipfm"``: integral pulse-frequency modulation; an integrator of ``xi`` fires a high
        pulse of width ``t_h`` s when it reaches ``gain*t_h`` and subtracts that threshold.
        ``"iipfm"``: inverse IPFM; high by default, an integrator of ``1 - xi`` fires a low
        pulse of width ``t_l`` s when it reaches ``gain*t_l``.
        ``"dsm"``: first-order ΔΣ clocked every ``period`` s:
        ``v_k = v_{k-1} + xi_k - u_{k-1}``, ``u_k = [v_k >= 1/2]``, from ``v = u = 0``.
    xi : array_like of float, shape (n,)
        Input fraction at ``t = k*dt``; clipped to [0, 1].
    dt : float
        Step of the modulator in s.
    **settings
        ``f_w``; ``t_h`` and ``gain`` (default 1); ``t_l`` and ``gain`` (default 1); ``period``.

    Returns
    -------
    numpy.ndarray of int8, shape (n,)
        ``u[k]`` in {0, 1}, the command over ``[k*dt, (k+1)*dt)``.

    Raises
    ------
    ValueError
        If ``xi`` holds NaN or inf, or a setting is missing, unknown or out of range (for
        example a PWM period or a pulse width shorter than ``dt``).

    Notes
    -----
    Steady pulse trains for constant ``xi`` (Appendix A): PWM duty ``xi`` at ``f_w``; IPFM
    ``t_h`` high and ``t_h*(G/xi - 1)`` low; IIPFM ``t_l*(G/(1-xi) - 1)`` high and ``t_l``
    low; ΔΣ duty ``xi`` in multiples of ``period``. A firing while a pulse is still running
    extends it to a full width after the new firing, so with ``G = 1`` IPFM stays high at
    ``xi = 1`` and IIPFM stays low at ``xi = 0``.

    Examples
    --------
    >>> u = modulate("pwm", [0.25] * 8, dt=0.125, f_w=0.5)
    >>> u.tolist()
    [1, 1, 1, 1, 0, 0, 0, 0]
    """
    s = check_settings(kind, dt, **settings)
    x = np.clip(checks.finite_array("xi", xi, ndim=1), 0.0, 1.0)
    if x.size == 0:
        return np.zeros(0, dtype=np.int8)
    if kind == "pwm":
        return _pwm(x, dt, s["f_w"])
    if kind == "ipfm":
        fire = _firings(x, dt, s["gain"] * s["t_h"])
        return _from_edges(x.size, fire, fire + _steps(s["t_h"], dt))
    if kind == "iipfm":
        fire = _firings(1.0 - x, dt, s["gain"] * s["t_l"])
        return 1 - _from_edges(x.size, fire, fire + _steps(s["t_l"], dt))
    return _dsm(x, dt, s["period"])
