"""PI design from the averaged model, and the closed-loop metrics' definitions."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest

from spa.closedloop.design import design_pi, feedforward, local_models, simc
from spa.closedloop.experiments import (
    LoopUnderTest,
    Staircase,
    run_staircase,
    staircase_reference,
)
from spa.closedloop.metrics import cycle_mean, sine_metrics, step_metrics, steps
from spa.model.averaging import equilibrium, time_constant, time_fractions
from spa.model.modulators import Modulator
from spa.model.params import ValveParams

P = ValveParams()
IIPFM = Modulator.from_mapping({"type": "iipfm", "t_l": 0.02, "gain": 1.15})
PWM = Modulator.from_mapping({"type": "pwm", "f_w": 20.0})
LEVELS = [0.05, 0.25, 0.45, 0.65]


@pytest.mark.parametrize("mod", [IIPFM, PWM], ids=lambda m: m.label)
def test_feedforward_inverts_the_equilibrium(mod: Modulator) -> None:
    r = np.linspace(0.05, 0.75, 8)
    xi = feedforward(r, mod, P)
    np.testing.assert_allclose(equilibrium(mod.kind, xi, P, **mod.settings), r, atol=2e-3)


def test_local_models_are_the_averaged_derivative_and_eq9() -> None:
    m = local_models([0.2, 0.5], IIPFM, P)
    h = 1e-4
    up = equilibrium("iipfm", m.xi + h, P, **IIPFM.settings)
    down = equilibrium("iipfm", m.xi - h, P, **IIPFM.settings)
    np.testing.assert_allclose(m.gain, (up - down) / (2 * h), rtol=2e-3)
    a1, a2 = time_fractions("iipfm", m.xi, P, **IIPFM.settings)
    np.testing.assert_allclose(m.tau, time_constant(a1, a2, P), rtol=1e-12)
    # Dead time: mean valve delay plus half the IIPFM period t_l*G/(1 - xi).
    period = 0.02 * 1.15 / (1.0 - m.xi)
    np.testing.assert_allclose(m.dead_time, 0.0065 + period / 2, rtol=1e-9)


def test_simc_rule() -> None:
    kp, ki = simc([1.0, 2.0], [0.5, 0.5], [0.02, 0.02], tau_c=0.2)
    np.testing.assert_allclose(kp, [0.5 / 0.22, 0.5 / 0.44])
    np.testing.assert_allclose(ki, kp / 0.5)  # Ti = min(tau, 4*(tau_c + theta)) = tau
    _, ki_slow = simc(1.0, 5.0, 0.02, tau_c=0.2)
    assert float(ki_slow) == pytest.approx(5.0 / 0.22 / 0.88)


def test_design_schedules_simc_over_the_levels() -> None:
    d = design_pi(IIPFM, P, levels=LEVELS, tau_c=0.2)
    m = local_models(LEVELS, IIPFM, P)
    kp, ki = simc(m.gain, m.tau, m.dead_time, 0.2)
    assert d["scheduled"].schedule == tuple(LEVELS)
    np.testing.assert_allclose(d["scheduled"].kp, kp)
    np.testing.assert_allclose(d["scheduled"].ki, ki)
    assert d["scheduled"].feedforward is None
    np.testing.assert_allclose(d["scheduled_ff"].feedforward[1], m.xi)
    mid = local_models([np.median(LEVELS)], IIPFM, P)
    kp_mid, _ = simc(mid.gain, mid.tau, mid.dead_time, 0.2)
    assert d["fixed"].kp == pytest.approx(float(kp_mid[0]))
    with pytest.raises(ValueError, match="no local model"):
        design_pi(PWM, P, levels=[0.05, 0.9])  # 0.9 bar is above k2


@pytest.mark.parametrize("name", ["fixed", "scheduled", "scheduled_ff"])
def test_designed_pi_tracks_the_staircase_without_offset(name: str) -> None:
    ctrl = design_pi(IIPFM, P, levels=LEVELS)[name]
    run, m = run_staircase(LoopUnderTest(IIPFM, ctrl, P), Staircase(LEVELS, 3.0, 1e-3))
    assert len(m) == 2 * len(LEVELS) - 2
    assert np.all(np.abs(m["steady_state_error"]) < 0.01)
    assert np.all(m["rise_time"] < 1.5)
    assert run["valve"].isin([0, 1]).all()


def _first_order(tau: float, t_end: float = 3.0) -> pd.DataFrame:
    t = np.arange(round(t_end / 1e-3)) * 1e-3
    r = np.where(t < 1.0, 0.2, 0.6)
    p = np.where(t < 1.0, 0.2, 0.6 - 0.4 * np.exp(-(t - 1.0) / tau))
    return pd.DataFrame({"t": t, "r": r, "p": p, "valve": 0})


def test_step_metrics_of_a_first_order_response() -> None:
    tau = 0.1
    m = step_metrics(_first_order(tau), 1e-3).iloc[-1]
    assert (m.r0, m.r1, m.t0) == (0.2, 0.6, 1.0)
    assert m.rise_time == pytest.approx(math.log(9) * tau, abs=2e-3)
    assert m.overshoot == 0.0
    assert m.settling_time == pytest.approx(math.log(50) * tau, abs=2e-3)
    assert m.iae == pytest.approx(0.4 * tau, rel=1e-2)
    assert m.itae == pytest.approx(0.4 * tau**2, rel=2e-2)
    assert abs(m.steady_state_error) < 1e-6


def test_step_metrics_overshoot_ripple_and_switching() -> None:
    t = np.arange(4000) * 1e-3
    r = np.where(t < 1.0, 0.0, 1.0)
    # A decaying oscillation peaking 25 % above the set-point, plus 50 Hz ripple.
    resp = 1.0 - np.exp(-(t - 1.0) / 0.3) * np.cos(2 * np.pi * (t - 1.0) * 0.6)
    p = np.where(t < 1.0, 0.0, resp) + 0.01 * np.sin(2 * np.pi * 50 * t)
    valve = ((t * 100).astype(int) % 2).astype(np.int8)  # an edge every 10 ms: 100 per s
    m = step_metrics(pd.DataFrame({"t": t, "r": r, "p": p, "valve": valve}), 0.02).iloc[-1]
    peak = np.max(np.where(t < 1.0, 0.0, resp)) - 1.0
    assert m.overshoot == pytest.approx(100 * peak, abs=0.5)
    assert m.ripple_pp == pytest.approx(0.02, abs=2e-3)
    assert m.ripple_rms == pytest.approx(0.01 / math.sqrt(2), abs=1e-3)
    assert m.switching_rate == pytest.approx(100.0, rel=0.01)


def test_settling_is_nan_when_the_response_never_settles() -> None:
    run = _first_order(5.0)
    assert math.isnan(step_metrics(run, 1e-3).iloc[-1].settling_time)


def test_cycle_mean_removes_a_periodic_ripple() -> None:
    x = 0.3 + 0.05 * np.sign(np.sin(2 * np.pi * np.arange(1000) / 20 + 0.1))
    np.testing.assert_allclose(cycle_mean(x, 20)[20:-20], 0.3, atol=1e-12)


def test_steps_and_staircase_reference() -> None:
    r = staircase_reference([0.1, 0.3, 0.5], 0.003, 0.001)
    assert steps(r) == [(0, 3), (3, 6), (6, 9), (9, 12), (12, 15)]
    assert r[-1] == 0.1


def test_sine_metrics_of_a_known_lag() -> None:
    t = np.arange(20000) * 1e-3
    r = 0.4 + 0.1 * np.sin(2 * np.pi * 0.5 * t)
    p = 0.4 + 0.08 * np.sin(2 * np.pi * 0.5 * t - math.radians(30))
    m = sine_metrics(pd.DataFrame({"t": t, "r": r, "p": p}), 0.5, skip=2.0)
    assert m["gain"] == pytest.approx(0.8, abs=1e-6)
    assert m["phase"] == pytest.approx(-30.0, abs=1e-4)
    # RMS of the difference of two sines: |0.1 - 0.08 e^{-i30deg}| / sqrt(2).
    expected = abs(0.1 - 0.08 * np.exp(-1j * math.radians(30))) / math.sqrt(2)
    assert m["rms_error"] == pytest.approx(expected, rel=1e-3)


def test_a_loop_started_at_the_feedforward_stays_near_its_level() -> None:
    from spa.closedloop.loop import simulate_closed_loop

    ctrl = design_pi(IIPFM, P, levels=LEVELS)["fixed"]
    xi0 = float(feedforward([0.4], IIPFM, P)[0])
    settled = simulate_closed_loop(np.full(2000, 0.4), 1e-3, IIPFM, ctrl, P, 0.4, integral0=xi0)
    cold = simulate_closed_loop(np.full(2000, 0.4), 1e-3, IIPFM, ctrl, P, 0.4)
    assert np.abs(settled["p"] - 0.4).max() < 0.03
    assert np.abs(cold["p"] - 0.4).max() > 0.05  # with I = 0 the actuator first empties
