"""The physical test plant's settings and constants (:class:`PhysicalPlant`), shared by the
numba kernels (:mod:`spa.synthetic.physical`) and the C twin's harness
(:mod:`spa.synthetic._physical_c`)."""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import asdict, dataclass, fields
from typing import Any

import numpy as np

#: Air: specific gas constant, J/(kg*K).
R_AIR = 287.05
#: ISO 8778 reference atmosphere (ANR): density at 20 degC and 100 kPa, kg/m^3.
RHO0 = 1.185
#: Pressure ratio above which the ISO 6358 law is continued linearly to zero flow at r = 1.
LAMINAR_RATIO = 0.999
#: Longest pending-edge queue (dead time / controller step + 2).
QUEUE = 4096

# dm^3/(s*bar) -> m^3/(s*Pa); cm^3 -> m^3; bar -> Pa
_DM3_PER_S_BAR = 1e-3 / 1e5
_CM3 = 1e-6
_BAR = 1e5


@dataclass(frozen=True)
class PhysicalPlant:
    """A 3/2 solenoid valve, a soft chamber, a regulator and a sensor: every setting in SI-like
    bench units (config keys of the same names, ``plant: {kind: physical, ...}``).

    Parameters
    ----------
    supply : float
        Regulator set-point, bar gauge, in (0.05, 12].
    c_supply, c_exhaust : float
        ISO 6358 sonic conductance of the supply (P->A) and exhaust (A->R) ports,
        dm³/(s·bar) (ANR), in (0, 50].
    b_supply, b_exhaust : float
        Critical pressure ratios, in [0, 0.95].
    m_supply, m_exhaust : float
        Subsonic indices, in (0, 1] (0.5: the classic elliptic law).
    volume : float
        Chamber volume at 0 bar gauge, cm³, in (0.1, 1e5].
    compliance : float
        Volume growth per bar gauge, cm³/bar, in [0, 1e5] (linear).
    polytropic : float
        Polytropic index ``n`` of the chamber, in [1, 1.4] (1: isothermal, 1.4: adiabatic).
    t_open, t_close : float
        Armature dead time after a rising / falling command edge, s, in [0, 0.1]: the
        previous connection persists meanwhile.
    transit : float
        Spool transit time, s, in (0, 0.01]: the effective conductances change linearly.
    droop : float
        Regulator sag per flow drawn, bar per (NL/s) (normal litres per second), in [0, 100].
    regulator_tau : float
        Regulator time constant, s, in [1e-4, 1].
    sensor_lag : float
        Sensor time constant (first order), s, in [0, 0.1] (0: none).
    noise : float
        Sensor noise standard deviation, bar, in [0, 1].
    quantum : float
        ADC step, bar, in [0, 1] (0: none).
    mains : float
        Amplitude of the mains pickup, bar, in [0, 1].
    mains_frequency : float
        Mains frequency, Hz, in (0, 1000] (50 in Europe).
    mains_phase : float
        Phase of the pickup at t = 0, rad, in [-2π, 2π].
    atmosphere : float
        Atmospheric pressure, bar absolute, in [0.5, 1.2].
    temperature : float
        Supply air temperature ``T0``, K, in [200, 400].
    leak : float
        Chamber leak to atmosphere, a laminar conductance in dm³/(s·bar) (ANR), in [0, 50]
        (0: none): mass flow ``leak*rho0*(P - p_atm)``.
    heat_tau : float
        Wall heat exchange, s, in [0, 100] (0: none, the polytropic chamber). When set the
        chamber is a thermal state: the gas temperature ``T`` follows the energy balance
        with ``polytropic`` as the ratio of specific heats, air entering at ``T0``, leaving
        at ``T``, and exchanging ``m*cv*(T0 - T)/heat_tau`` with the wall.
    creep, creep_tau : float
        Viscoelastic chamber: an extra volume ``Vc`` creeping towards ``creep*(P - p_atm)``
        (cm³/bar, in [0, 1e5]) with time constant ``creep_tau`` (s, in [0, 1000]; needed
        when ``creep > 0``) after each change of pressure.
    tube_tau : float
        Connecting tube between the chamber and the sensor, s, in [0, 0.5] (0: none): the
        sensor's port follows the chamber's pressure through a first-order pneumatic lag,
        ahead of the sensor's own lag.
    hose_volume, c_line : float
        Supply hose behind a line conductance: a volume (cm³, in [0, 1e5]; 0: none) fed by
        the regulator through an ISO 6358 conductance ``c_line`` (dm³/(s·bar), in [0, 50];
        needed when ``hose_volume > 0``; ``b = 0.3``, ``m = 0.5``), from which the valve
        draws.
    bounce, bounce_time : float
        Valve bounce: when the spool reaches its end stop it rebounds by ``bounce`` of its
        stroke (in [0, 0.5]), decaying as ``exp(-t/bounce_time)*|sin(pi*t/bounce_time)|``
        (``bounce_time`` s, in [0, 0.01]; needed when ``bounce > 0``).

    Raises
    ------
    ValueError
        Naming the field and its range, for a value out of range or not a number.

    Examples
    --------
    >>> PhysicalPlant(supply=4.0).supply
    4.0
    >>> PhysicalPlant(b_supply=1.0)
    Traceback (most recent call last):
    ...
    ValueError: PhysicalPlant.b_supply = 1.0: must be in [0, 0.95] (critical pressure ratio)
    """

    supply: float = 0.85
    c_supply: float = 0.04
    b_supply: float = 0.3
    m_supply: float = 0.5
    c_exhaust: float = 0.05
    b_exhaust: float = 0.3
    m_exhaust: float = 0.5
    volume: float = 20.0
    compliance: float = 12.0
    polytropic: float = 1.2
    t_open: float = 0.004
    t_close: float = 0.006
    transit: float = 0.0015
    droop: float = 0.2
    regulator_tau: float = 0.02
    sensor_lag: float = 0.002
    noise: float = 0.003
    quantum: float = 0.001
    mains: float = 0.002
    mains_frequency: float = 50.0
    mains_phase: float = 0.0
    atmosphere: float = 1.01325
    temperature: float = 293.15
    leak: float = 0.0
    heat_tau: float = 0.0
    creep: float = 0.0
    creep_tau: float = 0.0
    tube_tau: float = 0.0
    hose_volume: float = 0.0
    c_line: float = 0.0
    bounce: float = 0.0
    bounce_time: float = 0.0

    def __post_init__(self) -> None:
        for f in fields(self):
            value = getattr(self, f.name)
            lo, hi, lo_open, what = _RANGES[f.name]
            if isinstance(value, bool) or not isinstance(value, int | float | np.number):
                raise ValueError(f"PhysicalPlant.{f.name} must be a number ({what}), got {value!r}")
            v = float(value)
            ok = math.isfinite(v) and (v > lo if lo_open else v >= lo) and v <= hi
            if not ok:
                bra = "(" if lo_open else "["
                raise ValueError(
                    f"PhysicalPlant.{f.name} = {value!r}: must be in {bra}{lo:g}, {hi:g}] ({what})"
                )
            object.__setattr__(self, f.name, v)
        for amount, scale in (
            ("creep", "creep_tau"),
            ("hose_volume", "c_line"),
            ("bounce", "bounce_time"),
        ):
            if getattr(self, amount) > 0.0 and not getattr(self, scale) > 0.0:
                raise ValueError(
                    f"PhysicalPlant.{scale} must be > 0 when {amount} = {getattr(self, amount)!r}"
                )

    @classmethod
    def from_mapping(cls, cfg: Mapping[str, Any]) -> PhysicalPlant:
        """From a config mapping (``kind: physical`` allowed and dropped); unknown keys are
        refused by name."""
        d = dict(cfg)
        kind = d.pop("kind", "physical")
        if kind != "physical":
            raise ValueError(f"plant.kind = {kind!r}: only 'physical' is known")
        unknown = sorted(set(d) - set(PHYSICAL_KEYS))
        if unknown:
            raise ValueError(f"plant: unknown key(s) {unknown}; allowed: {list(PHYSICAL_KEYS)}")
        return cls(**d)

    def to_mapping(self) -> dict[str, Any]:
        """The config mapping (``kind: physical`` and every field)."""
        return {"kind": "physical", **asdict(self)}


