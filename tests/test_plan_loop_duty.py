"""The closed loop's command as a verification prediction: the duty that holds the top and the
bottom level, its model error measured on the recorded open-loop staircases as a log-odds
difference, and a supply 20 % lower breaking it where the loop's levels and dynamics keep."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from scipy.special import logit

from spa.closedloop.controller import PIController
from spa.model.params import ValveParams
from spa.model.plant import simulate
from spa.plan.loop_bands import level_duties, loop_predictions, with_model_error
from spa.plan.loop_error import duty_error

TRUTH = ValveParams()
DT = 0.002
SETTING = {"type": "pwm", "f_w": 20.0}
META = {"kind": "staircase", "modulator": SETTING}


def _staircase(plant: ValveParams, noise: float = 0.003, seed: int = 1) -> pd.DataFrame:
    """An open-loop PWM staircase at 20 Hz, five levels of 6 s, on ``plant``, logged with
    ``noise``."""
    u = np.repeat([0.2, 0.35, 0.5, 0.65, 0.8], 3000)
    valve = (np.arange(u.size) % 25 < 25 * u).astype(np.int8)
    p = simulate(valve, DT, plant) + np.random.default_rng(seed).normal(0.0, noise, u.size)
    return pd.DataFrame({"t": np.arange(u.size) * DT, "p": p, "valve": valve, "u": u})


@pytest.mark.parametrize(
    ("change", "low", "high"),
    [
        ({}, -0.02, 0.02),  # the identified valve itself: no error
        # vents slower: less duty holds a pressure, by about the odds' log(1/2) and log(1/1.1)
        ({"c1": 2 * TRUTH.c1}, -0.8, -0.4),
        ({"c1": 1.1 * TRUTH.c1}, -0.12, -0.06),
        ({"k2": 0.8 * TRUTH.k2}, 0.2, 0.6),  # a lower supply: more duty
        ({"tau2": 1.3 * TRUTH.tau2}, 0.15, 0.4),  # charges slower: more duty, log(1.3) = 0.26
    ],
)
def test_the_duty_error_is_the_log_odds_the_bench_holds_a_pressure_with_beyond_the_model(
    change, low, high
):
    plant = dataclasses.replace(TRUTH, **change)
    err = duty_error({"s": _staircase(plant)}, {"s": META}, TRUTH, "pwm-20Hz")
    assert err["n"] >= 3 and err["runs"] == ["s"]
    assert low < err["shift"] < high, err
    assert err["logit_sd"] >= 0.0 and err["dof"] == err["n"] - 1


def test_the_duty_error_reads_the_loops_own_setting_only():
    err = duty_error({"s": _staircase(TRUTH)}, {"s": META}, TRUTH, "pwm-10Hz")
    assert err["n"] == 0 and "shift" not in err


def test_a_duty_band_moves_on_the_log_odds_and_ends_within_0_and_1():
    band = {"value": 0.9, "sd": 0.01, "dof": 47.0, "scale": 1.0, "lo": 0.88, "hi": 0.92}
    exact = with_model_error(band, {"n": 10, "shift": 0.0, "logit_sd": 0.0, "dof": 9.0})
    assert exact["value"] == pytest.approx(0.9)
    assert exact["hi"] - exact["lo"] == pytest.approx(band["hi"] - band["lo"], rel=0.01)
    moved = with_model_error(band, {"n": 10, "shift": 1.0, "logit_sd": 0.5, "dof": 9.0})
    assert logit(moved["value"]) == pytest.approx(logit(0.9) + 1.0)
    assert moved["hi"] <= 1.0 and moved["lo"] < moved["value"] < moved["hi"]
    assert moved["model_error"] == {"n": 10, "shift": 1.0, "logit_sd": 0.5, "applied": True}


def test_the_loops_duty_is_the_command_that_holds_the_level_open_loop():
    """The duty a closed loop settles on at a level lies between two whole numbers of ticks
    on per period, and PWM held open loop at those two holds a pressure either side of the
    level (the invariant the duty's model error is carried by)."""
    pi = PIController(kp=0.3, ki=2.0)
    out = loop_predictions(TRUTH, SETTING, pi, [0.2, 0.35, 0.5], 4.0, DT, 0.0, 0.0, draws=2)
    period = 25  # 20 Hz at 2 ms
    for key, level in (("duty_top", 0.5), ("duty_bottom", 0.2)):
        ticks = period * out[key]["value"]
        held = []
        for on in (math.floor(ticks), math.ceil(ticks) + (ticks == int(ticks))):
            valve = ((np.arange(6000) % period) < on).astype(np.int8)
            held.append(float(np.mean(simulate(valve, DT, TRUTH, p0=level)[-1500:])))
        assert held[0] <= level <= held[1], (key, ticks, held)


def test_a_lower_supply_moves_the_loops_duty_out_of_its_band():
    pi = PIController(kp=0.3, ki=2.0)
    levels = [0.2, 0.35, 0.5]
    box = {"k2": (0.82, 0.85), "tau2": (0.80, 0.85), "c1": (0.52, 0.545)}
    same = loop_predictions(TRUTH, SETTING, pi, levels, 4.0, DT, 0.003, 0.0, box, seed=2)
    low = dataclasses.replace(TRUTH, k2=0.8 * TRUTH.k2)
    moved = loop_predictions(low, SETTING, pi, levels, 4.0, DT, 0.003, 0.0, seed=3)
    assert not same["duty_top"]["lo"] <= moved["duty_top"]["value"] <= same["duty_top"]["hi"]
    # while the levels the loop holds, its ripple and overshoot read much the same
    assert moved["duty_top"]["value"] > same["duty_top"]["hi"]


def test_level_duties_skip_the_lead_and_read_nan_without_a_valve_column():
    r = np.repeat([0.2, 0.2, 0.4, 0.2], 16)
    valve = np.where(r > 0.3, 1, np.tile([1, 1, 0, 0], 16))
    valve[:16] = 0  # the lead: not read
    run = pd.DataFrame({"t": np.arange(64) * 0.1, "r": r, "valve": valve})
    got = level_duties(run, 1.6)
    assert (got["duty_top"], got["duty_bottom"]) == (1.0, 0.5)
    # the top level's one pulse fills its window; the bottom's pulses are 2 of 4 samples
    assert (got["duty_top_step"], got["duty_bottom_step"]) == (1.0, 0.5)
    assert all(math.isnan(x) for x in level_duties(run.drop(columns="valve"), 1.6).values())


def test_a_duty_is_not_predicted_without_its_model_error(tmp_path: Path):
    from spa.plan.verify_command import _loop_model_error

    band = {"value": 0.4, "sd": 0.01, "dof": 47.0, "scale": 1.0, "lo": 0.38, "hi": 0.42}
    loop = {"setting": SETTING, "bands": {"duty_top": dict(band), "duty_bottom": dict(band)}}
    _loop_model_error(loop, tmp_path, TRUTH, 0.003, 0.0, 0)  # no runs recorded
    assert loop["bands"] == {}
    assert set(loop["unpredicted"]) == {"duty_top", "duty_bottom"}
    assert "not measured" in loop["unpredicted"]["duty_top"]["why"]
