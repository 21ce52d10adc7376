"""Simulated bench datasets: input signals, a sensor model and the paper's experiments.

A simulated run goes through exactly what a bench run goes through: an input fraction, a
digital modulator clocked at the controller step, the valve + actuator (exact, from
:func:`spa.simulate`), and a pressure sensor logged at its own rate with noise, ADC
quantisation and optionally the short damped ringing the paper saw after each valve edge.
The result is the canonical run table (``t`` s, ``p`` bar, ``valve`` 0/1, ``u`` 0–1).
"""

from __future__ import annotations

import math
import zlib
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt
import pandas as pd

from spa.model.modulators import modulate, parse_modulator
from spa.model.params import ValveParams
from spa.model.plant import simulate

__all__ = [
    "EXAMPLE_PARAMS",
    "Ringing",
    "RunSpec",
    "Sensor",
    "chirp_input",
    "dataset_runs",
    "generate_dataset",
    "identification_runs",
    "modulated_runs",
    "run_seed",
    "setting_label",
    "simulate_run",
    "sine_input",
    "staircase_input",
    "write_example_dataset",
]


# ---- input signals ----------------------------------------------------------------------


def staircase_input(t: npt.ArrayLike, step: float = 0.1, hold: float = 5.0) -> np.ndarray:
    """Staircase of the input fraction: 0, ``step``, 2*``step``, ... held ``hold`` s each, up to 1.

    Parameters
    ----------
    t : array_like
        Times in s, from 0.
    step : float
        Increment of the input fraction per level (paper: 0.1).
    hold : float
        Duration of each level in s (paper: 5 s).

    Returns
    -------
    numpy.ndarray
        ``min(floor(t/hold)*step, 1)``.

    Examples
    --------
    >>> staircase_input([0.0, 4.9, 5.0, 12.0, 99.0]).tolist()
    [0.0, 0.0, 0.1, 0.2, 1.0]
    """
    if not (step > 0 and hold > 0):
        raise ValueError(f"step and hold must be > 0, got step={step!r}, hold={hold!r}")
    t = np.asarray(t, dtype=np.float64)
    level = np.floor(t / hold + 1e-9)
    return np.minimum(np.round(level * step, 12), 1.0)


def sine_input(
    t: npt.ArrayLike,
    frequency: float,
    amplitudes: Sequence[float],
    periods_per_level: int = 2,
    offset: float = 0.5,
) -> np.ndarray:
    """Fixed-frequency sine whose amplitude decreases piece-wise (Fig. 8's input).

    Level ``i`` lasts ``periods_per_level`` whole periods with amplitude ``amplitudes[i]``;
    after the last level the input stays at ``offset``.

    Parameters
    ----------
    t : array_like
        Times in s, from 0.
    frequency : float
        Sine frequency in Hz.
    amplitudes : sequence of float
        Amplitude of each level (input-fraction units), e.g. ``[0.5, 0.4, 0.3, 0.2, 0.1]``.
    periods_per_level : int
        Whole periods per amplitude level.
    offset : float
        Mean input fraction.

    Returns
    -------
    numpy.ndarray
        ``offset + A(t) * sin(2*pi*frequency*t)``.
    """
    if frequency <= 0 or periods_per_level < 1 or not amplitudes:
        raise ValueError("frequency must be > 0, periods_per_level >= 1, amplitudes non-empty")
    t = np.asarray(t, dtype=np.float64)
    level = np.floor(t * frequency / periods_per_level + 1e-9).astype(np.int64)
    amp = np.asarray([*amplitudes, 0.0], dtype=np.float64)
    a = amp[np.minimum(level, len(amplitudes))]
    return offset + a * np.sin(2 * np.pi * frequency * t)


def chirp_input(
    t: npt.ArrayLike,
    f0: float = 0.1,
    f1: float = 100.0,
    duration: float | None = None,
    offset: float = 0.5,
    amplitude: float = 0.25,
) -> np.ndarray:
    """Linear chirp of the input fraction (Fig. 9's input: 0.1 to 100 Hz, 0.5 ± 0.25).

    Parameters
    ----------
    t : array_like
        Times in s, from 0.
    f0, f1 : float
        Start and end frequencies in Hz.
    duration : float, optional
        Sweep time in s (default: the span of ``t``).
    offset, amplitude : float
        Mean and amplitude of the input fraction.

    Returns
    -------
    numpy.ndarray
        ``offset + amplitude * sin(2*pi*(f0*t + (f1 - f0)*t**2/(2*duration)))``.
    """
    t = np.asarray(t, dtype=np.float64)
    if duration is None:
        duration = float(t[-1]) if t.size > 1 else 1.0
    if f0 < 0 or f1 <= 0 or duration <= 0:
        raise ValueError("need f0 >= 0, f1 > 0 and duration > 0")
    phase = 2 * np.pi * (f0 * t + (f1 - f0) * t**2 / (2 * duration))
    return offset + amplitude * np.sin(phase)


