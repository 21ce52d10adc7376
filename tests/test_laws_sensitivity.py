"""The exact sensitivities of the laws' simulation (spa.model.laws.sensitivity) and the
laws' fit that uses them (spa.identification.laws_fit)."""

from __future__ import annotations

import dataclasses
import math
import sys
from pathlib import Path

import numpy as np
import yaml
from _laws_data import bench_runs

import spa.identification.laws_fit as laws_fit
from spa.identification.laws_model import law_model_sensitivity
from spa.model.laws import Laws
from spa.model.laws._sens_kernel import chain_sensitivity, chain_sensitivity_py
from spa.model.laws.sensitivity import law_replay_sensitivity, law_tangents
from spa.model.laws.timemap import NODES, law_replay, law_tables
from spa.model.params import ValveParams

ROOT = Path(__file__).resolve().parents[1]

# Non-monotone rates both ways, m inside (1/2, 1).
LAWS = Laws(log_g=(0.3, -0.4, 0.5, -0.2), log_h=(-0.2, 0.5, -0.3, 0.4), m=0.7)
VALVE = ValveParams(c1=0.3, k2=0.6, tau2=0.4, t_on=0.012, t_off=0.008, laws=LAWS)


def _edges(seed: int = 1, runs: int = 80) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Command runs of random lengths (20-400 ms): partial charges and discharges from many
    pressures, some long enough to come close to k2 or to empty the chamber."""
    rng = np.random.default_rng(seed)
    starts = np.concatenate(([0.0], np.cumsum(rng.uniform(0.02, 0.4, runs - 1))))
    level = np.arange(runs) % 2 == 1
    t = np.arange(0.0, starts[-1] + 0.3, 1e-3)
    return t, starts, level


def _vector(prm: ValveParams) -> np.ndarray:
    lw = prm.laws
    return np.array([*lw.log_g, *lw.log_h, lw.m, math.log(prm.k2), prm.t_on, prm.t_off])


def _valve(x: np.ndarray) -> ValveParams:
    laws = Laws(log_g=tuple(x[:4]), log_h=tuple(x[4:8]), m=float(x[8]))
    k2 = math.exp(x[9])
    return dataclasses.replace(VALVE, k2=k2, t_on=float(x[10]), t_off=float(x[11]), laws=laws)


def _hold(prm: ValveParams, level: np.ndarray) -> np.ndarray:
    hold = np.where(level, prm.t_on, prm.t_off)
    hold[0] = 0.0
    return hold


def test_the_exact_jacobian_equals_a_central_difference():
    t, starts, level = _edges()
    x = _vector(VALVE)

    def sim(xv: np.ndarray) -> np.ndarray:
        prm = _valve(xv)
        return law_replay(t, starts, level, _hold(prm, level), 0.05, prm, nodes=NODES)

    out = law_replay_sensitivity(t, starts, level, _hold(VALVE, level), 0.05, VALVE, nodes=NODES)
    assert out is not None
    p, dp = out
    np.testing.assert_allclose(p, sim(x), rtol=0, atol=1e-13)
    assert dp.shape == (t.size, 12)
    # the run visits most of [0, k2] in both modes
    assert p.min() < 0.05 * VALVE.k2 and p.max() > 0.7 * VALVE.k2
    for c in range(x.size):
        h = 1e-4 if c < 10 else 1e-6
        up, down = x.copy(), x.copy()
        up[c] += h
        down[c] -= h
        fd = (sim(up) - sim(down)) / (2.0 * h)
        scale = np.max(np.abs(fd))
        assert scale > 1e-3, c  # every column moves the pressure
        assert np.max(np.abs(dp[:, c] - fd)) < 1e-5 * scale, c


def test_the_compiled_chain_equals_its_plain_python_twin():
    _, starts, level = _edges(seed=4, runs=40)
    tab = law_tables(VALVE, 1 << 11)
    hold = _hold(VALVE, level)
    active = np.maximum(np.append(starts[1:], np.inf) - starts - hold, 0.0)
    from spa.model.laws.timemap import law_run_start_pressures

    p_start = law_run_start_pressures(level, active, 0.05, VALVE, 1 << 11)
    t0 = np.where(
        level, tab.charge.forward(p_start, tab.k2), tab.discharge.forward(p_start, tab.k2)
    )
    dact = np.random.default_rng(0).normal(size=(level.size, 12))
    args = (
        level,
        active,
        dact,
        p_start,
        t0,
        np.array([tab.charge.inv_h, tab.discharge.inv_h]),
        np.array([tab.charge.t_end, tab.discharge.t_end]),
        tab.kernel_args[-1],
        law_tangents(VALVE, 1 << 11),
        VALVE.k2,
    )
    dp, base = chain_sensitivity(*args)
    dp_py, base_py = chain_sensitivity_py(*args)
    assert np.max(np.abs(dp)) > 0.0
    np.testing.assert_allclose(dp, dp_py, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(base, base_py, rtol=1e-12, atol=1e-15)


def test_runs_outside_the_tables_and_the_transport_convention_fall_back():
    t, starts, level = _edges(runs=6)
    hold = _hold(VALVE, level)
    # a discharge from above k2 (the closed form beyond the supply pressure)
    assert law_replay_sensitivity(t, starts, level, hold, 1.1 * VALVE.k2, VALVE) is None
    runs = bench_runs(VALVE, np.random.default_rng(2), seconds=4.0)
    assert law_model_sensitivity(runs[0], VALVE, "hold") is not None
    assert law_model_sensitivity(runs[0], VALVE, "transport") is None
    assert law_model_sensitivity(runs[0], dataclasses.replace(VALVE, laws=None), "hold") is None


def test_the_fit_on_balloon_06_reaches_the_finite_difference_fits_optimum(monkeypatch):
    """The full config's balloon-06 as benchmarks/bench_laws_identify.py builds it, identified
    with laws: auto, with the exact Jacobian and with forward differences only."""
    sys.path.insert(0, str(ROOT / "benchmarks"))
    from bench_laws_identify import dataset

    from spa.identification import identify_with_config

    cfg = yaml.safe_load((ROOT / "config" / "config.yaml").read_text(encoding="utf-8"))
    runs, kinds, mods, cdt = dataset(cfg, "balloon-06")

    def record() -> dict:
        res = identify_with_config(runs, kinds, cfg, modulators=mods, command_dt=cdt)
        return res.to_dict()["laws"]

    calls = []
    exact_fn = laws_fit.law_model_sensitivity
    monkeypatch.setattr(
        laws_fit, "law_model_sensitivity", lambda *a, **k: calls.append(1) or exact_fn(*a, **k)
    )
    exact = record()
    assert calls  # the exact Jacobian was taken (hold convention, every run within [0, k2])
    monkeypatch.setattr(laws_fit, "law_model_sensitivity", lambda *a, **k: None)
    numeric = record()
    assert exact["chosen"] == numeric["chosen"] == "identified"
    assert abs(exact["gain"] - numeric["gain"]) < 0.01
    for rid, value in numeric["fit_identified"].items():
        assert abs(exact["fit_identified"][rid] - value) < 0.01, rid

    def vector(rec: dict) -> np.ndarray:
        c, v = rec["coefficients"], rec["valve"]
        return np.array(
            [*c["log_g"], *c["log_h"], c["m"], math.log(v["k2"]), v["t_on"], v["t_off"]]
        )

    cov = np.array(numeric["covariance"]["matrix"])
    se = np.sqrt(np.diag(cov))
    free = se > 0.0
    assert free.sum() >= 11
    assert np.all(np.abs(vector(exact) - vector(numeric))[free] < se[free] / 100.0)
    np.testing.assert_allclose(np.sqrt(np.diag(exact["covariance"]["matrix"])), se, rtol=0.01)
