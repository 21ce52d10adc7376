"""The model error measured on a dataset's staircases, as parameter ranges for the promise."""

from __future__ import annotations

import numpy as np
import pandas as pd

from spa.closedloop.model_error import (
    dataset_error,
    error_intervals,
    level_errors,
    same_pressure_gain_error,
    widen,
)
from spa.model.modulators import Modulator, modulate
from spa.model.params import ValveParams
from spa.model.plant import simulate

DT = 1e-3


def _staircase(valve: ValveParams, estimate: ValveParams) -> pd.DataFrame:
    u = np.repeat(np.arange(0.1, 1.0, 0.1), 3000)
    command = modulate("pwm", u, DT, f_w=20.0)
    p = simulate(command, DT, valve)
    return pd.DataFrame({"t": np.arange(u.size) * DT, "p": p, "valve": command, "u": u})


def test_the_model_on_its_own_data_has_no_error():
    p = ValveParams()
    e = level_errors(_staircase(p, p), p)
    assert np.allclose(e["error"], 0.0, atol=1e-12)
    assert np.allclose(e["gain_error"].dropna(), 0.0, atol=1e-9)
    assert error_intervals(e, p) == {}


def test_a_plant_with_a_higher_supply_shows_its_gain_error():
    est = ValveParams()
    plant = ValveParams(k2=1.2 * est.k2)
    e = level_errors(_staircase(plant, est), est)
    assert (e["error"].iloc[1:] > 0).all()  # it charges higher at every level
    iv = error_intervals(e, est)
    lo, hi = iv["gain"]
    assert lo == 1.0 and hi > 1.05  # the loop gain reaches towards the steeper plant's
    assert "k2" not in iv  # a loop without feed-forward: its integrator takes the offset
    lo, hi = error_intervals(e, est, equilibrium=True)["k2"]
    assert lo == est.k2 and hi > 1.05 * est.k2  # the feed-forward's plants: a higher supply


def test_a_steeper_plant_is_a_loop_gain_factor_in_the_box():
    """The promise over a gain error: every corner is run with the PI's gains scaled by the
    factor's ends, so a plant twice as steep is one of the plants the promise covers."""
    from spa.closedloop.controller import PIController
    from spa.closedloop.robust import box_worst_case

    mod = Modulator.from_mapping({"type": "pwm", "f_w": 20.0})
    p = ValveParams()
    ctrl = PIController(kp=2.0, ki=10.0)
    alone, _ = box_worst_case(mod, ctrl, p, None, [0.3, 0.5], 3.0, DT)
    steep, _ = box_worst_case(mod, ctrl.scaled(3.0), p, None, [0.3, 0.5], 3.0, DT)
    both, _ = box_worst_case(mod, ctrl, p, None, [0.3, 0.5], 3.0, DT, (1.0, 3.0))
    assert steep["overshoot"] != alone["overshoot"]  # a different loop
    for metric in ("overshoot", "rise_time", "end_error"):
        assert both[metric] == max(alone[metric], steep[metric]), metric


def test_dataset_error_reads_only_staircases():
    p = ValveParams()
    run = _staircase(ValveParams(k2=1.2 * p.k2), p)
    metas = {"s": {"kind": "staircase"}, "c": {"kind": "closed_loop"}}
    iv = dataset_error({"s": run, "c": run}, metas, p)
    assert set(iv) == {"gain"}
    assert set(dataset_error({"c": run}, metas, p)) == set()


def test_gain_error_is_compared_at_the_same_pressure():
    xi = np.array([0.2, 0.4, 0.6, 0.8])
    # an equilibrium offset alone is no gain error; a steeper curve is
    assert np.allclose(same_pressure_gain_error(xi, xi + 0.1, xi, 0.01)[1:3], 0.0)
    steep = same_pressure_gain_error(xi, 0.5 * xi + 0.2, xi, 0.01)
    assert np.allclose(steep[1:], -0.5)


def test_the_box_merge_keeps_both():
    box = widen({"k2": (0.9, 1.1), "c1": (0.5, 0.56)}, {"k2": (0.8, 1.0), "t_on": (0.0, 0.01)})
    assert box == {"k2": (0.8, 1.1), "c1": (0.5, 0.56), "t_on": (0.0, 0.01)}


def test_a_gain_error_within_the_tolerance_is_no_model_error():
    est = ValveParams()
    e = level_errors(_staircase(ValveParams(k2=1.02 * est.k2), est), est)
    g = e["gain_error"].dropna()
    assert 0.0 < g.abs().max() < 0.05  # measured, and small
    assert "gain" not in error_intervals(e, est)