# ---- sensor -----------------------------------------------------------------------------


@dataclass(frozen=True)
class Ringing:
    """Damped oscillation added to the pressure after each valve edge.

    ``amplitude * exp(-damping*s) * sin(2*pi*frequency*s)`` at time ``s`` after the most
    recent edge, positive after an opening edge and negative after a closing one.
    """

    amplitude: float = 0.01  # bar
    frequency: float = 60.0  # Hz
    damping: float = 60.0  # 1/s


@dataclass(frozen=True)
class Sensor:
    """Pressure sensor and logger.

    Parameters
    ----------
    fs : float
        Logging rate in Hz; ``1/fs`` must be a whole number of controller steps.
    noise : float
        Standard deviation of additive Gaussian noise, bar.
    quantum : float
        ADC step, bar (0: none).
    ringing : Ringing, optional
        Damped ringing after each valve edge.
    """

    fs: float = 1000.0
    noise: float = 0.005
    quantum: float = 0.001
    ringing: Ringing | None = None

    @classmethod
    def from_mapping(cls, cfg: Mapping[str, Any] | None) -> Sensor:
        """Build from a config mapping (``fs``, ``noise``, ``quantum``, ``ringing``)."""
        cfg = dict(cfg or {})
        ring = cfg.pop("ringing", None)
        return cls(**cfg, ringing=Ringing(**ring) if ring else None)


def _ringing(t: np.ndarray, edge_t: np.ndarray, edge_sign: np.ndarray, r: Ringing) -> np.ndarray:
    out = np.zeros_like(t)
    if edge_t.size == 0:
        return out
    j = np.searchsorted(edge_t, t, side="right") - 1
    has = j >= 0
    s = t[has] - edge_t[j[has]]
    out[has] = (
        edge_sign[j[has]]
        * r.amplitude
        * np.exp(-r.damping * s)
        * np.sin(2 * np.pi * r.frequency * s)
    )
    return out


# ---- runs -------------------------------------------------------------------------------


@dataclass(frozen=True)
class RunSpec:
    """One simulated run: what the controller commands.

    Either a fixed valve command (``valve``; identification experiments) or an input
    fraction (``xi``) through ``modulator`` (``{"type": ..., settings}``).
    """

    id: str
    kind: str
    p0: float = 0.0
    valve: np.ndarray | None = None
    xi: np.ndarray | None = None
    modulator: Mapping[str, Any] | None = None
    notes: str = ""
    meta: dict[str, Any] = field(default_factory=dict)


def run_seed(seed: int, dataset: str, run_id: str) -> np.random.Generator:
    """A Generator seeded from the config seed, dataset name and run id (stable across runs)."""
    return np.random.default_rng([seed, zlib.crc32(dataset.encode()), zlib.crc32(run_id.encode())])


