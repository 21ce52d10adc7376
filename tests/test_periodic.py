"""The exact periodic steady state against long exact simulations, closed forms, invariants."""

from __future__ import annotations

from math import gcd

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from spa import ValveParams, charge, discharge, modulate, simulate
from spa.model.averaging import equilibrium, pseudo_steady_state
from spa.model.periodic import (
    charge_integral,
    discharge_integral,
    dsm_mean,
    dsm_runs,
    train_mean,
)
from spa.model.steady_state import periodic_mean

P = ValveParams()


def simulated_cycle_mean(
    kind: str, xi: float, cycle: float, params: ValveParams, dt: float, settings_: dict
) -> float:
    """Mean pressure over the last 20 cycles of a long exact run at constant ``xi``.

    The run starts at the averaged equilibrium (only the transient depends on it) and lasts
    long enough for the orbit to settle to well below 1e-7 bar.
    """
    steps = round(cycle / dt)
    assert abs(steps * dt - cycle) < 1e-12 * cycle, "the cycle must be whole steps"
    n = max(round(25.0 / dt), 40 * steps)
    u = modulate(kind, np.full(n, xi), dt, **settings_)
    p0 = float(equilibrium(kind, xi, params, **settings_)) if kind != "dsm" else 0.0
    p = simulate(u, dt, params, p0=p0)
    return float(p[-20 * steps :].mean())


# kind, xi, settings, cycle length (s): a normal train, the dead-zone, saturation, a train
# that empties the actuator every cycle, IIPFM with the Eq. 17 gain, and ΔΣ patterns with
# runs shorter than t_off (held, never discharging) and clock periods below t_on.
CASES = [
    ("pwm", 0.3, {"f_w": 20.0}, 0.05),
    ("pwm", 0.04, {"f_w": 20.0}, 0.05),  # t_h = 2 ms < t_on: never charges
    ("pwm", 0.9, {"f_w": 20.0}, 0.05),  # t_l = 5 ms < t_off: never discharges
    ("ipfm", 0.25, {"t_h": 0.02}, 0.08),  # xi exact in binary: no float drift of firings
    ("ipfm", 0.05, {"t_h": 0.05}, 1.0),  # t_l = 0.95 s: empties every cycle
    ("iipfm", 0.5, {"t_l": 0.02, "gain": 1.15}, 0.046),
    ("dsm", 0.3, {"period": 0.02}, 0.2),
    ("dsm", 2 / 7, {"period": 0.01}, 0.07),  # single lows last exactly t_off
    ("dsm", 0.75, {"period": 0.005}, 0.02),  # single lows shorter than t_off
    ("dsm", 0.1, {"period": 0.002}, 0.02),  # single highs shorter than t_on
]


@pytest.mark.parametrize(("kind", "xi", "settings_", "cycle"), CASES)
def test_cycle_mean_equals_a_long_exact_simulation(kind, xi, settings_, cycle):
    """Issue 14: the exact cycle mean agrees with long exact runs within 1e-6 bar."""
    expected = simulated_cycle_mean(kind, xi, cycle, P, 1e-4, settings_)
    assert float(periodic_mean(kind, xi, P, **settings_)) == pytest.approx(expected, abs=1e-6)


def test_cycle_mean_of_a_non_nominal_valve():
    params = ValveParams(c1=0.45, k2=1.05, tau2=0.70, t_on=0.004, t_off=0.009)
    for kind, xi, s, cycle in [("pwm", 0.5, {"f_w": 16.0}, 0.0625),
                               ("dsm", 0.4, {"period": 0.0245}, 0.1225)]:  # fmt: skip
        expected = simulated_cycle_mean(kind, xi, cycle, params, 1e-4 / 2, s)
        assert float(periodic_mean(kind, xi, params, **s)) == pytest.approx(expected, abs=1e-6)


def test_the_limits_of_the_train():
    assert train_mean(np.inf, 0.02, P) == P.k2  # always high
    assert train_mean(0.02, np.inf, P) == 0.0  # always low
    assert train_mean(0.0, 0.02, P) == 0.0
    assert train_mean(0.02, 0.0, P) == P.k2
    assert train_mean(P.t_on, 0.02, P) == 0.0  # a high as long as the hold never charges
    assert train_mean(0.02, P.t_off, P) == P.k2


def test_the_orbit_is_a_fixed_point_of_the_plants_closed_forms():
    t_h, t_l = 0.017, 0.031
    hi, lo = pseudo_steady_state(t_h, t_l, P)
    assert charge(lo, t_h - P.t_on, P) == pytest.approx(hi, abs=1e-15)
    assert discharge(hi, t_l - P.t_off, P) == pytest.approx(lo, abs=1e-15)


