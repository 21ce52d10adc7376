"""The exact plant against closed forms, the per-sample reference and its own conventions."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from spa import ValveParams, charge, discharge, simulate

import reference as ref

P = ValveParams()


def test_constant_open_follows_exact_charge_curve():
    dt = 1e-3
    t = np.arange(5000) * dt
    p = simulate(np.ones(t.size, dtype=np.int8), dt, P, p0=0.0)
    # settled open at t = 0: no t_on hold, pure first-order charge
    np.testing.assert_allclose(p, P.k2 * (1 - np.exp(-t / P.tau2)), rtol=0, atol=1e-13)


def test_constant_closed_follows_exact_discharge_curve_and_empties():
    dt = 1e-3
    t = np.arange(3000) * dt
    p = simulate(np.zeros(t.size, dtype=np.int8), dt, P, p0=P.k2)
    expected = np.maximum(math.sqrt(P.k2) - t / (2 * P.c1), 0.0) ** 2
    np.testing.assert_allclose(p, expected, rtol=0, atol=1e-13)
    t_empty = 2 * P.c1 * math.sqrt(P.k2)  # ~0.975 s
    assert p[t > t_empty + dt].max() == 0.0
    assert p[t < t_empty - dt].min() > 0.0


def test_edge_starts_hold_then_dynamics():
    dt = 1e-4
    u = np.zeros(10000, dtype=np.int8)
    u[1000:] = 1  # edge at t = 0.1 s
    p = simulate(u, dt, P, p0=0.2)
    t = np.arange(u.size) * dt
    # before the edge: exhausting from 0.2 bar
    np.testing.assert_allclose(p[:1001], discharge(0.2, t[:1001], P), atol=1e-13)
    p_edge = p[1000]
    hold_end = 1000 + round(P.t_on / dt)
    # during t_on the pressure holds exactly
    np.testing.assert_allclose(p[1000 : hold_end + 1], p_edge, rtol=0, atol=1e-14)
    # afterwards: charging from p_edge, delayed by t_on
    tail = t[hold_end:] - t[hold_end]
    np.testing.assert_allclose(p[hold_end:], charge(p_edge, tail, P), atol=1e-12)


@pytest.mark.parametrize("level", [0, 1])
def test_short_pulse_inside_the_hold_changes_nothing(level):
    """A high pulse shorter than t_on (or a low pulse shorter than t_off) does nothing."""
    dt = 1e-4
    hold = P.t_on if level == 0 else P.t_off  # pulse to the other state
    width = round(hold / dt) - 1  # strictly shorter than the hold
    u = np.full(4000, level, dtype=np.int8)
    u[1000 : 1000 + width] = 1 - level
    p0 = 0.4
    baseline = simulate(np.full(4000, level, dtype=np.int8), dt, P, p0=p0)
    p = simulate(u, dt, P, p0=p0)
    # pressure is frozen during the pulse and the following hold of the original command
    frozen_until = 1000 + width + round((P.t_off if level == 0 else P.t_on) / dt)
    np.testing.assert_allclose(p[1000 : frozen_until + 1], baseline[1000], rtol=0, atol=1e-14)
    # and afterwards the response is the baseline shifted by the frozen time
    shift = frozen_until - 1000
    np.testing.assert_allclose(p[frozen_until:], baseline[1000 : 4000 - shift], atol=1e-12)


def test_pulse_longer_than_hold_does_act():
    dt = 1e-4
    width = round(P.t_on / dt) + 20  # 2 ms of charging
    u = np.zeros(2000, dtype=np.int8)
    u[500 : 500 + width] = 1
    p = simulate(u, dt, P, p0=0.0)
    assert p.max() == pytest.approx(charge(0.0, 20 * dt, P), rel=1e-9)


def test_pseudo_steady_state_matches_appendix_b():
    """Fixed t_h, t_l train: extrema converge to Appendix B's P+ and P- (to 1e-6 bar)."""
    t_h, t_l = 0.030, 0.025
    dt = 1e-4
    nh, nl = round(t_h / dt), round(t_l / dt)
    cycles = 400
    u = np.tile(np.r_[np.ones(nh, np.int8), np.zeros(nl, np.int8)], cycles)
    p = simulate(u, dt, P)
    h = max(t_h - P.t_on, 0.0)
    l_ = max(t_l - P.t_off, 0.0)
    e = math.exp(-h / P.tau2)
    beta = l_ / (2 * P.c1)
    sq = -e * beta / (1 - e) + math.sqrt(P.k2 + e * beta**2 / (1 - e) ** 2)
    p_plus, p_minus = sq**2, (sq - beta) ** 2
    last = p[-(nh + nl) :]
    # the last cycle starts with the rising edge at P-, the falling edge is at P+
    assert last[0] == pytest.approx(p_minus, abs=1e-6)
    assert last[nh] == pytest.approx(p_plus, abs=1e-6)
    assert last.max() == pytest.approx(p_plus, abs=1e-6)
    assert last.min() == pytest.approx(p_minus, abs=1e-6)


