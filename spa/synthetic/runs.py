"""Simulated runs and datasets: the experiments of a dataset, simulated exactly and written as
canonical run tables."""

from __future__ import annotations

import math
import zlib
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from spa._progress import progress as progress_bar
from spa.identification.experiments import identification_commands
from spa.model.modulators import Modulator, modulate
from spa.model.params import ValveParams
from spa.model.plant import simulate
from spa.synthetic.inputs import chirp_input, sine_input, staircase_input
from spa.synthetic.physical import PhysicalPlant, simulate_physical
from spa.synthetic.sensor import Sensor, edge_declaration, sensor_record

__all__ = [
    "RunSpec",
    "closed_loop_runs",
    "dataset_experiments",
    "dataset_plant",
    "dataset_runs",
    "generate_dataset",
    "identification_experiment_for",
    "identification_runs",
    "modulated_runs",
    "run_seed",
    "simulate_run",
]

# ---- runs -------------------------------------------------------------------------------


@dataclass(frozen=True)
class RunSpec:
    """One simulated run: what the controller commands.

    Either a fixed valve command (``valve``; identification experiments), an input
    fraction (``xi``) through ``modulator`` (``{"type": ..., settings}``), or a set-point
    (``reference``, bar) tracked by ``controller`` (a PI mapping with its step ``dt``)
    through ``modulator`` (closed-loop runs).
    """

    id: str
    kind: str
    p0: float = 0.0
    valve: np.ndarray | None = None
    xi: np.ndarray | None = None
    modulator: Mapping[str, Any] | None = None
    notes: str = ""
    meta: dict[str, Any] = field(default_factory=dict)
    reference: np.ndarray | None = None
    controller: Mapping[str, Any] | None = None


def run_seed(seed: int, dataset: str, run_id: str) -> np.random.Generator:
    """A Generator seeded from the config seed, dataset name and run id (stable across runs)."""
    return np.random.default_rng([seed, zlib.crc32(dataset.encode()), zlib.crc32(run_id.encode())])


