"""The transport-delay convention of the exact simulator against a small-step reference."""

from __future__ import annotations

import math

import numpy as np
import pytest

from spa.model.params import ValveParams
from spa.model.plant import replay, simulate, transport_runs


def _brute(u: np.ndarray, dt: float, prm: ValveParams, p0: float, sub: int = 64) -> np.ndarray:
    """Plain-Python reference: the plant follows the latest command edge whose transport delay
    has elapsed, stepped with the exact one-step map at ``dt/sub``."""
    k = [0] + [i for i in range(1, u.size) if u[i] != u[i - 1]]
    reach = [0.0] + [i * dt + (prm.t_on if u[i] else prm.t_off) for i in k[1:]]
    h = dt / sub
    p, out = p0, []
    for i in range(u.size):
        out.append(p)
        for m in range(sub):
            t = i * dt + (m + 0.5) * h
            last = max(j for j, r in enumerate(reach) if r <= t)
            if u[k[last]]:
                p = prm.k2 + (p - prm.k2) * math.exp(-h / prm.tau2)
            else:
                r = math.sqrt(p) - h / (2 * prm.c1)
                p = r * r if r > 0 else 0.0
    return np.array(out)


@pytest.mark.parametrize(
    "prm",
    [
        ValveParams(t_on=0.009, t_off=0.038),  # exhaust slower: low pulses cancel
        ValveParams(c1=0.3, k2=2.0, tau2=0.2, t_on=0.020, t_off=0.0025),  # high pulses cancel
        ValveParams(t_on=0.0, t_off=0.0),
    ],
)
def test_transport_matches_small_step_reference(prm: ValveParams) -> None:
    rng = np.random.default_rng(3)
    u = np.repeat(rng.integers(0, 2, 120).astype(np.int8), rng.integers(1, 30, 120))[:500]
    got = simulate(u, 1e-3, prm, 0.15, delay="transport")
    np.testing.assert_allclose(got, _brute(u, 1e-3, prm, 0.15), atol=1e-11)


def test_hold_is_the_default_and_unchanged() -> None:
    rng = np.random.default_rng(4)
    u = np.repeat(rng.integers(0, 2, 200).astype(np.int8), rng.integers(1, 40, 200))
    prm = ValveParams(t_on=0.007, t_off=0.012)
    np.testing.assert_array_equal(
        simulate(u, 1e-3, prm, 0.1), simulate(u, 1e-3, prm, 0.1, delay="hold")
    )


def test_transport_is_the_command_shifted_when_delays_are_equal() -> None:
    """With t_on = t_off = d the plant sees u(t - d): the zero-delay model of the shifted
    command (an invariant, exact on the grid when d is a whole number of steps)."""
    rng = np.random.default_rng(5)
    u = np.repeat(rng.integers(0, 2, 60).astype(np.int8), rng.integers(1, 50, 60))
    dt, shift = 1e-3, 7
    prm = ValveParams(t_on=shift * dt, t_off=shift * dt)
    zero = ValveParams(prm.c1, prm.k2, prm.tau2, 0.0, 0.0)
    shifted = np.r_[np.full(shift, u[0], dtype=np.int8), u[:-shift]]
    np.testing.assert_allclose(
        simulate(u, dt, prm, 0.2, delay="transport"), simulate(shifted, dt, zero, 0.2), atol=1e-12
    )


def test_the_pressure_keeps_moving_during_the_dead_time() -> None:
    """Unlike the hold convention, the previous connection persists after an edge."""
    prm = ValveParams(t_on=0.01, t_off=0.02)
    u = np.r_[np.ones(100), np.zeros(100)].astype(np.int8)
    hold = simulate(u, 1e-3, prm, 0.0, delay="hold")
    trans = simulate(u, 1e-3, prm, 0.0, delay="transport")
    assert hold[100] == hold[110]  # held still after the falling edge
    assert trans[110] > trans[100]  # still charging for t_off
    assert trans[121] < trans[120]  # exhausting after t_off


def test_a_pulse_shorter_than_the_delay_difference_is_cancelled() -> None:
    starts, level = transport_runs([0.0, 1.0, 1.02], [True, False, True], [0.0, 0.038, 0.009])
    assert starts.tolist() == [0.0] and level.tolist() == [True]
    starts, level = transport_runs([0.0, 1.0, 1.04], [True, False, True], [0.0, 0.038, 0.009])
    np.testing.assert_allclose(starts, [0.0, 1.038, 1.049])
    assert level.tolist() == [True, False, True]


def test_replay_transport_equals_simulate_on_the_grid() -> None:
    rng = np.random.default_rng(6)
    u = np.repeat(rng.integers(0, 2, 80).astype(np.int8), rng.integers(1, 40, 80))
    prm = ValveParams(t_on=0.0043, t_off=0.0171)
    dt = 1e-3
    t = np.arange(u.size) * dt
    k = np.r_[0, np.flatnonzero(u[1:] != u[:-1]) + 1]
    hold = np.where(u[k] == 1, prm.t_on, prm.t_off)
    hold[0] = 0.0
    np.testing.assert_array_equal(
        replay(t, t[k], u[k].astype(bool), hold, 0.3, prm, delay="transport"),
        simulate(u, dt, prm, 0.3, delay="transport"),
    )


def test_unknown_convention_is_named() -> None:
    with pytest.raises(ValueError, match="delay must be one of"):
        simulate(np.zeros(3, dtype=np.int8), 1e-3, delay="lag")
