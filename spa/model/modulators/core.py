"""The modulator value type and the functions every kind shares (docs/model.md section 2).

:class:`Modulator` is the one value a modulator setting is passed around as: built once where
a setting enters (the config, a ``dataset.yaml``, the command line, a run's metadata) and
asked, never re-parsed. Each kind (:mod:`spa.model.modulators.pwm` and its siblings) holds
its own pulse law; :func:`modulate` dispatches to it through the registry.

Every modulator runs at a fixed step ``dt``. ``xi[k]`` is the input fraction sampled at
``t = k*dt`` and ``u[k]`` the valve command held over ``[k*dt, (k+1)*dt)``. Event times are
quantised to the step: a pulse of width ``w`` lasts ``round(w/dt)`` steps (at least one).
None of them loops over samples in Python (:mod:`spa.model.modulators._pulses`).
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, overload

import numpy as np
import numpy.typing as npt

from spa import _checks as checks
from spa.model.modulators.base import REGISTRY, get_kind, kinds

__all__ = [
    "MODULATORS",
    "MODULATOR_ORDER",
    "PARAMETER",
    "Modulator",
    "check_settings",
    "modulate",
    "parse_modulator",
    "settings_arrays",
]


class _Settings(Mapping[str, Mapping[str, "float | None"]]):
    """``kind -> {setting: default}`` of every registered kind (None: required or optional)."""

    def __getitem__(self, kind: str) -> Mapping[str, float | None]:
        k = REGISTRY[kind]
        return {**k.settings, **dict.fromkeys(k.optional)}

    def __iter__(self) -> Iterator[str]:
        return iter(kinds())

    def __len__(self) -> int:
        return len(REGISTRY)


class _Parameter(Mapping[str, tuple[str, str]]):
    """``kind -> (swept setting, unit)`` of every registered kind."""

    def __getitem__(self, kind: str) -> tuple[str, str]:
        k = REGISTRY[kind]
        return (k.parameter, k.unit)

    def __iter__(self) -> Iterator[str]:
        return iter(kinds())

    def __len__(self) -> int:
        return len(REGISTRY)


class _Order(Sequence[str]):
    """The registered kinds in table order (a live tuple)."""

    @overload
    def __getitem__(self, i: int) -> str: ...
    @overload
    def __getitem__(self, i: slice) -> tuple[str, ...]: ...
    def __getitem__(self, i: int | slice) -> str | tuple[str, ...]:
        return kinds()[i]

    def __len__(self) -> int:
        return len(REGISTRY)

    def __repr__(self) -> str:
        return repr(kinds())


#: Modulator kinds and their settings with defaults (``None`` = required, or optional for
#: the kinds that take the valve from their context).
MODULATORS: Mapping[str, Mapping[str, float | None]] = _Settings()

#: The order in which modulators are listed in tables and legends.
MODULATOR_ORDER: Sequence[str] = _Order()

#: The setting that characterises each modulator (its swept parameter) and its unit.
PARAMETER: Mapping[str, tuple[str, str]] = _Parameter()


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
    if kind in REGISTRY:
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
    kind : str
        Modulator type, a registered kind (:data:`MODULATOR_ORDER`).
    dt : float, optional
        Step of the digital modulator in s. When given, settings are also checked against it
        (a period or pulse must last at least one step).
    **settings
        ``f_w`` (Hz) for PWM; ``t_h`` (s) and ``gain`` for IPFM; ``t_l`` (s) and ``gain`` for
        IIPFM; ``period`` (s) for ΔΣ; ``f_w`` and optionally the valve ``c1``, ``k2``,
        ``tau2``, ``t_on``, ``t_off`` for LPWM (each kind's ``settings``).

    Returns
    -------
    dict
        The complete settings as floats (optional settings only when given).

    Raises
    ------
    ValueError
        For an unknown kind, an unknown or missing setting, or a value outside its range; the
        message names the setting and the allowed range.
    """
    k = get_kind(kind)
    spec = MODULATORS[kind]
    unknown = sorted(set(settings) - set(spec))
    if unknown:
        raise ValueError(f"{kind}: unknown setting(s) {unknown}; expected {sorted(spec)}")
    out: dict[str, float] = {}
    for name, default in spec.items():
        value = settings.get(name, default)
        if value is None:
            if name in k.optional:
                continue
            raise ValueError(f"{kind}: missing setting {name!r}")
        # Booleans and strings are refused (YAML ``true`` is not 1 Hz).
        check = (
            checks.number
            if name in k.signed
            else checks.nonnegative
            if name in k.zero_allowed
            else checks.positive
        )
        out[name] = check(f"{kind}: setting {name!r}", value)
        lo, hi, unit = k.range(name)
        if not lo <= out[name] <= hi:
            raise ValueError(
                f"{kind}: setting {name!r} = {value!r} is outside the range a solenoid-valve "
                f"modulator can have, [{lo:g}, {hi:g}] {unit}"
            )
    if dt is not None:
        k.check_dt(out, checks.positive("dt", dt))
    return out