@pytest.mark.parametrize(("p0", "elapsed"), [(0.0, 0.3), (0.5, 0.02), (0.837, 1.0)])
def test_charge_integral_against_quadrature(p0, elapsed):
    s = np.linspace(0.0, elapsed, 20001)
    p = charge(p0, s, P)
    area = float(np.sum((p[1:] + p[:-1]) / 2 * np.diff(s)))
    exact = float(charge_integral(p0, p[-1], elapsed, P))
    assert exact == pytest.approx(area, rel=1e-8, abs=1e-15)


@pytest.mark.parametrize(("p0", "elapsed"), [(0.8, 0.05), (0.3, 2.0), (0.0, 0.1)])
def test_discharge_integral_against_quadrature(p0, elapsed):
    """Including a discharge that empties the actuator half-way (0.3 bar in 2 s)."""
    s = np.linspace(0.0, elapsed, 200001)
    p = discharge(p0, s, P)
    area = float(np.sum((p[1:] + p[:-1]) / 2 * np.diff(s)))
    assert float(discharge_integral(p0, p[-1], P)) == pytest.approx(area, rel=1e-8, abs=1e-12)


@given(p=st.integers(1, 60), q=st.integers(2, 61))
@settings(max_examples=60, deadline=None)
def test_dsm_runs_are_the_modulators_pattern(p, q):
    if p >= q:
        return
    g = gcd(p, q)
    p, q = p // g, q // g
    runs = dsm_runs(p / q)
    assert sum(runs) == q and sum(runs[::2]) == p and len(runs) % 2 == 0
    u = modulate("dsm", np.full(3 * q, p / q), 1.0, period=1.0)
    pattern = np.repeat(np.arange(len(runs)) % 2 == 0, runs).astype(np.int8)
    # the modulator's output is the pattern, rotated to start where it starts
    assert any(np.array_equal(u[k : k + q], pattern) for k in range(q))


def test_dsm_two_run_patterns_are_two_level_trains():
    for q, period in [(2, 0.02), (5, 0.015), (9, 0.03)]:
        exact = dsm_mean(1.0 / q, period, P)
        assert exact == pytest.approx(train_mean(period, (q - 1) * period, P), abs=1e-12)
    assert dsm_mean(0.0, 0.02, P) == 0.0
    assert dsm_mean(1.0, 0.02, P) == P.k2


def test_dsm_mean_broadcasts_like_a_loop():
    xi = np.linspace(0.0, 1.0, 12)
    periods = np.array([0.0125, 0.02, 0.1])
    together = dsm_mean(xi, periods[:, None], P, max_denominator=11)
    for i, t in enumerate(periods):
        for j, x in enumerate(xi):
            assert together[i, j] == pytest.approx(float(dsm_mean(x, t, P)), abs=1e-13)


@given(xi=st.lists(st.floats(0.0, 1.0), min_size=2, max_size=8))
@settings(max_examples=40, deadline=None)
def test_pwm_cycle_mean_grows_with_the_duty(xi):
    x = np.sort(np.array(xi))
    mean = periodic_mean("pwm", x, P, f_w=20.0)
    assert np.all(np.diff(mean) >= -1e-12)
    assert np.all((mean >= 0.0) & (mean <= P.k2))


def test_fast_switching_cycle_mean_tends_to_eq5():
    """Periods and delays shrunk together at fixed fractions: the mean -> Eq. 5."""
    errors = []
    for scale in (1.0, 0.1, 0.01):
        params = ValveParams(t_on=P.t_on * scale, t_off=P.t_off * scale)
        exact = periodic_mean("pwm", 0.5, params, f_w=20.0 / scale)
        errors.append(abs(exact - equilibrium("pwm", 0.5, params, f_w=20.0 / scale)))
    assert errors[0] > 10 * errors[1] > 100 * errors[2]


@pytest.mark.parametrize(
    ("call", "match"),
    [
        (lambda: dsm_mean(0.5, 0.0, P), "period"),
        (lambda: dsm_mean(np.nan, 0.02, P), "xi"),
        (lambda: dsm_runs(1.5), "xi"),
        (lambda: periodic_mean("dsm", 0.5, P, f_w=20.0), "unknown setting"),
        (lambda: train_mean(-1.0, 0.02, P), "t_h and t_l"),
    ],
)
def test_bad_arguments_name_themselves(call, match):
    with pytest.raises(ValueError, match=match):
        call()