#: field -> (lower bound, upper bound, lower bound open, what it is with its unit)
_RANGES: dict[str, tuple[float, float, bool, str]] = {
    "supply": (0.05, 12.0, True, "regulator set-point, bar gauge"),
    "c_supply": (0.0, 50.0, True, "sonic conductance, dm^3/(s*bar)"),
    "b_supply": (0.0, 0.95, False, "critical pressure ratio"),
    "m_supply": (0.0, 1.0, True, "subsonic index"),
    "c_exhaust": (0.0, 50.0, True, "sonic conductance, dm^3/(s*bar)"),
    "b_exhaust": (0.0, 0.95, False, "critical pressure ratio"),
    "m_exhaust": (0.0, 1.0, True, "subsonic index"),
    "volume": (0.1, 1e5, True, "chamber volume at 0 bar gauge, cm^3"),
    "compliance": (0.0, 1e5, False, "volume growth, cm^3/bar"),
    "polytropic": (1.0, 1.4, False, "polytropic index"),
    "t_open": (0.0, 0.1, False, "opening dead time, s"),
    "t_close": (0.0, 0.1, False, "closing dead time, s"),
    "transit": (0.0, 0.01, True, "spool transit time, s"),
    "droop": (0.0, 100.0, False, "regulator sag, bar/(NL/s)"),
    "regulator_tau": (1e-4, 1.0, False, "regulator time constant, s"),
    "sensor_lag": (0.0, 0.1, False, "sensor time constant, s"),
    "noise": (0.0, 1.0, False, "noise standard deviation, bar"),
    "quantum": (0.0, 1.0, False, "ADC step, bar"),
    "mains": (0.0, 1.0, False, "mains pickup amplitude, bar"),
    "mains_frequency": (0.0, 1000.0, True, "mains frequency, Hz"),
    "mains_phase": (-2 * math.pi, 2 * math.pi, False, "mains phase, rad"),
    "atmosphere": (0.5, 1.2, False, "atmospheric pressure, bar absolute"),
    "temperature": (200.0, 400.0, False, "supply air temperature, K"),
    "leak": (0.0, 50.0, False, "chamber leak, dm^3/(s*bar)"),
    "heat_tau": (0.0, 100.0, False, "wall heat exchange time constant, s"),
    "creep": (0.0, 1e5, False, "creeping volume, cm^3/bar"),
    "creep_tau": (0.0, 1000.0, False, "creep time constant, s"),
    "tube_tau": (0.0, 0.5, False, "sensor tube time constant, s"),
    "hose_volume": (0.0, 1e5, False, "supply hose volume, cm^3"),
    "c_line": (0.0, 50.0, False, "line conductance, dm^3/(s*bar)"),
    "bounce": (0.0, 0.5, False, "valve bounce, fraction of the stroke"),
    "bounce_time": (0.0, 0.01, False, "valve bounce time, s"),
}