@dataclass(frozen=True)
class Modulator(Mapping[str, Any]):
    """One modulator setting: the type and its complete, validated settings.

    Built once where a setting enters (the config, a ``dataset.yaml``, the command line, a
    run's metadata in :func:`spa.datasets.read_runs`, a notebook) with :meth:`from_mapping`; every
    later stage passes this value around and asks it (:meth:`from_mapping` of a Modulator is
    the value itself). It is also a read-only mapping ``{"type": kind, **settings}``, for
    code written for the mapping form. ``label`` is the one name used in run ids, file
    names, tables, legends and the report.

    Parameters
    ----------
    kind : str
        Modulator type, a registered kind (:data:`MODULATOR_ORDER`).
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
    def spec(self) -> Any:
        """The kind (:class:`~spa.model.modulators.base.ModulatorKind`) of this setting."""
        return get_kind(self.kind)

    @property
    def parameter(self) -> str:
        """Name of the characteristic setting: ``f_w``, ``t_h``, ``t_l`` or ``period``."""
        return self.spec.parameter

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
        """Display name of the type: PWM, IPFM, IIPFM, ΔΣM or LPWM."""
        return self.spec.name

    @property
    def colour(self) -> str:
        """Colour of the type in every figure."""
        return self.spec.colour

    @property
    def label(self) -> str:
        """Short file-safe name, e.g. ``pwm-20Hz``, ``ipfm-20ms``, ``iipfm-20ms-G1.15``."""
        return self.spec.label(self.settings)

    @property
    def description(self) -> str:
        """Human description, e.g. ``PWM, f_W = 20 Hz`` or ``IIPFM, t_l = 20 ms, G = 1.15``."""
        return self.spec.description(self.settings)

    @property
    def sort_key(self) -> tuple[float, float, float]:
        """Numeric order: by type (PWM, IPFM, IIPFM, ΔΣM, …), then setting value, then gain."""
        return (MODULATOR_ORDER.index(self.kind), self.value, self.gain)

    def bind(self, params: Any) -> Modulator:
        """This setting with what it takes from the valve ``params`` filled in (LPWM's
        inverted valve); the same value for kinds that do not use the valve."""
        full = self.spec.bind(self.settings, params)
        return self if full == dict(self.settings) else Modulator(self.kind, full)

    # A read-only mapping ``{"type": kind, **settings}``, so that code written for the mapping
    # form (a run's metadata, a RunSpec) takes the value as it is, without parsing it again.
    def __getitem__(self, key: str) -> Any:
        return self.kind if key == "type" else self.settings[key]

    def __iter__(self) -> Iterator[str]:
        return iter(("type", *self.settings))

    def __len__(self) -> int:
        return 1 + len(self.settings)

    def __lt__(self, other: Modulator) -> bool:
        return self.sort_key < other.sort_key

    def modulate(self, xi: npt.ArrayLike, dt: float) -> npt.NDArray[np.int8]:
        """:func:`modulate` with this setting."""
        return modulate(self.kind, xi, dt, **self.settings)


def modulate(kind: str, xi: npt.ArrayLike, dt: float, **settings: float) -> npt.NDArray[np.int8]:
    """Turn an input fraction into a 0/1 valve command with a digital pulse modulator.

    Parameters
    ----------
    kind : str
        A registered kind. ``"pwm"``: pulse-width modulation at ``f_w`` Hz; ``xi`` is
        sampled at the start of each period and the output is high for ``xi/f_w`` of it.
        ``"ipfm"``: integral pulse-frequency modulation; an integrator of ``xi`` fires a high
        pulse of width ``t_h`` s when it reaches ``gain*t_h`` and subtracts that threshold.
        ``"iipfm"``: inverse IPFM; high by default, an integrator of ``1 - xi`` fires a low
        pulse of width ``t_l`` s when it reaches ``gain*t_l``.
        ``"dsm"``: first-order ΔΣ clocked every ``period`` s:
        ``v_k = v_{k-1} + xi_k - u_{k-1}``, ``u_k = [v_k >= 1/2]``, from ``v = u = 0``.
        ``"lpwm"``: PWM at ``f_w`` whose duty inverts the averaged equilibrium of a valve
        (its settings ``c1``, ``k2``, ``tau2``, ``t_on``, ``t_off``; nominal if not given).
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
    return get_kind(kind).pulse(x, dt, s)


def settings_arrays(kind: str, settings: Mapping[str, Any]) -> dict[str, Any]:
    """Validate settings like :func:`spa.model.modulators.check_settings`, allowing arrays.

    Scalar settings go through ``check_settings`` unchanged (same messages); array-valued
    ones must be finite and > 0 everywhere.
    """
    scalars: dict[str, Any] = {}
    arrays: dict[str, npt.NDArray[np.float64]] = {}
    for name, value in settings.items():
        if np.ndim(value) == 0:
            scalars[name] = value
        else:
            arrays[name] = checks.positive_array(f"{kind}: setting {name!r}", value)
    out: dict[str, Any] = check_settings(kind, **scalars, **dict.fromkeys(arrays, 1.0))
    out.update(arrays)
    return out
