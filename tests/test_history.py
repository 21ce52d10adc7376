"""The history test: a second state told from laws other than the plant's
(spa.identification.history)."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pandas as pd
import pytest

import spa
from spa.identification.history import (
    edge_history,
    full_rate_records,
    history_test,
    nested_wald,
)
from spa.identification.refine import prepare_runs
from spa.model.params import ValveParams

DT = 1e-3
TRUTH = ValveParams(c1=0.6, k2=1.0, tau2=0.5, t_on=0.01, t_off=0.015)


def _commands() -> dict[str, np.ndarray]:
    """A charge, a discharge and two PWM staircases (5 and 3 Hz): partial charges and
    discharges from many pressures."""
    out = {"charge": np.ones(3000, np.int8), "discharge": np.zeros(3000, np.int8)}
    for name, f_w in (("pwm5", 5.0), ("pwm3", 3.0)):
        xi = np.repeat(np.arange(1, 10) / 10.0, 2500)
        out[name] = spa.modulate("pwm", xi, DT, f_w=f_w)
    return out


def _modes(u: np.ndarray, params: ValveParams) -> tuple[np.ndarray, np.ndarray]:
    """The mode each sample is in (the command delayed by t_on / t_off) and the time since
    that mode began, s."""
    t = np.arange(u.size) * DT
    k = np.concatenate(([0], np.flatnonzero(np.diff(u)) + 1))
    on, since, _ = edge_history(t, t[k], u[k].astype(bool), params.t_on, params.t_off, 0.0)
    # inside a delay the previous mode holds (transport)
    on = np.where(since < 0, ~on, on) if k.size > 1 else on
    return on, since


def _plant(u: np.ndarray, p0: float, heat: float, tau: float, rng) -> np.ndarray:
    """A two-mode plant with the truth's laws and, with ``heat`` > 0, a second state: a rate
    offset ``theta`` that jumps by ``heat`` times the new mode's rate scale at each change of
    mode and relaxes in ``tau`` s (the gas heated by a charge, cooled by a discharge)."""
    on, _ = _modes(u, TRUTH)
    p, theta = p0, 0.0
    k2, tau2, c1 = TRUTH.k2, TRUTH.tau2, TRUTH.c1
    out = np.empty(u.size)
    prev = bool(on[0])
    for i in range(u.size):  # a test fixture, not a hot path
        if on[i] != prev:
            theta += heat * (1.0 if on[i] else -1.0)
            prev = bool(on[i])
        rate = (k2 - p) / tau2 if on[i] else -math.sqrt(p) / c1  # the paper's laws
        p = max(p + DT * (rate + theta * abs(rate)), 0.0)
        theta *= math.exp(-DT / tau)
        out[i] = p
    return out + rng.normal(0.0, 0.002, u.size)


def _runs(heat: float = 0.0, tau: float = 1.0, seed: int = 0):
    rng = np.random.default_rng(seed)
    runs, kinds = {}, {}
    for rid, u in _commands().items():
        p0 = TRUTH.k2 if rid == "discharge" else 0.0
        p = _plant(u, p0, heat, tau, rng)
        runs[rid] = pd.DataFrame({"t": np.arange(u.size) * DT, "p": p, "valve": u})
        kinds[rid] = rid if rid in ("charge", "discharge") else "staircase"
    mods = {r: ("pwm" if kinds[r] == "staircase" else "") for r in runs}
    return runs, prepare_runs(runs, kinds, mods, dict.fromkeys(runs, DT))


@pytest.fixture(scope="module")
def tables_and_runs():
    return _runs()


@pytest.fixture(scope="module")
def single(tables_and_runs):
    """The single-state plant's runs at the log's full rate."""
    return full_rate_records(*tables_and_runs)


@pytest.fixture(scope="module")
def two_state():
    return full_rate_records(*_runs(heat=0.4, tau=1.0))


def test_edge_history_gives_each_samples_mode_and_age():
    t = np.arange(0, 1.0, 0.001)
    starts = np.array([0.0, 0.2, 0.5])
    on, since, usable = edge_history(t, starts, np.array([0, 1, 0], bool), 0.01, 0.02, 0.005)
    i = np.searchsorted(t, 0.3)
    assert on[i] and since[i] == pytest.approx(0.3 - 0.21)
    j = np.searchsorted(t, 0.8)
    assert not on[j] and since[j] == pytest.approx(0.8 - 0.52)
    # inside a dead time, and within the reach of a change, nothing is used
    assert not usable[(t >= 0.2) & (t < 0.215)].any()
    assert not usable[(t > 0.505) & (t < 0.52)].any()
    assert usable[(t > 0.22) & (t < 0.5)].all()
    # a dead time the model underestimates is still cleared
    _, _, cleared = edge_history(t, starts, np.array([0, 1, 0], bool), 0.0, 0.0, 0.005, 0.03)
    assert not cleared[(t >= 0.2) & (t < 0.235)].any() and cleared[np.searchsorted(t, 0.24)]


def test_nested_wald_holds_its_level_on_correlated_noise_and_finds_a_term():
    rng = np.random.default_rng(3)
    n, hits = 4000, 0
    blocks = np.arange(n) // 40
    x = rng.normal(size=(n, 2))
    base = np.ones((n, 1))
    for _ in range(200):
        # noise correlated within ~10 samples (a moving average), as a smoothed derivative
        e = np.convolve(rng.normal(size=n + 9), np.ones(10) / 10, mode="valid")
        hits += nested_wald(e, base, x, blocks)[0] < 0.05
    assert 0.01 <= hits / 200 <= 0.10
    y = 0.05 * x[:, 0] + np.convolve(rng.normal(size=n + 9), np.ones(10) / 10, mode="valid")
    p, gain = nested_wald(y, base, x, blocks)
    assert p < 1e-4 and np.corrcoef(gain, x[:, 0])[0, 1] > 0.9
    # a column already in the base adds nothing
    assert nested_wald(y, np.hstack([base, x]), x[:, :1] * 2.0, blocks)[0] == 1.0


def test_a_single_state_plant_has_no_second_state_under_its_laws_or_others(single):
    own = history_test(single, TRUTH)
    assert own is not None and not own.second_state and not own.pressure_laws
    wrong = dataclasses.replace(TRUTH, c1=1.3 * TRUTH.c1, tau2=0.7 * TRUTH.tau2)
    other = history_test(single, wrong)
    assert not other.second_state
    # the rates are told to depend on pressure otherwise than the (paper's) laws used
    assert other.pressure_laws and other.p_pressure < 1e-6
    assert "otherwise than the paper's laws" in other.sentence(suggest_laws=True)
    assert other.sentence(suggest_laws=False) == ""


def test_a_second_state_is_named_under_the_true_laws_and_wrong_ones(two_state):
    for params in (TRUTH, dataclasses.replace(TRUTH, c1=1.3 * TRUTH.c1, tau2=0.7 * TRUTH.tau2)):
        got = history_test(two_state, params)
        assert got.second_state, got
        assert got.p_history < 1e-4 and got.history_share >= got.min_share
        assert "second state" in got.sentence(suggest_laws=True)


def test_too_few_samples_say_nothing(single):
    short = [dataclasses.replace(r, t=r.t[:150], p=r.p[:150]) for r in single[:1]]
    assert history_test(short, TRUTH) is None
    assert history_test([], TRUTH) is None


def test_full_rate_records_keep_stretches_of_long_runs_within_the_budget(tables_and_runs):
    tables, prepared = tables_and_runs
    assert any(r.stride > 1 for r in prepared)  # the refinement's runs are thinned
    recs = full_rate_records(tables, prepared, budget=4000)
    for run in prepared:
        mine = [x for x in recs if x.rid == run.rid]
        n = len(tables[run.rid])
        assert sum(x.t.size for x in mine) <= max(1000, n)
        assert mine[0].t[0] == 0.0  # the run's own clock, from its first sample
        assert mine[-1].t[-1] == pytest.approx(tables[run.rid]["t"].iloc[-1])  # to its end
        assert len(mine) >= 4 or mine[0].t.size == n
        p = tables[run.rid]["p"].to_numpy()
        for x in mine:  # full rate: the log's step, and the samples themselves
            assert np.allclose(np.diff(x.t), DT)
            i = round(x.t[0] / DT)
            assert np.array_equal(x.p, p[i : i + x.t.size])
    assert full_rate_records(tables, []) == []