def simulate_run(
    spec: RunSpec,
    params: ValveParams,
    dt: float,
    sensor: Sensor,
    rng: np.random.Generator,
    plant: PhysicalPlant | None = None,
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
    plant : PhysicalPlant, optional
        A physical plant that makes the run instead of the model
        (:func:`spa.synthetic.physical.simulate_physical`; its own sensor, logged at
        ``sensor.fs``); ``params`` is then only the valve the modulators and controllers are
        designed for (an LPWM setting without a valve inverts it).

    Returns
    -------
    pandas.DataFrame
        ``t`` (s), ``p`` (bar), ``valve`` (int8) and, for modulated runs, ``u`` (input
        fraction), one row per logged sample. ``valve`` is the command at each sample
        instant.
    """
    if plant is not None:
        return _physical_run(spec, params, dt, sensor.fs, rng, plant)
    ratio = 1.0 / (sensor.fs * dt)
    every = round(ratio)
    if every < 1 or abs(ratio - every) > 1e-6:
        raise ValueError(
            f"sensor.fs = {sensor.fs:g} Hz: 1/fs must be a whole number of controller steps "
            f"dt = {dt:g} s"
        )
    reference = None
    if spec.reference is not None and spec.modulator is not None and spec.controller:
        from spa.closedloop import PIController
        from spa.closedloop.loop import closed_loop_arrays

        reference = np.asarray(spec.reference, dtype=np.float64)
        ctrl = PIController.from_mapping(dict(spec.controller))
        p, xi, u = closed_loop_arrays(reference, dt, spec.modulator, ctrl, params, spec.p0)
    else:
        u, xi = _open_loop_command(spec, params, dt)
        p = simulate(u, dt, params, p0=spec.p0)
    idx = np.arange(0, u.size, every)
    t = idx * dt
    logged = sensor_record(t, p[idx], u, dt, sensor, rng)
    table = {"t": t, "p": logged, "valve": u[idx]}
    if xi is not None:
        table["u"] = np.clip(xi[idx], 0.0, 1.0)
    if reference is not None:
        table["r"] = reference[idx]
    return pd.DataFrame(table)


def _open_loop_command(
    spec: RunSpec, params: ValveParams, dt: float
) -> tuple[np.ndarray, np.ndarray | None]:
    """An open-loop run's valve command ``u`` (int8) and input fraction ``xi`` (None for a
    run given as its valve command)."""
    if spec.valve is not None:
        return np.asarray(spec.valve, dtype=np.int8), None
    if spec.xi is not None and spec.modulator is not None:
        # A setting that inverts a valve (LPWM) without naming one inverts the simulated one.
        mod = Modulator.from_mapping(spec.modulator).bind(params)
        xi = np.asarray(spec.xi, dtype=np.float64)
        return modulate(mod.kind, xi, dt, **mod.settings), xi
    raise ValueError(f"run {spec.id!r}: give either valve, or xi and modulator")


def _physical_run(
    spec: RunSpec,
    params: ValveParams,
    dt: float,
    fs: float,
    rng: np.random.Generator,
    plant: PhysicalPlant,
) -> pd.DataFrame:
    """:func:`simulate_run` on a physical plant."""
    from spa.synthetic.physical import closed_loop_physical

    if spec.reference is not None and spec.modulator is not None and spec.controller:
        from spa.closedloop import PIController

        ctrl = PIController.from_mapping(dict(spec.controller))
        run = closed_loop_physical(plant, spec.reference, dt, spec.modulator, ctrl, rng=rng)
        every = round(1.0 / (fs * dt))
        return run.iloc[::every, :5].reset_index(drop=True)
    u, xi = _open_loop_command(spec, params, dt)
    table = simulate_physical(plant, u, dt, fs=fs, p0=spec.p0, rng=rng, u=xi)
    table.attrs.clear()
    return table


def identification_runs(
    params: ValveParams,
    dt: float,
    charge_time: float = 6.0,
    discharge_time: float = 4.0,
    low_times: Sequence[float] = (0.005, 0.010, 0.015, 0.020, 0.050, 0.100, 0.200),
    high_time: float = 0.300,
    repeats: int = 3,
) -> list[RunSpec]:
    """The paper's three identification experiments (Section 3.2) as simulated runs.

    The commands are :func:`spa.identification.identification_commands`, the one experiment
    design, with the simulator's settings (the config's ``experiments: identification``):
    charge and discharge from t = 0 with the valve settled (no lead), the pulse train after
    0.2 s closed, opened ``high_time`` first (the fill), each low followed by ``high_time``
    open, and 0.5 s closed at the end.

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
    cmds = identification_commands(
        dt,
        lead=0.0,
        charge_duration=charge_time,
        discharge_duration=discharge_time,
        pulse_lead=0.2,
        fill=high_time,
        lows=low_times,
        highs=(high_time,),
        repeats=repeats,
        tail=0.5,
    )
    return [
        RunSpec("charge", "charge", p0=0.0, valve=cmds["charge"]),
        RunSpec("discharge", "discharge", p0=params.k2, valve=cmds["discharge"]),
        RunSpec(
            "pulse",
            "pulse",
            p0=0.0,
            valve=cmds["pulse"],
            notes=f"low durations {list(low_times)} s, high {high_time} s, x{repeats}",
        ),
    ]


