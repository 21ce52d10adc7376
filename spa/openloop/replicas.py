"""What a simulated run would have recorded without noise, or with other noise.

A run written by the simulator (:func:`spa.synthetic.generate_dataset`) carries in its
metadata everything that made it: the true parameters (``truth``), the controller step
(``controller_dt``), the sensor, the config ``seed``, the modulator and the experiment. The
open-loop analyses use that to say how much of a result is the sensor's:

* `noise_free_pressure`: the true pressure at the run's samples (the exact plant replayed on
  the run's recorded valve command), or what its sensor would log without noise;
* `noise_replicates`: the same run re-simulated with fresh sensor noise, seeded from the
  run's own seed so that the replicates are the same bytes on every machine (and, on
  request, without the sensor's ringing);
* `through_sensor`: any pressure record at the run's samples (the linear reference's) logged
  by the run's sensor: ringing after the run's valve edges, the noise of the run's seeds.

Bench runs have no such metadata: both give nothing for them.
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Mapping
from dataclasses import replace
from typing import Any

import numpy as np
import numpy.typing as npt
import pandas as pd

from spa.model.params import ValveParams
from spa.synthetic import RunSpec, Sensor, modulated_runs, run_seed, sensor_record, simulate_run

__all__ = ["is_simulated", "noise_free_pressure", "noise_replicates", "through_sensor"]

_SIMULATOR_KEYS = ("truth", "controller_dt", "sensor", "seed", "dataset", "run")


def is_simulated(meta: Mapping[str, Any]) -> bool:
    """Whether a run's metadata is the simulator's (it can be replayed and re-simulated).

    Examples
    --------
    >>> is_simulated({"kind": "chirp", "origin": "bench"})
    False
    """
    return meta.get("origin") == "synthetic" and all(k in meta for k in _SIMULATOR_KEYS)


def noise_free_pressure(
    run: pd.DataFrame, meta: Mapping[str, Any], *, ringing: bool = False
) -> npt.NDArray[np.float64] | None:
    """A simulated run's pressure at its samples without the sensor's noise.

    Parameters
    ----------
    run : pandas.DataFrame
        The run table (``t``, ``valve``).
    meta : mapping
        Its metadata.
    ringing : bool, default False
        False: the plant's true pressure (no sensor effect at all). True: what the run's
        sensor would have logged without its noise and ADC step, i.e. with the ringing after
        each valve edge that the simulated sensor adds.

    Returns
    -------
    numpy.ndarray or None
        The recorded valve command through the exact plant with the true parameters, from
        0 bar (the simulator starts every modulated run empty), and the sensor without noise
        (:func:`spa.synthetic.simulate_run`). None for a run that is not the simulator's
        (`is_simulated`), or whose samples are not every controller step (then the recorded
        command misses the edges between samples and the replay would not be the run's).
    """
    if not _every_step(run, meta):
        return None
    dt = float(meta["controller_dt"])
    sensor = Sensor.from_mapping(meta["sensor"])
    quiet = replace(sensor, noise=0.0, quantum=0.0, ringing=sensor.ringing if ringing else None)
    spec = RunSpec(str(meta["run"]), str(meta["kind"]), valve=run["valve"].to_numpy(np.int8))
    params = ValveParams(**meta["truth"])
    return simulate_run(spec, params, dt, quiet, np.random.default_rng(0))["p"].to_numpy()


def _every_step(run: pd.DataFrame, meta: Mapping[str, Any]) -> bool:
    """A simulated run logged at every controller step (its ``valve`` is the whole command)."""
    if not is_simulated(meta):
        return False
    t = run["t"].to_numpy(dtype=np.float64)
    dt = float(meta["controller_dt"])
    return t.size >= 2 and math.isclose(float(np.mean(np.diff(t))), dt, rel_tol=1e-9)


def noise_replicates(
    meta: Mapping[str, Any], count: int, *, ringing: bool = True, first: int = 1
) -> Iterator[npt.NDArray[np.float64]]:
    """Pressure records of a simulated run re-simulated with fresh sensor noise.

    Parameters
    ----------
    meta : mapping
        The run's metadata (`is_simulated`), with its ``experiment`` settings.
    count : int
        Number of replicates (>= 0).
    ringing : bool, default True
        False: the run's sensor without its ringing after the valve edges (noise and ADC
        step unchanged, the same draws).
    first : int, default 1
        The first replicate: 0 starts with the run's own noise.

    Yields
    ------
    numpy.ndarray
        The ``p`` column of replicate ``r = first .. first + count - 1``: the same command,
        plant and sensor as the run, with the sensor's noise drawn from
        ``run_seed(seed, dataset, f"{run}/noise-{r}")`` (`replicate_rng`). (Replicate 0, the
        run's own seed, with the ringing is the recorded run itself, bit for bit.)

    Raises
    ------
    ValueError
        If the run is not the simulator's.
    """
    if not is_simulated(meta):
        raise ValueError(f"run {meta.get('run')!r}: not a simulated run, cannot re-simulate")
    spec = replicate_spec(meta)
    params = ValveParams(**meta["truth"])
    sensor = Sensor.from_mapping(meta["sensor"])
    if not ringing:
        sensor = replace(sensor, ringing=None)
    dt = float(meta["controller_dt"])
    for r in range(int(first), int(first) + int(count)):
        rng = replicate_rng(meta, r)
        yield simulate_run(spec, params, dt, sensor, rng)["p"].to_numpy()


def through_sensor(
    p: npt.ArrayLike,
    run: pd.DataFrame,
    meta: Mapping[str, Any],
    replicate: int = 0,
    *,
    ringing: bool = True,
) -> npt.NDArray[np.float64] | None:
    """A pressure record at a simulated run's samples, as the run's sensor would log it.

    Parameters
    ----------
    p : array_like of float, shape (n,)
        Pressure at the run's samples, bar (e.g. the linear reference driven by the run's
        input).
    run : pandas.DataFrame
        The run (``t``, ``valve``): its valve edges start the sensor's ringing.
    meta : mapping
        Its metadata (`is_simulated`).
    replicate : int, default 0
        Whose noise: 0 the run's own seed, ``r`` that of `noise_replicates`' replicate ``r``.
    ringing : bool, default True
        False: the sensor without its ringing.

    Returns
    -------
    numpy.ndarray or None
        ``p`` with the run's sensor (:func:`spa.synthetic.sensor_record`): the ringing after
        the run's valve edges, the noise of the seed, the ADC step. None for a run that is
        not the simulator's or not logged at every controller step (its edges are unknown).
    """
    if not _every_step(run, meta):
        return None
    sensor = Sensor.from_mapping(meta["sensor"])
    if not ringing:
        sensor = replace(sensor, ringing=None)
    t = run["t"].to_numpy(dtype=np.float64)
    valve = run["valve"].to_numpy(np.int8)
    rng = replicate_rng(meta, replicate)
    return sensor_record(t, p, valve, float(meta["controller_dt"]), sensor, rng)


def replicate_rng(meta: Mapping[str, Any], replicate: int) -> np.random.Generator:
    """The noise generator of replicate ``replicate`` (0: the run's own)."""
    run = str(meta["run"]) if replicate == 0 else f"{meta['run']}/noise-{replicate}"
    return run_seed(int(meta["seed"]), str(meta["dataset"]), run)


def replicate_spec(meta: Mapping[str, Any]):
    """The simulator's :class:`spa.synthetic.RunSpec` of a modulated run, from its metadata."""
    experiment = {str(meta["kind"]): dict(meta.get("experiment") or {})}
    try:
        specs = modulated_runs([meta["modulator"]], float(meta["controller_dt"]), experiment)
    except KeyError as missing:
        raise ValueError(
            f"run {meta['run']!r}: its metadata's experiment lacks {missing}; cannot re-simulate"
        ) from None
    if len(specs) != 1 or specs[0].id != meta["run"]:
        raise ValueError(f"run {meta['run']!r}: its metadata does not rebuild one run of its id")
    return specs[0]
