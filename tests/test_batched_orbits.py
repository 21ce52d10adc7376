"""ΔΣ orbits in a batch (spa.model.periodic.dsm_means): each valve's means bit for bit its own
dsm_mean, whatever else is in the batch; the tuning's box corners computed that way."""

from __future__ import annotations

import numpy as np
import pytest

from spa.model.params import ValveParams
from spa.model.periodic import dsm_mean, dsm_means
from spa.tuning.cost import linearity_cost
from spa.tuning.exact import exact_costs
from spa.tuning.intervals import box_points
from spa.tuning.tables import _corner_optima

XI = np.linspace(0.0, 1.0, 41)


def _valves(seed: int, n: int) -> list[ValveParams]:
    rng = np.random.default_rng(seed)
    out = []
    for i in range(n):
        t_on, t_off = rng.uniform(0.002, 0.015, 2)
        out.append(
            ValveParams(
                c1=rng.uniform(0.2, 1.5),
                k2=rng.uniform(0.5, 3.0),
                tau2=rng.uniform(0.2, 1.5),
                t_on=t_on,
                t_off=t_off,
                delay="transport" if i % 3 == 2 else "hold",
            )
        )
    return out


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_each_row_is_that_valve_s_own_orbit_bit_for_bit(seed: int) -> None:
    valves = _valves(seed, 7)
    periods = [np.float64(p) for p in np.random.default_rng(seed).uniform(0.01, 0.08, 7)]
    batch = dsm_means(XI, periods, valves, max_denominator=40)
    assert batch.shape == (7, XI.size)
    for row, t, v in zip(batch, periods, valves, strict=True):
        assert np.array_equal(row, dsm_mean(XI, t, v, max_denominator=40))
    # and whatever the batch's other members and order
    flipped = dsm_means(XI, periods[::-1], valves[::-1], max_denominator=40)
    assert np.array_equal(flipped[::-1], batch)


def test_a_batch_checks_its_arguments() -> None:
    with pytest.raises(ValueError, match="one period array a valve"):
        dsm_means(XI, [0.02, 0.03], [ValveParams()])
    with pytest.raises(ValueError, match="period"):
        dsm_means(XI, [-0.02], [ValveParams()])


def test_exact_costs_are_exact_cost_for_every_kind() -> None:
    valves = _valves(5, 4)
    for kind, values in {
        "dsm": [0.02, 0.03, 0.04, 0.05],
        "pwm": [10.0, 20.0, 30.0, 40.0],
        "ipfm": [0.02, 0.03, 0.04, 0.05],
    }.items():
        batch = exact_costs(kind, values, valves, n_xi=30)
        single = [
            float(linearity_cost(kind, x, v, 30, exact=True))
            for x, v in zip(values, valves, strict=True)
        ]
        assert batch.tolist() == single, kind


def test_the_box_corners_in_one_batch_equal_each_corner_alone() -> None:
    grids = {
        "pwm": {"start": 5.0, "stop": 40.0, "step": 5.0},
        "dsm": {"start": 0.01, "stop": 0.06, "step": 0.005},
    }
    intervals = {"c1": (0.5, 0.56), "k2": (1.1, 1.2), "t_on": (0.004, 0.006)}
    points = box_points(ValveParams(), intervals)
    batch = _corner_optima(grids, points, 30)
    assert batch.shape == (len(points), 2, 3)
    for row, valve in zip(batch, points, strict=True):
        assert np.array_equal(row, _corner_optima(grids, [valve], 30)[0])