def simulate_run(
    spec: RunSpec,
    params: ValveParams,
    dt: float,
    sensor: Sensor,
    rng: np.random.Generator,
) -> pd.DataFrame:
    """Simulate one run and log it through the sensor: the canonical run table.

    Parameters
    ----------
    spec : RunSpec
        The command: a valve sequence at step ``dt``, or an input fraction and a modulator.
    params : ValveParams
        The true valve + actuator.
    dt : float
        Controller step in s (the modulator clock and the resolution of valve edges).
    sensor : Sensor
        Logging rate, noise, quantisation, ringing.
    rng : numpy.random.Generator
        Source of the sensor noise.

    Returns
    -------
    pandas.DataFrame
        ``t`` (s), ``p`` (bar), ``valve`` (int8) and, for modulated runs, ``u`` (input
        fraction), one row per logged sample. ``valve`` is the command at each sample
        instant.
    """
    ratio = 1.0 / (sensor.fs * dt)
    every = round(ratio)
    if every < 1 or abs(ratio - every) > 1e-6:
        raise ValueError(
            f"sensor.fs = {sensor.fs:g} Hz: 1/fs must be a whole number of controller steps "
            f"dt = {dt:g} s"
        )
    if spec.valve is not None:
        u = np.asarray(spec.valve, dtype=np.int8)
        xi = None
    elif spec.xi is not None and spec.modulator is not None:
        mod = dict(spec.modulator)
        kind = mod.pop("type")
        xi = np.asarray(spec.xi, dtype=np.float64)
        u = modulate(kind, xi, dt, **mod)
    else:
        raise ValueError(f"run {spec.id!r}: give either valve, or xi and modulator")
    p = simulate(u, dt, params, p0=spec.p0)
    idx = np.arange(0, u.size, every)
    t = idx * dt
    logged = p[idx]
    if sensor.ringing is not None:
        edges = np.flatnonzero(np.diff(u)) + 1
        sign = np.where(u[edges] == 1, 1.0, -1.0)
        logged = logged + _ringing(t, edges * dt, sign, sensor.ringing)
    if sensor.noise > 0:
        logged = logged + rng.normal(0.0, sensor.noise, logged.size)
    if sensor.quantum > 0:
        logged = np.round(logged / sensor.quantum) * sensor.quantum
    table = {"t": t, "p": logged, "valve": u[idx]}
    if xi is not None:
        table["u"] = np.clip(xi[idx], 0.0, 1.0)
    return pd.DataFrame(table)


def identification_runs(
    params: ValveParams,
    dt: float,
    charge_time: float = 6.0,
    discharge_time: float = 4.0,
    low_times: Sequence[float] = (0.005, 0.010, 0.015, 0.020, 0.050, 0.100, 0.200),
    high_time: float = 0.300,
    repeats: int = 3,
) -> list[RunSpec]:
    """The paper's three identification experiments (Section 3.2) as valve commands.

    Parameters
    ----------
    params : ValveParams
        Used for the supply pressure ``k2`` (the discharge starts there).
    dt : float
        Controller step, s.
    charge_time : float
        Experiment 1: valve open from 0 bar for this long (several ``tau2``).
    discharge_time : float
        Experiment 2: valve closed from the supply pressure for this long.
    low_times : sequence of float
        Experiment 3: the low-state durations of the pulse train, s.
    high_time : float
        Experiment 3: the high-state duration between lows, s.
    repeats : int
        How many times the sequence of low durations is repeated.

    Returns
    -------
    list of RunSpec
        ``charge``, ``discharge`` and ``pulse`` runs.
    """
    n_charge = round(charge_time / dt)
    n_dis = round(discharge_time / dt)
    charge = RunSpec("charge", "charge", p0=0.0, valve=np.ones(n_charge, dtype=np.int8))
    discharge = RunSpec("discharge", "discharge", p0=params.k2, valve=np.zeros(n_dis, np.int8))
    # pulse train: start low, open for high_time, close for each low duration in turn
    pieces = [np.zeros(round(0.2 / dt), np.int8)]
    for _ in range(repeats):
        for low in low_times:
            pieces.append(np.ones(round(high_time / dt), np.int8))
            pieces.append(np.zeros(round(low / dt), np.int8))
    pieces.append(np.ones(round(high_time / dt), np.int8))
    pieces.append(np.zeros(round(0.5 / dt), np.int8))
    pulse = RunSpec(
        "pulse",
        "pulse",
        p0=0.0,
        valve=np.concatenate(pieces),
        notes=f"low durations {list(low_times)} s, high {high_time} s, x{repeats}",
    )
    return [charge, discharge, pulse]


def setting_label(mod: Mapping[str, Any]) -> str:
    """Short file-safe name of a modulator setting, used in run ids.

    Examples
    --------
    >>> setting_label({"type": "pwm", "f_w": 20})
    'pwm-20Hz'
    >>> setting_label({"type": "iipfm", "t_l": 0.02, "gain": 1.15})
    'iipfm-20ms-G1.15'
    """
    kind, s = parse_modulator(mod)
    if kind == "pwm":
        return f"pwm-{s['f_w']:g}Hz"
    name = {"ipfm": "t_h", "iipfm": "t_l", "dsm": "period"}[kind]
    label = f"{kind}-{s[name] * 1e3:g}ms"
    if kind in ("ipfm", "iipfm") and not math.isclose(s["gain"], 1.0):
        label += f"-G{s['gain']:g}"
    return label


