"""Model validation: exact re-simulation at the sample times, and the scores."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from spa import ValveParams, modulate, simulate
from spa.validation import (
    command_from_input,
    fit_percent,
    initial_pressure,
    model_response,
    validate_run,
    validate_runs,
)

PARAMS = ValveParams(c1=0.45, k2=0.9, tau2=0.6, t_on=0.0037, t_off=0.0081)


@settings(max_examples=40, deadline=None)
@given(
    seed=st.integers(0, 2**31),
    p0=st.floats(0.0, 1.0),
    t0=st.floats(-5.0, 50.0),
    dt=st.sampled_from([1e-4, 1e-3, 2.5e-3]),
)
def test_model_response_equals_simulate_on_a_uniform_grid(seed, p0, t0, dt):
    rng = np.random.default_rng(seed)
    u = np.repeat(rng.integers(0, 2, 60), rng.integers(1, 30, 60)).astype(np.int8)
    t = t0 + dt * np.arange(u.size)
    expected = simulate(u, dt, PARAMS, p0)
    assert np.allclose(model_response(t, u, PARAMS, p0), expected, rtol=0, atol=1e-11)


def test_model_response_is_exact_at_irregular_sample_times():
    """Edges at irregular sample instants: compare with simulate on a 10 us grid."""
    rng = np.random.default_rng(4)
    n, fine = 3000, 100
    idx = np.arange(n) * fine + rng.integers(-30, 31, n)
    idx[0] = 0
    u = np.repeat(rng.integers(0, 2, 150), 20).astype(np.int8)
    u_fine = u[np.searchsorted(idx, np.arange(idx[-1] + 1), side="right") - 1]
    truth = simulate(u_fine, 1e-5, PARAMS, 0.2)[idx]
    got = model_response(7.0 + idx * 1e-5, u, PARAMS, 0.2)
    assert np.max(np.abs(got - truth)) < 1e-10


def test_dead_zone_short_pulses_hold_the_pressure():
    # a 2 ms high pulse is shorter than t_on = 3.7 ms: nothing happens
    t = 1e-3 * np.arange(20)
    u = np.zeros(20, dtype=np.int8)
    u[5:7] = 1
    p = model_response(t, u, PARAMS, 0.0)
    assert np.all(p == 0.0)


def test_model_response_rejects_bad_input():
    t = np.arange(5.0)
    with pytest.raises(ValueError, match="strictly increasing"):
        model_response(t[::-1], np.zeros(5), PARAMS, 0.0)
    with pytest.raises(ValueError, match="valve"):
        model_response(t, np.full(5, 0.5), PARAMS, 0.0)
    with pytest.raises(ValueError, match="valve must have shape"):
        model_response(t, np.zeros(4), PARAMS, 0.0)
    with pytest.raises(ValueError, match="p0"):
        model_response(t, np.zeros(5), PARAMS, -0.1)


def test_fit_percent_and_initial_pressure():
    assert fit_percent([1.0, 2.0, 3.0], [1.0, 2.0, 3.0]) == 100.0
    assert fit_percent([1.0, 2.0, 3.0], [2.0, 2.0, 2.0]) == 0.0
    assert math.isnan(fit_percent([1.0, 1.0], [1.0, 1.0]))
    p = [1.0, 3.0]
    assert fit_percent(p, [1.0, 2.0]) == pytest.approx(100 * (1 - 1 / math.sqrt(2)))
    t = 2.0 + 1e-3 * np.arange(50)
    assert initial_pressure(t, 0.4 + 0.5 * (t - 2.0)) == pytest.approx(0.4)
    assert initial_pressure(t, np.full(50, -0.01)) == 0.0


def _noise_free(u: np.ndarray, dt: float, p0: float = 0.0) -> pd.DataFrame:
    return pd.DataFrame(
        {"t": 10.0 + dt * np.arange(u.size), "p": simulate(u, dt, PARAMS, p0), "valve": u}
    )


def test_validate_run_perfect_model_scores_100():
    u = modulate("pwm", np.full(3000, 0.6), 1e-3, f_w=10.0)
    res = validate_run(_noise_free(u, 1e-3), PARAMS, p0=0.0)
    assert res.fit_percent == pytest.approx(100.0, abs=1e-9)
    assert res.rmse < 1e-12 and res.max_abs_error < 1e-12
    assert list(res.trace.columns) == ["t", "p", "p_model", "valve"]
    assert res.trace["valve"].dtype == np.int8 and res.n == 3000
    # wrong parameters score lower, and the error is the largest deviation
    worse = validate_run(_noise_free(u, 1e-3), ValveParams(), p0=0.0)
    assert worse.fit_percent < 99.0
    err = worse.trace["p"] - worse.trace["p_model"]
    assert worse.max_abs_error == pytest.approx(float(err.abs().max()))


@pytest.mark.parametrize(
    "modulator",
    [
        {"type": "pwm", "f_w": 20.0},
        {"type": "ipfm", "t_h": 0.02},
        {"type": "iipfm", "t_l": 0.02, "gain": 1.15},
        {"type": "dsm", "period": 0.02},
    ],
)
def test_validate_from_input_through_the_modulator(modulator):
    dt = 1e-3
    xi = np.repeat(np.linspace(0.0, 1.0, 6), 800)
    settings_ = {k: v for k, v in modulator.items() if k != "type"}
    u = modulate(modulator["type"], xi, dt, **settings_)
    table = _noise_free(u, dt).assign(u=xi)
    with_valve = validate_run(table, PARAMS)
    from_u = validate_run(table.drop(columns="valve"), PARAMS, modulator, p0=0.0)
    assert from_u.fit_percent == pytest.approx(100.0, abs=1e-6)
    assert np.array_equal(from_u.trace["valve"], u)
    assert np.array_equal(with_valve.trace["valve"], u)
    # the measured start is estimated by a line over 10 ms: close to, not exactly, 0 bar
    assert with_valve.p0 < 2e-4 and with_valve.fit_percent > 99.9


def test_command_from_input_on_irregular_samples():
    rng = np.random.default_rng(1)
    t = np.cumsum(1e-3 + rng.uniform(-5e-5, 5e-5, 1000))
    grid, cmd = command_from_input(t, np.full(1000, 0.5), {"type": "pwm", "f_w": 10.0})
    assert np.allclose(np.diff(grid), np.diff(grid)[0]) and grid[0] == t[0]
    assert grid[-1] <= t[-1] and cmd.dtype == np.int8
    assert abs(cmd.mean() - 0.5) < 0.02


def test_validate_run_errors_name_the_problem():
    table = _noise_free(np.ones(100, dtype=np.int8), 1e-3)
    with pytest.raises(ValueError, match="'p' column"):
        validate_run(table.drop(columns="p"), PARAMS)
    with pytest.raises(ValueError, match="pass modulator"):
        validate_run(table.drop(columns="valve").assign(u=0.5), PARAMS)
    with pytest.raises(ValueError, match="'valve' column, or a 'u' column"):
        validate_run(table.drop(columns="valve"), PARAMS)
    with pytest.raises(ValueError, match="'type'"):
        validate_run(table.drop(columns="valve").assign(u=0.5), PARAMS, {"f_w": 20})
    with pytest.raises(ValueError, match="DataFrame"):
        validate_run({"t": [0, 1]}, PARAMS)


def test_validate_runs_table():
    u = modulate("iipfm", np.full(2000, 0.5), 1e-3, t_l=0.02, gain=1.15)
    runs = {"a": _noise_free(u, 1e-3), "b": _noise_free(1 - u, 1e-3, p0=0.5)}
    mods = {"a": {"type": "iipfm", "t_l": 0.02, "gain": 1.15}}
    out = validate_runs(runs, PARAMS, mods, kinds={"a": "staircase", "b": "sine"})
    assert list(out.columns) == [
        "run", "kind", "modulator", "setting", "fit_percent", "rmse", "max_abs_error", "n", "p0"
    ]  # fmt: skip
    assert out["run"].tolist() == ["a", "b"] and out["kind"].tolist() == ["staircase", "sine"]
    # one label for a setting, everywhere (spa.model.modulators.Modulator.label)
    assert out["modulator"].tolist() == ["iipfm", ""]
    assert out["setting"].tolist() == ["iipfm-20ms-G1.15", ""]
    assert (out["fit_percent"] > 99.9).all()