#: The settings of a physical plant (config keys), in order.
PHYSICAL_KEYS = tuple(f.name for f in fields(PhysicalPlant))

# ---- the constants the kernels read ---------------------------------------------------

#: Index of each constant in the array the kernels (Python, numba, C) read.
_C = (
    "p_atm",  # Pa abs
    "p_set",  # Pa abs
    "n",  # polytropic index
    "rt",  # R*T0, J/kg
    "rho0",  # kg/m^3
    "cs",  # m^3/(s*Pa)
    "bs",
    "ms",
    "ce",  # m^3/(s*Pa)
    "be",
    "me",
    "v0",  # m^3
    "kv",  # m^3/Pa
    "droop",  # Pa per m^3/s (ANR)
    "tau_r",  # s
    "tau_s",  # s (0: no lag)
    "transit",  # s
    "t_open",  # s
    "t_close",  # s
    "blam",  # laminar ratio
    "leak",  # m^3/(s*Pa) (0: none)
    "heat_tau",  # s (0: polytropic chamber)
    "creep",  # m^3/Pa
    "creep_tau",  # s
    "tube_tau",  # s (0: none)
    "hose_v",  # m^3 (0: none)
    "c_line",  # m^3/(s*Pa)
    "bounce",  # fraction of the stroke
    "bounce_time",  # s
    "t0",  # K
)
N_CONST = len(_C)


