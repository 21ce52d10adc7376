"""The closed loop over the identification's box, the robust tau_c, and bench disturbances."""

from __future__ import annotations

import math

import numpy as np
import pytest

from spa.closedloop.comparison import level_hold
from spa.closedloop.controller import PIController
from spa.closedloop.design import design_pi
from spa.closedloop.disturbance import disturbances, noise_ripple, recovery_time, supply_drop
from spa.closedloop.experiments import (
    LoopUnderTest,
    Staircase,
    run_staircase,
    staircase_reference,
)
from spa.closedloop.loop import closed_loop_arrays
from spa.closedloop.robust import (
    box_worst_case,
    lengthen_tau_c,
    robust_design,
    worst_of_steps,
)
from spa.model.modulators import Modulator
from spa.model.params import ValveParams

P = ValveParams()
DT = 1e-3
LEVELS = [0.1, 0.4, 0.7]
PWM = Modulator.from_mapping({"type": "pwm", "f_w": 20.0})
IIPFM = Modulator.from_mapping({"type": "iipfm", "t_l": 0.02, "gain": 1.15})
# A box far wider than an identification gives: fast, weakly exhausting valves with long
# delays, where the fixed PI designed at the estimate overshoots.
WIDE = {"tau2": (0.3, 0.826), "c1": (0.533, 1.2), "t_off": (0.01, 0.02)}
WIDE_LEVELS = [0.1, 0.4, 0.6]


def test_lengthen_tau_c_takes_the_first_that_holds():
    tau, tried = lengthen_tau_c(lambda t: 30.0 * math.exp(-t), 0.5, 10.0, factor=2.0)
    assert tau == 2.0 and [t for t, _ in tried] == [0.5, 1.0, 2.0]
    assert all(o > 10.0 for _, o in tried[:-1]) and tried[-1][1] <= 10.0
    # held at once: the nominal tau_c is the robust one
    assert lengthen_tau_c(lambda t: 5.0, 0.2, 10.0) == (0.2, [(0.2, 5.0)])
    # never held, NaN included: None, every try up to the bound recorded
    tau, tried = lengthen_tau_c(lambda t: math.nan, 0.2, 10.0, max_tau_c=0.5)
    assert tau is None and len(tried) == 3
    with pytest.raises(ValueError, match="factor"):
        lengthen_tau_c(lambda t: 0.0, 0.2, 10.0, factor=1.0)


def test_worst_of_steps_takes_the_largest_magnitude_and_flags_no_rise():
    a = {"rise_time": [0.2, 0.5], "overshoot": [1.0, 3.0], "settling_time": [0.4, 0.9],
         "end_error": [0.5, 1.5], "steady_state_error": [0.01, -0.03],
         "ripple_pp": [0.01, 0.02], "ripple_rms": [0.003, 0.001]}  # fmt: skip
    b = {**a, "overshoot": [7.0, 0.0], "rise_time": [0.1, math.nan],
         "settling_time": [math.nan, 0.2]}  # fmt: skip
    w = worst_of_steps([a])
    assert w == {"rise_time": 0.5, "overshoot": 3.0, "settling_time": 0.9, "end_error": 1.5,
                 "steady_state_error": 0.03, "ripple_pp": 0.02, "ripple_rms": 0.003}  # fmt: skip
    w2 = worst_of_steps([a, b])
    assert w2["overshoot"] == 7.0 and math.isnan(w2["rise_time"])
    assert math.isnan(w2["settling_time"])  # a step that never settles is the worst case


