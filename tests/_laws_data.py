"""Synthetic benches for the laws' fit: every run the bench would log with the command."""

from __future__ import annotations

import numpy as np
import pandas as pd

from spa import modulate, simulate
from spa.identification.refine import RefineRun, prepare_runs
from spa.model.params import ValveParams

DT = 1e-3
MODULATED = {
    "pwm": {"f_w": 20.0},
    "iipfm": {"t_l": 0.02, "gain": 1.15},
    "dsm": {"period": 0.02},
    "ipfm": {"t_h": 0.02},
}


def _step(n: int, level: int, before: int = 50) -> np.ndarray:
    """``before`` samples at the other level, then ``level``: a charge or discharge with its
    command edge (the refinement uses runs whose valve switches)."""
    u = np.full(n, level, np.int8)
    u[:before] = 1 - level
    return u


def _table(u: np.ndarray, p: np.ndarray) -> pd.DataFrame:
    return pd.DataFrame({"t": np.arange(u.size) * DT, "p": p, "valve": u})


def bench_runs(
    truth: ValveParams, rng: np.random.Generator, noise: float = 0.002, seconds: float = 12.0
) -> list[RefineRun]:
    """Charge, discharge and four modulated runs (staircases and sines) of ``truth``."""
    n = round(seconds / DT)
    t = np.arange(n) * DT
    runs, kinds, mods = {}, {}, {}

    def add(rid: str, kind: str, u: np.ndarray, p0: float, mod: str = "") -> None:
        p = simulate(u, DT, truth, p0=p0) + rng.normal(0.0, noise, u.size)
        runs[rid], kinds[rid] = _table(u, p), kind
        if mod:
            mods[rid] = mod

    add("charge", "charge", _step(n // 2, 1), 0.0)
    add("discharge", "discharge", _step(n // 2, 0), truth.k2)
    stair = np.minimum(np.floor(t / (seconds / 8)) / 7, 1.0)
    sine = 0.5 + 0.35 * np.sin(2 * np.pi * 0.4 * t)
    for j, (kind, settings) in enumerate(MODULATED.items()):
        xi = stair if j % 2 == 0 else sine
        add(
            f"{kind}-run",
            "staircase" if j % 2 == 0 else "sine",
            modulate(kind, xi, DT, **settings),
            0.0,
            kind,
        )
    return prepare_runs(runs, kinds, mods)


SLOW = {
    "pwm": {"f_w": 5.0},
    "iipfm": {"t_l": 0.06, "gain": 1.25},
    "dsm": {"period": 0.05},
    "ipfm": {"t_h": 0.05},
}
#: Eight modulated runs: each kind at two settings, staircase and sine.
SLOW_PAIRS = [
    ("pwm", {"f_w": 5.0}),
    ("pwm", {"f_w": 8.0}),
    ("iipfm", {"t_l": 0.06, "gain": 1.25}),
    ("iipfm", {"t_l": 0.1, "gain": 1.15}),
    ("dsm", {"period": 0.05}),
    ("dsm", {"period": 0.08}),
    ("ipfm", {"t_h": 0.05}),
    ("ipfm", {"t_h": 0.08}),
]


def plant_runs(
    plant, rng: np.random.Generator, seconds: float = 16.0, settings=SLOW_PAIRS
) -> list[RefineRun]:
    """The same bench on a physical plant (spa.synthetic.physical)."""
    from spa.synthetic.physical import simulate_physical

    n = round(seconds / DT)
    t = np.arange(n) * DT
    runs, kinds, mods = {}, {}, {}

    def add(rid: str, kind: str, u: np.ndarray, p0: float, mod: str = "") -> None:
        runs[rid] = simulate_physical(plant, u, DT, p0=p0, rng=rng)[["t", "p", "valve"]]
        kinds[rid] = kind
        if mod:
            mods[rid] = mod

    add("charge", "charge", _step(n // 2, 1), 0.0)
    add("discharge", "discharge", _step(n // 2, 0), plant.supply)
    stair = np.minimum(np.floor(t / (seconds / 8)) / 7, 1.0)
    sine = 0.5 + 0.35 * np.sin(2 * np.pi * 0.25 * t)
    for j, (kind, s) in enumerate(settings):
        xi = stair if j % 2 == 0 else sine
        add(
            f"{kind}-run{j}",
            "staircase" if j % 2 == 0 else "sine",
            modulate(kind, xi, DT, **s),
            0.0,
            kind,
        )
    return prepare_runs(runs, kinds, mods)