def identification_experiment_for(params: ValveParams) -> dict[str, Any]:
    """Identification experiment durations scaled to a valve, as a bench user would choose.

    A pure helper for simulating valves unlike the paper's: the returned mapping is the
    keyword arguments of :func:`identification_runs` (the config's ``experiments:
    identification`` section).

    Parameters
    ----------
    params : ValveParams
        The valve (its rough size is what a user knows before identifying it).

    Returns
    -------
    dict
        ``charge_time`` (s): ``t_on`` plus 6 ``tau2`` (the pressure is within 0.25 % of the
        supply), at least 0.5 s; ``discharge_time`` (s): ``t_off`` plus 1.5 times the time to
        empty from the supply, ``2*c1*sqrt(k2)`` (Eq. A1), at least 0.3 s; ``low_times``
        (s): the paper's lows 5–200 ms, plus ``2*t_off + 10 ms`` and ``4*t_off + 20 ms`` so
        that at least two lows per pattern are longer than the closing delay;
        ``high_time`` (s): 300 ms, or ``5*t_on + 50 ms`` if longer; ``repeats``: 3. Every
        duration is rounded up to 10 ms.

    Notes
    -----
    Lows shorter than ``t_off`` are kept on purpose: the exhaust never starts (the dead-zone)
    and the delay fit must handle such edges. The durations only depend on the valve, so a
    simulated dataset stays deterministic.

    Examples
    --------
    >>> d = identification_experiment_for(ValveParams(c1=0.12, k2=0.3, tau2=0.06,
    ...                                               t_on=0.0008, t_off=0.0015))
    >>> d["charge_time"], d["discharge_time"], d["high_time"]
    (0.5, 0.3, 0.3)
    >>> identification_experiment_for(ValveParams())["charge_time"]
    4.96
    """

    def up(x: float) -> float:
        return math.ceil(round(x / 0.01, 6)) * 0.01

    empty = 2.0 * params.c1 * math.sqrt(params.k2)
    paper_lows = (0.005, 0.010, 0.015, 0.020, 0.050, 0.100, 0.200)
    extra = (up(2 * params.t_off + 0.01), up(4 * params.t_off + 0.02))
    return {
        "charge_time": round(up(max(params.t_on + 6.0 * params.tau2, 0.5)), 6),
        "discharge_time": round(up(max(params.t_off + 1.5 * empty, 0.3)), 6),
        "low_times": sorted({round(v, 6) for v in (*paper_lows, *extra)}),
        "high_time": round(up(max(0.3, 5.0 * params.t_on + 0.05)), 6),
        "repeats": 3,
    }


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
        label = Modulator.from_mapping(mod).label
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
    cfg: Mapping[str, Any],
    experiments: Mapping[str, Mapping[str, Any]],
    skipped: dict[str, str] | None = None,
) -> list[RunSpec]:
    """Every run of a simulated dataset: the identification experiments, then per modulator.

    Parameters
    ----------
    cfg : mapping
        One entry of the config's ``simulated:`` (``params``, ``controller_dt``, ``sensor``,
        ``modulators``).
    experiments : mapping
        The config's ``experiments:`` (``identification``, ``staircase``, ``sine``, ``chirp``,
        ``closed_loop``), with the dataset's own ``experiments:`` merged over it
        (:func:`dataset_experiments`).
    skipped : dict, optional
        Filled with ``run -> reason`` for the closed-loop runs left out.
    """
    dt = float(cfg["controller_dt"])
    plant, params = dataset_plant(cfg)
    ident = dict(experiments.get("identification", {}))
    runs = identification_runs(params, dt, **ident)
    if plant is not None:  # the discharge starts at rest at the plant's supply
        runs = [replace(r, p0=plant.supply) if r.kind == "discharge" else r for r in runs]
    modulated = {k: v for k, v in experiments.items() if k in ("staircase", "sine", "chirp")}
    runs += modulated_runs(cfg["modulators"], dt, modulated)
    if experiments.get("closed_loop"):
        runs += closed_loop_runs(params, dt, experiments["closed_loop"], skipped)
    return runs


def dataset_plant(cfg: Mapping[str, Any]) -> tuple[PhysicalPlant | None, ValveParams]:
    """What makes a simulated dataset's runs, and the valve its experiments are designed for.

    Parameters
    ----------
    cfg : mapping
        One entry of the config's ``simulated:``: ``params`` (the model's five parameters)
        and/or ``plant`` (``{kind: physical, ...}``, :class:`PhysicalPlant`'s settings).

    Returns
    -------
    plant : PhysicalPlant or None
        The physical plant that makes every run, or None (the model does, with ``params``).
    params : ValveParams
        The model's valve: ``params`` when given, else the plant's equivalent
        (:func:`spa.synthetic.physical.equivalent_params`). With a plant it is only what the
        experiments and closed-loop designs assume, not what makes the data.

    Raises
    ------
    ValueError
        If neither is given, or a setting is out of range (named).
    """
    from spa.synthetic.physical import PhysicalPlant, equivalent_params

    plant = None
    if cfg.get("plant") is not None:
        plant = PhysicalPlant.from_mapping(cfg["plant"])
    if cfg.get("params") is not None:
        return plant, ValveParams(**cfg["params"])
    if plant is None:
        raise ValueError("a simulated dataset needs params: (the model) or plant: (physical)")
    return plant, equivalent_params(plant, float(cfg.get("controller_dt", 1e-3)))