def test_box_worst_case_covers_the_estimate():
    ctrl = design_pi(IIPFM, P, levels=LEVELS)["fixed"]
    _, steps = run_staircase(LoopUnderTest(IIPFM, ctrl, P), Staircase(LEVELS, 1.5, DT))
    alone, n0 = box_worst_case(IIPFM, ctrl, P, None, LEVELS, 1.5, DT)
    assert n0 == 0
    assert alone["overshoot"] == steps["overshoot"].max()
    assert alone["steady_state_error"] == steps["steady_state_error"].abs().max()
    box = {"k2": (0.8, 0.87), "tau2": (0.78, 0.86)}
    worst, n = box_worst_case(IIPFM, ctrl, P, box, LEVELS, 1.5, DT)
    assert n == 4
    # the estimate is one of the valves (NaN: a step of some valve never rises or settles)
    assert all(math.isnan(worst[m]) or worst[m] >= alone[m] for m in worst)


def test_robust_tau_c_where_the_box_breaks_the_limit():
    def hold_of(tau):
        return level_hold(PWM, P, WIDE_LEVELS, tau, {"hold": None})

    res = robust_design(
        PWM, "fixed", P, WIDE, levels=WIDE_LEVELS, hold=1.5, dt=DT, tau_c=0.1, limit=10.0,
        hold_of=hold_of,
    )  # fmt: skip
    assert res.n_corners == 8
    assert res.worst["overshoot"] > 10.0  # the nominal tau_c breaks the limit over the box
    assert res.tau_c_robust is not None and res.tau_c_robust > res.tau_c
    assert res.worst_robust["overshoot"] <= 10.0
    assert res.worst_robust["end_error"] <= 2.0  # and every step of every corner settles
    assert res.tried[-1][0] == res.tau_c_robust
    assert all(over > 10.0 for _, over in res.tried[:-1])
    # the robust design, evaluated afresh, holds the limit at every corner
    ctrl = design_pi(PWM, P, levels=WIDE_LEVELS, tau_c=res.tau_c_robust)["fixed"]
    hold = hold_of(res.tau_c_robust)
    again, _ = box_worst_case(PWM, ctrl, P, WIDE, WIDE_LEVELS, hold, DT)
    assert again == res.worst_robust


def test_a_tau_c_that_never_settles_does_not_hold():
    # a corner whose delays exceed PWM's period cannot hold the levels: no tau_c holds,
    # however small the overshoot
    box = {**WIDE, "t_off": (0.01, 0.05)}
    res = robust_design(
        PWM, "fixed", P, box, levels=WIDE_LEVELS, hold=3.0, dt=DT, tau_c=0.2, limit=1e3,
        max_tau_c=0.3,
    )  # fmt: skip
    assert res.tau_c_robust is None
    assert all(math.isinf(over) for _, over in res.tried)


def test_robust_tau_c_is_the_nominal_one_on_a_narrow_box():
    box = {"k2": (0.83, 0.845), "tau2": (0.82, 0.83)}
    res = robust_design(
        IIPFM, "fixed", P, box, levels=LEVELS, hold=5.0, dt=DT, tau_c=0.2, limit=10.0
    )
    assert res.tau_c_robust == 0.2 and len(res.tried) == 1


def _open_loop(xi: float) -> PIController:
    return PIController(kp=0.0, ki=0.0, feedforward=((0.0,), (xi,)))


def test_k2_change_to_the_same_supply_changes_nothing():
    r = staircase_reference(LEVELS, 0.7, DT)
    ctrl = design_pi(IIPFM, P, levels=LEVELS)["scheduled_ff"]
    base = closed_loop_arrays(r, DT, IIPFM, ctrl, P, 0.1)
    for k in (1, 700, 1234, 2999):  # inside holds and runs alike
        same = closed_loop_arrays(r, DT, IIPFM, ctrl, P, 0.1, k2_change=(k, P.k2))
        np.testing.assert_array_equal(same[2], base[2])
        np.testing.assert_allclose(same[0], base[0], rtol=0, atol=1e-12)


