"""Coarse bench logs, as a hobby controller writes them: a few dozen samples at 20-50 Hz, charge
and discharge only, repeated, no valve edge and no time stamp in the log.

A serial-monitor dump of an Arduino soft-actuator controller is the model here: the sketch
opens (or closes) the valve, then prints one pressure reading every ``1/fs`` s. The log starts
at an unknown phase after the command (the loop's first reading), holds no valve column, and
its samples are rounded to the sensor's printed resolution. These runs exercise what
identification can and cannot get from such a log (:mod:`spa.identification`): the rates from
the closed-form fits, the delays not at all.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pandas as pd

from spa.model.params import ValveParams
from spa.model.plant import simulate
from spa.synthetic._physical_core import PhysicalPlant

__all__ = ["PSI", "coarse_runs", "write_coarse_bench"]

#: One psi in bar.
PSI = 0.0689475729


def coarse_runs(
    params: ValveParams,
    rng: np.random.Generator,
    *,
    fs: float = 50.0,
    repeats: int = 5,
    samples: int | None = None,
    noise: float = 0.004,
    resolution: float = 0.01 * PSI,
    dt: float = 1e-4,
    plant: PhysicalPlant | None = None,
) -> dict[str, pd.DataFrame]:
    """Charge and discharge runs of a coarse log, as canonical run tables (no ``valve``).

    Parameters
    ----------
    params : ValveParams
        The true valve.
    rng : numpy.random.Generator
        Noise and each run's phase of the first reading after the command.
    fs : float, optional
        Logging rate, Hz.
    repeats : int, optional
        Repeats of each experiment.
    samples : int, optional
        Readings per run; by default enough for the charge to settle (``t_on + 6 tau2``)
        and the discharge to empty (``t_off + 1.5 * 2 c1 sqrt(k2)``), at least 50.
    noise : float, optional
        Sensor noise standard deviation, bar.
    resolution : float, optional
        Printed resolution, bar (0.01 psi by default).
    dt : float, optional
        Step of the exact simulation, s.
    plant : PhysicalPlant, optional
        A physical plant that makes the runs instead of the model (its own sensor noise,
        ADC step and mains hum; ``noise`` and ``resolution`` are then not added); ``params``
        only sizes the runs (:func:`spa.synthetic.physical.equivalent_params`).

    Returns
    -------
    dict
        ``charge_1..n`` and ``discharge_1..n``: ``t`` (s from the first reading, on the
        log's clock ``k/fs``) and ``p`` (bar).

    Examples
    --------
    >>> runs = coarse_runs(ValveParams(c1=0.084, k2=0.88, tau2=0.092, t_on=0.012,
    ...                                t_off=0.018), np.random.default_rng(0), repeats=1)
    >>> sorted(runs), len(runs["charge_1"]), list(runs["charge_1"].columns)
    (['charge_1', 'discharge_1'], 50, ['t', 'p'])
    """
    step = 1.0 / fs
    if samples is None:
        charge = params.t_on + 6.0 * params.tau2
        empty = params.t_off + 1.5 * 2.0 * params.c1 * math.sqrt(params.k2)
        samples = max(50, math.ceil(max(charge, empty) / step) + 2)
    every = round(step / dt)
    out = {}
    full = params.k2 if plant is None else plant.supply
    for r in range(1, repeats + 1):
        for kind, level, p0 in (("charge", 1, 0.0), ("discharge", 0, full)):
            phase = int(rng.integers(0, every))  # first reading within a step after the command
            idx = phase + every * np.arange(samples)
            u = np.full(int(idx[-1]) + 1, level, dtype=np.int8)
            if plant is not None:
                from spa.synthetic.physical import simulate_physical

                p = simulate_physical(plant, u, dt, p0=p0, rng=rng)["p"].to_numpy()[idx]
                out[f"{kind}_{r}"] = pd.DataFrame({"t": step * np.arange(samples), "p": p})
                continue
            p = simulate(u, dt, params, p0=p0)[idx] + rng.normal(0.0, noise, samples)
            if resolution > 0:
                p = np.round(p / resolution) * resolution
            out[f"{kind}_{r}"] = pd.DataFrame({"t": step * np.arange(samples), "p": p})
    return out


def write_coarse_bench(
    folder: str | Path,
    params: ValveParams,
    rng: np.random.Generator,
    **kwargs: float,
) -> list[Path]:
    """Write :func:`coarse_runs` as a serial-monitor dump would leave them: one ``.txt`` file
    per run, a header ``pressure_psi`` and one reading per line in psi, no time column.

    Parameters
    ----------
    folder : path-like
        Where to write (created). Never a folder under a project's ``raw/`` from code that
        is not the user's: this is for tests and documentation.
    params, rng, **kwargs
        As :func:`coarse_runs`.

    Returns
    -------
    list of pathlib.Path
        ``inflate_<n>.txt`` (charge) and ``deflate_<n>.txt`` (discharge).
    """
    out = Path(folder)
    out.mkdir(parents=True, exist_ok=True)
    paths = []
    for rid, table in coarse_runs(params, rng, **kwargs).items():
        kind, n = rid.split("_")
        name = {"charge": "inflate", "discharge": "deflate"}[kind]
        path = out / f"{name}_{n}.txt"
        psi = table["p"].to_numpy() / PSI
        path.write_text("pressure_psi\n" + "".join(f"{x:.2f}\n" for x in psi))
        paths.append(path)
    return paths