def closed_loop_runs(
    params: ValveParams,
    dt: float,
    cfg: Mapping[str, Any],
    skipped: dict[str, str] | None = None,
) -> list[RunSpec]:
    """Closed-loop runs: a set-point staircase tracked by a PI through each modulator.

    Parameters
    ----------
    params : ValveParams
        The valve the PI is designed for (SIMC on the averaged model: the fixed PI of
        :func:`spa.closedloop.design.design_pi` at ``tau_c``), as a lab would after
        identifying it.
    dt : float
        Controller step, s.
    cfg : mapping
        ``levels`` (bar), ``hold`` (s per level), ``modulators`` (settings), ``tau_c`` (s).
    skipped : dict, optional
        Filled with ``label -> reason`` for the settings left out.

    Returns
    -------
    list of RunSpec
        Run ids ``closed_loop_<setting label>``; the staircase up then down, from rest at
        0 bar, over the levels the setting can hold on this valve
        (:func:`spa.closedloop.design.operating_levels`, spread over its range when fewer
        than two of ``levels`` fit, as a lab with a low supply would choose them). A setting
        that holds no range is left out (named in ``skipped``).
    """
    from spa.closedloop.design import design_pi, operating_levels
    from spa.closedloop.experiments import staircase_reference

    runs = []
    for setting in cfg["modulators"]:
        mod = Modulator.from_mapping(setting)
        levels, why = operating_levels(cfg["levels"], mod, params, spread=True)
        if why is not None:
            if skipped is not None:
                skipped[mod.label] = why
            continue
        reference = staircase_reference(levels, float(cfg["hold"]), dt)
        pi = design_pi(mod, params, levels=levels, tau_c=float(cfg.get("tau_c", 0.2)))
        controller = {**pi["fixed"].to_mapping(), "dt": dt}
        runs.append(
            RunSpec(
                f"closed_loop_{mod.label}",
                "closed_loop",
                modulator=mod.to_mapping(),
                reference=reference,
                controller=controller,
                meta={"levels": levels, "hold": float(cfg["hold"])},
            )
        )
    return runs


def dataset_experiments(
    cfg: Mapping[str, Any], experiments: Mapping[str, Mapping[str, Any]]
) -> dict[str, Any]:
    """The experiments of one simulated dataset: its own ``experiments:`` over the config's.

    Parameters
    ----------
    cfg : mapping
        One entry of the config's ``simulated:``; its optional ``experiments`` mapping
        (e.g. a longer ``identification: {charge_time: 15}`` for a slow valve) is merged
        key by key into each experiment of ``experiments``.
    experiments : mapping
        The config's ``experiments:``.

    Returns
    -------
    dict

    Examples
    --------
    >>> dataset_experiments({"experiments": {"staircase": {"hold": 20.0}}},
    ...                     {"staircase": {"step": 0.1, "hold": 5.0}})
    {'staircase': {'step': 0.1, 'hold': 20.0}}
    """
    out = {k: dict(v) if isinstance(v, Mapping) else v for k, v in experiments.items()}
    for key, value in dict(cfg.get("experiments") or {}).items():
        base = out.get(key)
        merge = isinstance(base, dict) and isinstance(value, Mapping)
        out[key] = {**base, **value} if merge else value
    return out


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
        run's bytes do not depend on which other runs are configured. The dataset's own
        ``seed`` (``cfg["seed"]``, a seeded fixture's) replaces it.
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

    plant, params = dataset_plant(cfg)
    seed = int(cfg.get("seed", seed))
    dt = float(cfg["controller_dt"])
    sensor = Sensor.from_mapping(cfg.get("sensor"))
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    paths = []
    skipped: dict[str, str] = {}
    specs = list(dataset_runs(cfg, dataset_experiments(cfg, experiments), skipped))
    for why in skipped.values():
        if progress is not None:
            progress(f"{name}: closed-loop run left out: {why}")
    for spec in progress_bar(specs, f"simulating {name}"):
        table = simulate_run(spec, params, dt, sensor, run_seed(seed, name, spec.id), plant)
        meta = {
            "dataset": name,
            "run": spec.id,
            "kind": spec.kind,
            "origin": "synthetic",
            "modulator": dict(spec.modulator) if spec.modulator else None,
            **({"controller": dict(spec.controller)} if spec.controller else {}),
            "notes": spec.notes,
            "description": str(cfg.get("description", "")),
            # a physical plant's runs have no model truth: nothing replays them as the model
            **(
                {"plant": plant.to_mapping(), "design_params": params.as_dict()}
                if plant
                else {"truth": params.as_dict()}
            ),
            "controller_dt": dt,
            **edge_declaration(spec.valve, dt, sensor),
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