def test_k2_change_follows_the_charging_closed_form():
    n, k = 3000, 1200
    r = np.full(n, 0.5)
    p, _, u = closed_loop_arrays(r, DT, PWM, _open_loop(1.0), P, 0.0, k2_change=(k, 0.7))
    assert np.all(u == 1)
    t = np.arange(n) * DT
    expect = P.k2 + (0.0 - P.k2) * np.exp(-t / P.tau2)  # settled open at t = 0: no hold
    np.testing.assert_allclose(p[: k + 1], expect[: k + 1], rtol=0, atol=1e-12)
    after = 0.7 + (p[k] - 0.7) * np.exp(-(t[k:] - t[k]) / P.tau2)
    np.testing.assert_allclose(p[k:], after, rtol=0, atol=1e-12)


def test_sensor_noise_is_what_the_controller_reads():
    r = np.full(2000, 0.4)
    ctrl = PIController(kp=2.0, ki=3.0)
    zero = closed_loop_arrays(r, DT, IIPFM, ctrl, P, 0.1, sensor_noise=np.zeros(r.size))
    base = closed_loop_arrays(r, DT, IIPFM, ctrl, P, 0.1)
    np.testing.assert_array_equal(zero[0], base[0])
    # a constant offset c read by a fixed PI is a set-point lowered by c
    offset = closed_loop_arrays(r, DT, IIPFM, ctrl, P, 0.1, sensor_noise=np.full(r.size, 0.05))
    lowered = closed_loop_arrays(r - 0.05, DT, IIPFM, ctrl, P, 0.1)
    np.testing.assert_array_equal(offset[2], lowered[2])
    with pytest.raises(ValueError, match="sensor_noise"):
        closed_loop_arrays(r, DT, IIPFM, ctrl, P, sensor_noise=np.zeros(3))
    with pytest.raises(ValueError, match="k2_change"):
        closed_loop_arrays(r, DT, IIPFM, ctrl, P, k2_change=(0, 0.7))


def test_recovery_time_cases():
    t = np.arange(5) * 0.1
    assert recovery_time(t, [0.0] * 5, 0.01, 0.0) == 0.0
    assert math.isnan(recovery_time(t, [0.0, 0.1, 0.05, 0.03, 0.02], 0.01, 0.0))
    assert recovery_time(t, [0.0, -0.1, 0.05, 0.005, 0.0], 0.01, 0.0) == pytest.approx(0.2)


def test_supply_drop_dips_and_recovers():
    loop = LoopUnderTest(PWM, design_pi(PWM, P, levels=LEVELS)["scheduled_ff"], P)
    stairs = Staircase(LEVELS, 3.0, DT)
    small = supply_drop(loop, stairs)
    out = supply_drop(loop, stairs, drop=0.2)
    assert out["drop_level"] == 0.4
    assert out["dip"] > small["dip"] > 0.0  # a larger drop, a deeper dip
    assert 0.0 < out["recovery_time"] < 1.5  # back within 2 % before the level ends
    assert abs(out["steady_state_error"]) < 0.02
    # a set-point above the dropped supply is never recovered
    high = supply_drop(loop, stairs, drop=0.6)
    assert math.isnan(high["recovery_time"])
    with pytest.raises(ValueError, match="drop"):
        supply_drop(loop, stairs, drop=0.0)


def test_noise_adds_ripple_deterministically():
    loop = LoopUnderTest(PWM, design_pi(PWM, P, levels=LEVELS)["fixed"], P)
    stairs = Staircase(LEVELS, 1.5, DT)
    a = noise_ripple(loop, stairs, 0.005, seed=3)
    b = noise_ripple(loop, stairs, 0.005, seed=3)
    assert a == b and a["noise"] == 0.005
    big = noise_ripple(loop, stairs, 0.05, seed=3)
    assert big["added_ripple_rms"] > 0.0 and big["added_ripple_pp"] > 0.0
    # together, sharing the undisturbed run: the same numbers
    both = disturbances(loop, stairs, 0.005, seed=3)
    assert both == {**supply_drop(loop, stairs), **a}