def modulated_runs(
    modulators: Sequence[Mapping[str, Any]],
    dt: float,
    experiments: Mapping[str, Mapping[str, Any]],
) -> list[RunSpec]:
    """Staircase, sine and chirp runs for every modulator setting.

    Parameters
    ----------
    modulators : sequence of mapping
        ``{"type": "pwm", "f_w": 20}`` and the like.
    dt : float
        Controller step, s.
    experiments : mapping
        ``staircase: {step, hold}``, ``sine: {frequency, amplitudes, periods_per_level,
        offset, settle}``, ``chirp: {f0, f1, duration, offset, amplitude}``; a missing key
        skips that experiment.

    Returns
    -------
    list of RunSpec
        Run ids ``<kind>_<setting label>``, e.g. ``staircase_pwm-20Hz``.
    """
    runs: list[RunSpec] = []
    for mod in modulators:
        label = setting_label(mod)
        if "staircase" in experiments:
            cfg = experiments["staircase"]
            step, hold = float(cfg["step"]), float(cfg["hold"])
            levels = math.floor(1.0 / step + 1e-9) + 1
            t = np.arange(round(levels * hold / dt)) * dt
            runs.append(
                RunSpec(
                    f"staircase_{label}",
                    "staircase",
                    xi=staircase_input(t, step, hold),
                    modulator=dict(mod),
                )
            )
        if "sine" in experiments:
            cfg = dict(experiments["sine"])
            settle = float(cfg.pop("settle", 0.0))
            f = float(cfg["frequency"])
            n_levels = len(cfg["amplitudes"])
            span = n_levels * int(cfg.get("periods_per_level", 2)) / f
            t = np.arange(round((settle + span) / dt)) * dt
            tt = np.maximum(t - settle, 0.0)
            xi = sine_input(tt, **cfg)
            xi[t < settle] = float(cfg.get("offset", 0.5))
            runs.append(
                RunSpec(
                    f"sine_{label}",
                    "sine",
                    xi=xi,
                    modulator=dict(mod),
                    meta={"settle": settle, **cfg},
                )
            )
        if "chirp" in experiments:
            cfg = dict(experiments["chirp"])
            duration = float(cfg["duration"])
            t = np.arange(round(duration / dt)) * dt
            runs.append(
                RunSpec(
                    f"chirp_{label}",
                    "chirp",
                    xi=chirp_input(t, **cfg),
                    modulator=dict(mod),
                    meta=cfg,
                )
            )
    return runs


# ---- whole datasets -----------------------------------------------------------------------


def dataset_runs(
    cfg: Mapping[str, Any], experiments: Mapping[str, Mapping[str, Any]]
) -> list[RunSpec]:
    """Every run of a simulated dataset: the identification experiments, then per modulator.

    Parameters
    ----------
    cfg : mapping
        One entry of the config's ``simulated:`` (``params``, ``controller_dt``, ``sensor``,
        ``modulators``).
    experiments : mapping
        The config's ``experiments:`` (``identification``, ``staircase``, ``sine``, ``chirp``).
    """
    params = ValveParams(**cfg["params"])
    dt = float(cfg["controller_dt"])
    ident = dict(experiments.get("identification", {}))
    runs = identification_runs(params, dt, **ident)
    modulated = {k: v for k, v in experiments.items() if k in ("staircase", "sine", "chirp")}
    return runs + modulated_runs(cfg["modulators"], dt, modulated)


def generate_dataset(
    name: str,
    cfg: Mapping[str, Any],
    experiments: Mapping[str, Mapping[str, Any]],
    seed: int,
    out_dir: str | Path,
    progress: Callable[[str], None] | None = None,
) -> list[Path]:
    """Simulate a whole dataset and write one canonical run table per run.

    Parameters
    ----------
    name : str
        Dataset name (the folder under ``results/``).
    cfg, experiments : mapping
        See :func:`dataset_runs`.
    seed : int
        Config seed; each run's noise comes from :func:`run_seed` (seed, name, run id), so a
        run's bytes do not depend on which other runs are configured.
    out_dir : path-like
        Folder for ``<run id>.parquet``.
    progress : callable, optional
        Called with a line of text after each run.

    Returns
    -------
    list of pathlib.Path
        The run tables written.
    """
    from spa.datasets import write_run_table

    params = ValveParams(**cfg["params"])
    dt = float(cfg["controller_dt"])
    sensor = Sensor.from_mapping(cfg.get("sensor"))
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    paths = []
    for spec in dataset_runs(cfg, experiments):
        table = simulate_run(spec, params, dt, sensor, run_seed(seed, name, spec.id))
        meta = {
            "dataset": name,
            "run": spec.id,
            "kind": spec.kind,
            "origin": "synthetic",
            "modulator": dict(spec.modulator) if spec.modulator else None,
            "notes": spec.notes,
            "description": str(cfg.get("description", "")),
            "truth": params.as_dict(),
            "controller_dt": dt,
            "sensor": dict(cfg.get("sensor") or {}),
            "seed": int(seed),
            "experiment": {k: v for k, v in spec.meta.items()},
        }
        path = out / f"{spec.id}.parquet"
        write_run_table(path, table, meta)
        paths.append(path)
        if progress is not None:
            progress(f"{name}/{spec.id}: {len(table)} samples, {spec.kind}")
    return paths


