"""The runs a bench records on a physical plant, in memory.

The physical-plant benchmarks and the tests that identify such a plant and close the loop on
it all record the same session: the identification experiments designed for the plant's
equivalent valve (:func:`spa.synthetic.runs.identification_experiment_for`), then a
staircase of each modulator setting, each run made by the plant with its own noise
(:func:`spa.synthetic.runs.run_seed`). :func:`plant_session` makes it once, without writing
files (:func:`spa.synthetic.runs.generate_dataset` writes a configured dataset's).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import pandas as pd

from spa.model.params import ValveParams
from spa.synthetic.physical import PhysicalPlant, equivalent_params
from spa.synthetic.runs import (
    RunSpec,
    dataset_runs,
    identification_experiment_for,
    run_seed,
    simulate_run,
)
from spa.synthetic.sensor import Sensor

__all__ = ["PlantSession", "plant_session", "staircase_hold"]


def staircase_hold(params: ValveParams) -> float:
    """How long a session's staircase holds each level: five ``tau2``, at least 3 s, in
    whole seconds.

    Examples
    --------
    >>> staircase_hold(ValveParams(tau2=0.826)), staircase_hold(ValveParams(tau2=1.3))
    (5.0, 7.0)
    """
    return float(math.ceil(max(3.0, 5.0 * params.tau2)))


@dataclass(frozen=True)
class PlantSession:
    """The runs of one session and how each was made.

    Attributes
    ----------
    runs : dict
        Run id -> canonical run table.
    specs : tuple of RunSpec
        The runs' specifications, in the session's order.
    params : ValveParams
        The plant's equivalent valve, which the experiments were designed for.
    dt : float
        The controller step, s.
    """

    runs: dict[str, pd.DataFrame]
    specs: tuple[RunSpec, ...]
    params: ValveParams
    dt: float

    @property
    def kinds(self) -> dict[str, str]:
        """Run id -> kind (``charge``, ``staircase``, ...)."""
        return {s.id: s.kind for s in self.specs}

    @property
    def metas(self) -> dict[str, dict[str, str]]:
        """Run id -> ``{"kind": kind}``, the metadata the stages read."""
        return {s.id: {"kind": s.kind} for s in self.specs}

    @property
    def modulators(self) -> dict[str, str]:
        """Run id -> its modulator's type (``""`` for a run without one)."""
        return {s.id: (s.modulator or {}).get("type", "") for s in self.specs}

    def identify_kwargs(self) -> dict[str, Any]:
        """``modulators`` and ``command_dt`` for
        :func:`spa.identification.identify_with_config`."""
        return {"modulators": self.modulators, "command_dt": dict.fromkeys(self.runs, self.dt)}


def plant_session(
    plant: PhysicalPlant,
    modulators: Sequence[Mapping[str, Any]],
    seed: int,
    name: str,
    experiments: Mapping[str, Mapping[str, Any]] | None = None,
    *,
    dt: float = 1e-3,
    fs: float = 1000.0,
) -> PlantSession:
    """The identification experiments and the modulated runs a physical plant makes.

    Parameters
    ----------
    plant : PhysicalPlant
        What makes every run.
    modulators : sequence of mapping
        The settings of the modulated runs.
    seed : int
        With ``name`` and each run's id, the run's noise (:func:`~spa.synthetic.runs.run_seed`).
    name : str
        The session's name.
    experiments : mapping, optional
        The modulated experiments (``staircase``, ``sine``, ``chirp``); by default one
        staircase in steps of 0.1 of the supply, each level held :func:`staircase_hold`.
    dt : float, default 1e-3
        The controller step, s.
    fs : float, default 1000
        The sensor's logging rate, Hz.

    Returns
    -------
    PlantSession
    """
    params = equivalent_params(plant, dt)
    if experiments is None:
        experiments = {"staircase": {"step": 0.1, "hold": staircase_hold(params)}}
    cfg = {
        "controller_dt": dt,
        "sensor": {"fs": fs},
        "plant": plant.to_mapping(),
        "modulators": [dict(m) for m in modulators],
    }
    specs = dataset_runs(
        cfg, {"identification": identification_experiment_for(params), **experiments}
    )
    sensor = Sensor(fs=fs)
    runs = {
        s.id: simulate_run(s, params, dt, sensor, run_seed(seed, name, s.id), plant) for s in specs
    }
    return PlantSession(runs, tuple(specs), params, dt)