def _constants(plant: PhysicalPlant) -> np.ndarray:
    """The plant's constants in SI, in the order of ``_C`` (the C twin's order too)."""
    patm = plant.atmosphere * _BAR
    return np.array(
        [
            patm,
            patm + plant.supply * _BAR,
            plant.polytropic,
            R_AIR * plant.temperature,
            RHO0,
            plant.c_supply * _DM3_PER_S_BAR,
            plant.b_supply,
            plant.m_supply,
            plant.c_exhaust * _DM3_PER_S_BAR,
            plant.b_exhaust,
            plant.m_exhaust,
            plant.volume * _CM3,
            plant.compliance * _CM3 / _BAR,
            plant.droop * _BAR / 1e-3,
            plant.regulator_tau,
            plant.sensor_lag,
            plant.transit,
            plant.t_open,
            plant.t_close,
            LAMINAR_RATIO,
            plant.leak * _DM3_PER_S_BAR,
            plant.heat_tau,
            plant.creep * _CM3 / _BAR,
            plant.creep_tau,
            plant.tube_tau,
            plant.hose_volume * _CM3,
            plant.c_line * _DM3_PER_S_BAR,
            plant.bounce,
            plant.bounce_time,
            plant.temperature,
        ],
        dtype=np.float64,
    )


def substeps(plant: PhysicalPlant, dt: float) -> int:
    """Runge-Kutta sub-steps per controller step ``dt``: the step ``h = dt/n`` is at most
    the fastest time constant of the linearised plant and at most 0.1 ms (a spool transit
    spans several steps).

    The fastest rate is the chamber's at equilibrium with the larger port (the laminar
    slope ``C*rho0*phi(0.999)/0.001``), the regulator's ``1/tau_r`` and the sensor's
    ``1/tau_s``.

    Examples
    --------
    >>> substeps(PhysicalPlant(), 0.001)
    10
    """
    c = _constants(plant)
    lam = 0.0
    for cc, b, m in ((c[5], c[6], c[7]), (c[8], c[9], c[10])):
        phi = (1.0 - ((LAMINAR_RATIO - b) / (1.0 - b)) ** 2) ** m
        slope = cc * RHO0 * phi / (1.0 - LAMINAR_RATIO)
        lam = max(lam, c[2] * c[3] * slope / c[11])
    lam = max(lam, 1.0 / plant.regulator_tau)
    if plant.sensor_lag > 0:
        lam = max(lam, 1.0 / plant.sensor_lag)
    if plant.tube_tau > 0:
        lam = max(lam, 1.0 / plant.tube_tau)
    if plant.hose_volume > 0:
        phi = (1.0 - ((LAMINAR_RATIO - 0.3) / 0.7) ** 2) ** 0.5
        slope = c[26] * RHO0 * phi / (1.0 - LAMINAR_RATIO)
        lam = max(lam, c[3] * slope / c[25])
    if plant.bounce > 0:
        lam = max(lam, 10.0 / plant.bounce_time)
    return max(math.ceil(dt * lam - 1e-9), math.ceil(dt / 1e-4 - 1e-9), 1)


def _check_dt(plant: PhysicalPlant, dt: float) -> float:
    dt = float(dt)
    if not (math.isfinite(dt) and 1e-5 <= dt <= 0.1):
        raise ValueError(f"dt = {dt!r} s: the controller step must be in [1e-5, 0.1] s")
    if max(plant.t_open, plant.t_close) / dt + 2 > QUEUE:
        raise ValueError(
            f"dt = {dt:g} s: the dead times ({plant.t_open:g}, {plant.t_close:g} s) span more "
            f"than {QUEUE - 2} controller steps"
        )
    return dt