@settings(max_examples=60, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    n=st.integers(1, 3000),
    dt=st.sampled_from([1e-5, 1e-4, 3e-4, 1e-3, 4e-3]),
    p0=st.floats(0.0, 1.5),
    run=st.integers(1, 60),
    c1=st.floats(0.1, 2.0),
    k2=st.floats(0.2, 5.0),
    tau2=st.floats(0.05, 3.0),
    t_on=st.floats(1e-4, 0.05),
    t_off=st.floats(1e-4, 0.05),
)
def test_matches_per_sample_reference(seed, n, dt, p0, run, c1, k2, tau2, t_on, t_off):
    rng = np.random.default_rng(seed)
    params = ValveParams(c1=c1, k2=k2, tau2=tau2, t_on=t_on, t_off=t_off)
    u = np.repeat(rng.integers(0, 2, n // run + 1), run)[:n].astype(np.int8)
    np.testing.assert_allclose(
        simulate(u, dt, params, p0), ref.simulate(u, dt, params, p0), atol=1e-11
    )


def test_pressure_stays_within_physical_bounds():
    rng = np.random.default_rng(1)
    u = rng.integers(0, 2, 50000).astype(np.int8)
    p = simulate(u, 1e-4, P, p0=0.3)
    assert p.min() >= 0.0
    assert p.max() <= P.k2


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"u": [0, 2, 1], "dt": 1e-3}, r"u\[1\]"),
        ({"u": [[0, 1]], "dt": 1e-3}, "one-dimensional"),
        ({"u": [0, 1], "dt": 0.0}, "dt"),
        ({"u": [0, 1], "dt": float("nan")}, "dt"),
        ({"u": [0, 1], "dt": 1e-3, "p0": -0.1}, "p0"),
        ({"u": ["a", "b"], "dt": 1e-3}, "u must hold numbers"),
    ],
)
def test_bad_input_names_the_argument(kwargs, match):
    with pytest.raises(ValueError, match=match):
        simulate(**kwargs)


def test_empty_and_bool_inputs():
    assert simulate(np.zeros(0, np.int8), 1e-3).size == 0
    np.testing.assert_array_equal(
        simulate(np.array([True, True, False]), 1e-3), simulate(np.array([1, 1, 0]), 1e-3)
    )


@pytest.mark.parametrize("field", ["c1", "k2", "tau2", "t_on", "t_off"])
@pytest.mark.parametrize("value", [-1.0, float("nan"), float("inf"), "x"])
def test_valve_params_reject_bad_values_naming_the_field(field, value):
    with pytest.raises(ValueError, match=f"ValveParams.{field}"):
        ValveParams(**{field: value})


@pytest.mark.parametrize("field", ["c1", "k2", "tau2"])
def test_valve_params_reject_zero_rates_but_allow_zero_delays(field):
    with pytest.raises(ValueError, match=f"ValveParams.{field} must be finite and > 0"):
        ValveParams(**{field: 0.0})
    assert ValveParams(t_on=0.0, t_off=0.0).t_on == 0.0  # an ideal valve switches at once


def test_segment_pressure_is_the_closed_form_of_eqs_a1_a2():
    """One plant function: charging k2 + (p - k2) e^(-t/tau2), exhausting (sqrt(p) - t/2c1)^2."""
    from spa.model.plant import segment_pressure

    prm = ValveParams(c1=0.4, k2=0.9, tau2=0.7)
    t = np.array([0.0, 0.05, 0.3, 1.0, 5.0])
    np.testing.assert_allclose(
        segment_pressure(True, 0.2, t, prm), 0.9 + (0.2 - 0.9) * np.exp(-t / 0.7), rtol=1e-15
    )
    expected = np.maximum(np.sqrt(0.6) - t / 0.8, 0.0) ** 2
    np.testing.assert_allclose(segment_pressure(False, 0.6, t, prm), expected, rtol=1e-15)
    assert segment_pressure(False, 0.6, 10.0, prm) == 0.0  # empty, and stays empty
    mixed = segment_pressure(np.array([True, False]), np.array([0.2, 0.6]), 0.3, prm)
    assert mixed[0] == segment_pressure(True, 0.2, 0.3, prm)
    assert mixed[1] == segment_pressure(False, 0.6, 0.3, prm)
    runs = segment_pressure(np.array([True, False]), [0.2, 0.6], t[:4], prm, repeats=[2, 2])
    np.testing.assert_array_equal(runs[:2], segment_pressure(True, 0.2, t[:2], prm))
    np.testing.assert_array_equal(runs[2:], segment_pressure(False, 0.6, t[2:4], prm))


def test_valve_params_nominal_values_are_the_papers():
    assert ValveParams().as_dict() == {
        "c1": 0.533,
        "k2": 0.837,
        "tau2": 0.826,
        "t_on": 0.003,
        "t_off": 0.010,
    }


def test_simulate_names_the_bad_argument():
    u = np.ones(10, dtype=np.int8)
    np.testing.assert_array_equal(simulate(u, np.int64(1)), simulate(u, 1.0))  # numpy integers
    with pytest.raises(TypeError, match="params must be a ValveParams, got dict"):
        simulate(u, 1e-3, {"c1": 0.5})
    with pytest.raises(TypeError, match="dt must be a number"):
        simulate(u, "1e-3")
    with pytest.raises(ValueError, match="p0 must be finite and >= 0 bar"):
        simulate(u, 1e-3, p0=-0.1)
