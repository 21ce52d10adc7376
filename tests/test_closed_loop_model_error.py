"""The model error measured on a dataset's staircases, as parameter ranges for the promise."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from spa.closedloop.model_error import (
    dataset_error,
    error_intervals,
    level_errors,
    same_pressure_gain_error,
    widen,
)
from spa.model.modulators import modulate
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
    lo, hi = iv["k2"]
    assert lo <= est.k2 and hi > 1.05 * est.k2  # the box reaches towards the plant's supply


def test_gain_error_is_compared_at_the_same_pressure():
    xi = np.array([0.2, 0.4, 0.6, 0.8])
    # an equilibrium offset alone is no gain error; a steeper curve is
    assert np.allclose(same_pressure_gain_error(xi, xi + 0.1, xi, 0.01)[1:3], 0.0)
    steep = same_pressure_gain_error(xi, 0.5 * xi + 0.2, xi, 0.01)
    assert np.allclose(steep[1:], -0.5)


def test_delay_conventions_and_the_box_merge():
    p = ValveParams(t_on=0.004, t_off=0.01)
    conv = {"delay_convention": {"chosen": "transport", "hold": {"t_on": 0.004, "t_off": 0.01},
                                 "transport": {"t_on": 0.009, "t_off": 0.002}}}  # fmt: skip
    iv = error_intervals(pd.DataFrame(), p, conv)
    assert iv == {"t_on": (0.004, 0.009), "t_off": (0.002, 0.01)}
    box = widen({"t_on": (0.0035, 0.0045), "c1": (0.5, 0.56)}, iv)
    assert box == {"t_on": (0.0035, 0.009), "c1": (0.5, 0.56), "t_off": (0.002, 0.01)}


def test_dataset_error_reads_only_staircases():
    p = ValveParams()
    run = _staircase(ValveParams(k2=1.2 * p.k2), p)
    metas = {"s": {"kind": "staircase"}, "c": {"kind": "closed_loop"}}
    iv = dataset_error({"s": run, "c": run}, metas, p)
    assert set(iv) == {"k2"}
    with pytest.raises(KeyError):
        iv["t_on"]