#: The example bench export shipped in ``raw/example`` (see :func:`write_example_dataset`).
EXAMPLE_PARAMS = ValveParams(c1=0.45, k2=1.05, tau2=0.70, t_on=0.004, t_off=0.009)


def write_example_dataset(folder: str | Path, seed: int = 2025) -> list[Path]:
    """Write a small synthetic dataset laid out the way a real bench export would be.

    It imitates a dSpace/MATLAB bench: identification runs as CSV with time in ms, pressure
    in kPa and the logger's own column names; one staircase as a MATLAB ``.mat`` file; one as
    Parquet; and the ``dataset.yaml`` that maps it all onto the contract. The valve is not
    the paper's (:data:`EXAMPLE_PARAMS`), so identification has something to find.

    Parameters
    ----------
    folder : path-like
        Destination, normally ``raw/example`` (created; existing files are overwritten).
    seed : int
        Noise seed.

    Returns
    -------
    list of pathlib.Path
        The files written.
    """
    import scipy.io
    import yaml

    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    name = folder.name
    dt = 1e-3
    sensor = Sensor(fs=1000.0, noise=0.004, quantum=0.001, ringing=Ringing(0.008, 70.0, 70.0))
    specs = identification_runs(EXAMPLE_PARAMS, dt, repeats=2)
    specs += modulated_runs(
        [{"type": "iipfm", "t_l": 0.020, "gain": 1.2}, {"type": "pwm", "f_w": 20.0}],
        dt,
        {"staircase": {"step": 0.1, "hold": 4.0}},
    )
    rename = {"t": "time_ms", "p": "P_act_kPa", "valve": "valve_cmd", "u": "xi_ref"}
    files = []
    runs_yaml = []
    for spec in specs:
        table = simulate_run(spec, EXAMPLE_PARAMS, dt, sensor, run_seed(seed, name, spec.id))
        table["t"] = np.round(table["t"] * 1000.0, 6)  # ms
        table["p"] = np.round(table["p"] * 100.0, 4)  # kPa
        table = table.rename(columns=rename)
        if spec.kind in ("charge", "discharge", "pulse"):
            fname = f"{spec.id}.csv"
            table.to_csv(folder / fname, index=False, lineterminator="\n")
        elif spec.modulator and spec.modulator["type"] == "iipfm":
            fname = f"{spec.id}.mat"
            scipy.io.savemat(
                folder / fname,
                {c: table[c].to_numpy(np.float64) for c in table.columns},
                do_compression=True,
                oned_as="column",
            )
        else:
            fname = f"{spec.id}.parquet"
            table.to_parquet(folder / fname, index=False)
        files.append(folder / fname)
        entry: dict[str, Any] = {"id": spec.id, "kind": spec.kind, "file": fname}
        if spec.modulator:
            entry["modulator"] = dict(spec.modulator)
        if spec.notes:
            entry["notes"] = spec.notes
        runs_yaml.append(entry)
    doc = {
        "name": name,
        "description": "Example bench export (synthetic, made by `python -m spa example "
        f"raw/{name}`): a valve unlike the paper's, logged at 1 kHz in ms and kPa.",
        "origin": "synthetic",
        "rig": {
            "valve": "3/2 on/off solenoid valve (simulated)",
            "actuator": "bellows SPA (simulated)",
            "sensors": "pressure sensor at the actuator, 1 kHz, 4 mbar noise, 1 mbar ADC step",
            "controller": "1 kHz real-time loop",
            "truth": EXAMPLE_PARAMS.as_dict(),
        },
        "units": {"time": "ms", "pressure": "kPa"},
        "columns": rename,
        "runs": runs_yaml,
    }
    spec_path = folder / "dataset.yaml"
    spec_path.write_text(yaml.safe_dump(doc, sort_keys=False, width=100))
    return [spec_path, *files]
