"""Staircase and sine analyses against synthetic records with known answers."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from spa.openloop.linearity import (
    TAU_FRACTION,
    compensate_lag,
    linear_fit_metrics,
    sine_linearity,
    staircase_levels,
    step_time_constants,
)

DT = 1 / 1024  # exact in binary: window edges fall on samples
STEP = 4.0  # s per level
XI = np.round(np.arange(11) / 10, 12)  # the paper's staircase 0, 0.1, .., 1


def staircase_run(levels_p, tau, dt=DT, step=STEP, p0=0.0):
    """First-order response, time constant ``tau`` (one per step or a scalar), to a staircase.

    Level j holds ``u = XI[j]`` for ``step`` s and drives the pressure towards ``levels_p[j]``.
    """
    n_levels = len(levels_p)
    per_level = round(step / dt)
    t = np.arange(n_levels * per_level) * dt
    j = np.repeat(np.arange(n_levels), per_level)
    elapsed = t - j * step
    taus = np.broadcast_to(np.asarray(tau, dtype=float), (n_levels,))
    start = np.empty(n_levels)  # pressure at the start of each level
    p_prev = p0
    for k in range(n_levels):  # one iteration per level, not per sample
        start[k] = p_prev
        p_prev = levels_p[k] + (p_prev - levels_p[k]) * math.exp(-step / taus[k])
    p = levels_p[j] + (start[j] - levels_p[j]) * np.exp(-elapsed / taus[j])
    return pd.DataFrame({"t": t, "p": p, "u": XI[:n_levels][j]})


# ---------------------------------------------------------------- staircase_levels


def test_ripple_is_the_chattering_without_the_settling_tail():
    t = np.arange(0, 10, 1e-4)
    u = np.where(t < 5, 0.2, 0.4)
    square = 0.01 * np.sign(np.sin(2 * np.pi * 20 * t + 0.1))
    p = 0.3 + 0.05 * t + square  # a level still drifting by 0.1 bar over its window
    lv = staircase_levels(t, p, u, settle=0.4)
    np.testing.assert_allclose(lv["p_ripple"], 0.02, atol=1e-3)
    assert (lv["p_pp"] > 0.1).all()  # the drift of 0.05 bar/s over the 2 s window counts
    # the line's change over the window (2 s) is the drift (to 1 %: the square wave's
    # incomplete last period tilts the line); a square wave of amplitude a has sd a
    np.testing.assert_allclose(lv["p_drift"], 0.05 * 2.0, rtol=1e-2)
    np.testing.assert_allclose(lv["p_ripple_sd"], 0.01, rtol=1e-3)


def test_the_ripple_sd_of_a_triangle_is_its_range_over_root_12():
    t = np.arange(0, 10, 1e-4)
    tri = 0.02 * np.abs(((t * 20) % 1.0) - 0.5)  # 20 Hz triangle, range 0.01 bar
    lv = staircase_levels(t, 0.4 + tri, np.full(t.size, 0.5), settle=0.5)
    assert lv["p_ripple"].iloc[0] == pytest.approx(0.01, rel=1e-3)
    assert lv["p_ripple_sd"].iloc[0] == pytest.approx(0.01 / math.sqrt(12), rel=1e-3)
    assert abs(lv["p_drift"].iloc[0]) < 1e-6


def test_levels_of_a_settled_staircase():
    p_levels = 0.837 * XI
    run = staircase_run(p_levels, tau=0.2)
    lv = staircase_levels(run["t"], run["p"], run["u"])
    assert list(lv.columns) == [
        "level",
        "xi",
        "t_start",
        "t_end",
        "p_eq",
        "p_std",
        "p_pp",
        "p_ripple",
        "p_ripple_sd",
        "p_drift",
        "switching_rate",
        "n_window",
    ]
    np.testing.assert_array_equal(lv["level"], np.arange(11))
    np.testing.assert_array_equal(lv["xi"], XI)
    np.testing.assert_allclose(lv["t_start"], np.arange(11) * STEP, rtol=0, atol=1e-12)
    np.testing.assert_allclose(lv["t_end"], np.arange(1, 12) * STEP, rtol=0, atol=1e-12)
    # last 40 % of 4 s: samples with t >= t_end - 1.6 s, i.e. k*DT >= 2.4 s into the level:
    # k = 2458 .. 4095, 1638 samples
    np.testing.assert_array_equal(lv["n_window"], 1638)
    # settled for 2.4 s = 12 tau: exp(-12) * 0.0837 < 1e-6
    np.testing.assert_allclose(lv["p_eq"], p_levels, rtol=0, atol=1e-6)
    assert lv["p_pp"].max() < 1e-6 and lv["p_std"].max() < 1e-6
    assert lv["switching_rate"].isna().all()


def test_window_statistics_and_switching_rate_of_a_chattering_level():
    # Two levels of 4 s; on the second a 20 Hz square wave of +-0.05 bar around 0.4 bar,
    # in phase with a 20 Hz valve train of duty 0.5 (40 edges per second).
    t = np.arange(round(8 / DT)) * DT
    u = np.where(t < 4, 0.0, 0.5)
    phase = np.floor(t * 20 * 2).astype(int) % 2  # 25 ms high, 25 ms low
    valve = np.where(t < 4, 0, 1 - phase)
    p = np.where(t < 4, 0.0, 0.4 + 0.05 * np.where(phase == 0, 1.0, -1.0))
    lv = staircase_levels(t, p, u, valve, settle=0.5)
    second = lv.iloc[1]
    assert second["n_window"] == 2048
    assert second["p_eq"] == pytest.approx(0.4, abs=1e-12)
    assert second["p_std"] == pytest.approx(0.05, abs=1e-12)
    assert second["p_pp"] == pytest.approx(0.1, abs=1e-12)
    # Window: samples 6.0 s .. 8 s - DT. Edges where floor(40 t) changes: 40 t = 241 .. 319
    # (the one at 40 t = 240 is the window's first sample, not between two of its samples):
    # 79 edges over the 2047 sample periods between the window's ends, ~40 per second.
    assert second["switching_rate"] == pytest.approx(79 / (2047 * DT), rel=1e-12)
    assert lv.iloc[0]["switching_rate"] == 0.0


@settings(max_examples=30, deadline=None)
@given(
    values=st.lists(st.floats(-2, 2), min_size=2, max_size=6),
    lengths=st.lists(st.integers(1, 30), min_size=6, max_size=6),
    settle=st.floats(0.01, 1.0),
)
def test_constant_levels_are_recovered_for_any_settle(values, lengths, settle):
    lengths = lengths[: len(values)]
    u = np.repeat(np.arange(len(values)) / 10, lengths)  # distinct consecutive levels
    p = np.repeat(values, lengths)
    t = np.cumsum(np.full(u.size, 0.01)) + 3.0
    if t.size < 2:
        return
    lv = staircase_levels(t, p, u, settle=settle)
    np.testing.assert_allclose(lv["p_eq"], values, rtol=0, atol=1e-12)
    assert (lv["n_window"] >= 1).all() and (lv["n_window"] <= lengths).all()
    np.testing.assert_array_equal(lv["p_pp"], 0.0)


def test_a_single_level_and_a_non_uniform_clock():
    t = np.array([0.0, 0.1, 0.3, 0.35, 1.0])
    lv = staircase_levels(t, [1.0, 2.0, 3.0, 4.0, 5.0], np.full(5, 0.3), settle=0.5)
    assert len(lv) == 1
    # the level spans [0, 1.65) (one more sample period, 0.65 s), window t >= 0.825: one sample
    assert lv["t_end"].iloc[0] == pytest.approx(1.65)
    assert lv["n_window"].iloc[0] == 1 and lv["p_eq"].iloc[0] == 5.0


# ---------------------------------------------------------------- linear_fit_metrics


def test_a_perfectly_linear_staircase_fits_exactly():
    run = staircase_run(0.05 + 0.75 * XI, tau=0.15)
    lv = staircase_levels(run["t"], run["p"], run["u"])
    r = linear_fit_metrics(lv["xi"], lv["p_eq"])
    assert r["m"] == pytest.approx(0.75, abs=1e-9)
    assert r["n"] == pytest.approx(0.05, abs=1e-9)
    assert r["fit"] == pytest.approx(100.0, abs=1e-6)
    assert r["max_dev"] < 1e-9 and r["mse"] < 1e-18
    exact = linear_fit_metrics(XI, 0.05 + 0.75 * XI)
    assert exact["max_dev"] < 1e-15 and exact["mse"] < 1e-30
    assert exact["fit"] == pytest.approx(100.0, abs=1e-12)


def test_a_quadratic_gives_the_closed_form_line():
    # P = xi^2 on xi = 0, 0.1, .., 1. With d = xi - 1/2 (symmetric): cov(xi, xi^2) = var(xi)
    # = 0.1, so m = 1 and n = mean(xi^2) - mean(xi) = 0.35 - 0.5 = -0.15. Residual
    # d^2 - 0.1: largest at d = +-0.5, MD = 0.15; MSE = mean(d^4) - 0.01 = 0.0178 - 0.01;
    # ||P - mean P||^2 / 11 = var(d + d^2) = 0.1 + 0.0078.
    r = linear_fit_metrics(XI, XI**2)
    assert r["m"] == pytest.approx(1.0, abs=1e-12)
    assert r["n"] == pytest.approx(-0.15, abs=1e-12)
    assert r["max_dev"] == pytest.approx(0.15, abs=1e-12)
    assert r["mse"] == pytest.approx(0.0078, abs=1e-12)
    # |d^2 - 0.1| = 0.1, 0.09, 0.06, 0.01, 0.06, 0.15 (all but the first twice): 0.84 / 11
    assert r["mad"] == pytest.approx(0.84 / 11, abs=1e-12)
    assert r["fit"] == pytest.approx(100 * (1 - math.sqrt(0.0078 / 0.1078)), abs=1e-9)


def test_a_flat_response_has_no_fit_but_valid_errors():
    r = linear_fit_metrics([0, 0.5, 1], [0.8, 0.8, 0.8])
    assert math.isnan(r["fit"])
    assert r["m"] == 0.0 and r["n"] == pytest.approx(0.8) and r["max_dev"] == pytest.approx(0.0)


@settings(max_examples=60, deadline=None)
@given(
    p=st.lists(st.floats(-1, 1), min_size=3, max_size=12),
    a=st.floats(0.01, 100) | st.floats(-100, -0.01),
    b=st.floats(-100, 100),
)
def test_fit_is_invariant_to_affine_rescaling(p, a, b):
    p = np.asarray(p)
    xi = np.linspace(0, 1, p.size)
    base = linear_fit_metrics(xi, p)
    # the fitted line must explain little enough for FIT to be well conditioned
    if np.ptp(p) < 1e-3:
        return
    scaled = linear_fit_metrics(xi, a * p + b)
    assert scaled["fit"] == pytest.approx(base["fit"], abs=1e-6)
    assert scaled["m"] == pytest.approx(a * base["m"], abs=1e-9 * max(1.0, abs(a)))
    assert scaled["n"] == pytest.approx(a * base["n"] + b, abs=1e-8 * max(1.0, abs(a), abs(b)))
    assert scaled["max_dev"] == pytest.approx(abs(a) * base["max_dev"], rel=1e-6, abs=1e-9 * abs(a))
    assert scaled["mse"] == pytest.approx(a**2 * base["mse"], rel=1e-6, abs=1e-12 * a**2)
    assert scaled["mad"] == pytest.approx(abs(a) * base["mad"], rel=1e-6, abs=1e-9 * abs(a))
    assert base["max_dev"] >= base["mad"] * (1 - 1e-12)
    assert base["fit"] <= 100.0 + 1e-9
    assert base["max_dev"] ** 2 >= base["mse"] * (1 - 1e-12)  # the largest residual bounds the RMS


# ---------------------------------------------------------------- step_time_constants


def test_first_order_steps_give_their_time_constants():
    taus = np.linspace(0.2, 0.5, 11)  # a different tau for every level
    p_levels = 0.837 * XI**0.7
    run = staircase_run(p_levels, tau=taus)
    steps = step_time_constants(run["t"], run["p"], run["u"])
    assert list(steps.columns) == [
        "step",
        "xi_from",
        "xi_to",
        "t_start",
        "p_from",
        "p_to",
        "dp",
        "tau",
    ]
    np.testing.assert_array_equal(steps["step"], np.arange(1, 11))
    np.testing.assert_array_equal(steps["xi_from"], XI[:-1])
    np.testing.assert_array_equal(steps["xi_to"], XI[1:])
    # The window starts 2.4 s = 4.8 tau (at worst) into each level: the settled means are
    # within 0.3 % of the levels' changes, and tau within 1 %.
    np.testing.assert_allclose(steps["dp"], np.diff(p_levels), rtol=3e-3)
    np.testing.assert_allclose(steps["tau"], taus[1:], rtol=1e-2)


def test_an_exactly_settled_step_gives_tau_to_interpolation_accuracy():
    t = np.arange(0, 30, 1e-3)
    tau = 0.8473
    u = np.where(t < 10, 0.3, 0.7)
    p = np.where(t < 10, 0.2, 0.6 - 0.4 * np.exp(-(t - 10) / tau))
    steps = step_time_constants(t, p, u, settle=0.2)  # window from 26 s: exp(-19) ~ 0
    assert steps["tau"].iloc[0] == pytest.approx(tau, abs=1e-6)
    # any other fraction: t = -tau*ln(1 - fraction)
    half = step_time_constants(t, p, u, settle=0.2, fraction=0.5)
    assert half["tau"].iloc[0] == pytest.approx(tau * math.log(2), abs=1e-6)


def test_falling_steps_and_steps_without_change():
    p_levels = np.array([0.0, 0.5, 0.5, 0.2, 0.2 + 0.004])
    run = staircase_run(p_levels, tau=0.25)
    run["u"] = np.repeat([0.0, 0.6, 0.7, 0.3, 0.35], round(STEP / DT))
    steps = step_time_constants(run["t"], run["p"], run["u"])
    assert steps["tau"].iloc[0] == pytest.approx(0.25, rel=1e-2)
    assert math.isnan(steps["tau"].iloc[1])  # no change
    assert steps["tau"].iloc[2] == pytest.approx(0.25, rel=1e-2)  # falling
    assert math.isnan(steps["tau"].iloc[3])  # 4 mbar < min_change = 10 mbar
    loose = step_time_constants(run["t"], run["p"], run["u"], min_change=1e-3)
    assert loose["tau"].iloc[3] == pytest.approx(0.25, rel=1e-2)
    assert steps["tau"].mean() == pytest.approx(0.25, rel=1e-2)  # pandas skips NaN


def test_smoothing_removes_the_bias_of_chattering():
    tau, period = 0.6, 0.05
    run = staircase_run(np.array([0.1, 0.3, 0.5]), tau=tau)
    square = np.where(np.floor(run["t"] / (period / 2)).astype(int) % 2 == 0, 1.0, -1.0)
    p = run["p"] + 0.03 * square  # chattering of 60 mbar peak to peak on 200 mbar steps
    raw = step_time_constants(run["t"], p, run["u"])
    smooth = step_time_constants(run["t"], p, run["u"], smooth=period)
    assert (raw["tau"] < 0.9 * tau).all()  # the first crossing comes early
    np.testing.assert_allclose(smooth["tau"], tau, rtol=0.03)


def test_late_crossing_is_interpolated_and_a_missed_one_is_nan():
    t = np.arange(200) * 0.01
    u = np.where(t < 1, 0.0, 1.0)
    p = np.where(t < 1, 0.0, np.where(t < 1.895, 0.2, 1.0))  # jumps at the very end
    steps = step_time_constants(t, p, u, settle=0.05)  # p_to = 1: target 0.632
    # between t = 1.89 s (0.2 bar) and 1.90 s (1 bar)
    assert steps["tau"].iloc[0] == pytest.approx(0.89 + 0.01 * (TAU_FRACTION - 0.2) / 0.8)
    # Three samples at 1 bar at the end: p_to = 1 bar, but averaged over 0.5 s the pressure
    # never gets above ~0.12 bar: never reached.
    p = np.where(t < 1.965, 0.0, 1.0)
    steps = step_time_constants(t, p, u, settle=0.02, smooth=0.5)
    assert steps["p_to"].iloc[0] == 1.0
    assert math.isnan(steps["tau"].iloc[0])


def test_a_jump_at_the_first_sample_gives_zero():
    t = np.arange(0, 2, 0.01)
    u = np.where(t < 1, 0.0, 1.0)
    steps = step_time_constants(t, u * 0.5, u)
    assert steps["tau"].iloc[0] == 0.0
    assert TAU_FRACTION == pytest.approx(0.632, abs=5e-4)


# ---------------------------------------------------------------- sine


def piecewise_sine(delay, dt=1e-3, freq=0.5, amplitudes=(0.45, 0.3, 0.15), cycles=4):
    """Input 0.5 + A_i sin(2 pi f t) with A_i held for ``cycles`` periods each; its delay."""
    per = round(cycles / freq / dt)
    t = np.arange(per * len(amplitudes)) * dt
    amp = np.repeat(amplitudes, per)
    x = 0.5 + amp * np.sin(2 * np.pi * freq * t)
    x_late = np.concatenate((np.full(round(delay / dt), 0.5), x))[: t.size]
    return t, x, x_late


def test_cross_correlation_recovers_a_known_delay_through_a_nonlinearity():
    t, x, x_late = piecewise_sine(delay=0.173)
    p = 0.8 * x_late**1.5  # a static nonlinearity after a pure delay
    lag, ta, xa, pa = compensate_lag(t, x, p)
    assert lag == pytest.approx(0.173, abs=1e-9)
    assert ta.size == xa.size == pa.size == t.size - 173
    np.testing.assert_array_equal(ta, t[: ta.size])
    np.testing.assert_allclose(pa, 0.8 * xa**1.5, atol=1e-12)


def test_a_lead_is_found_only_when_allowed():
    rng = np.random.default_rng(5)
    t = np.arange(4000) * 0.01
    x = np.convolve(rng.standard_normal(4000), np.ones(5) / 5, mode="same")
    p = np.roll(x, -37)  # p leads x by 0.37 s
    lag, _, xa, pa = compensate_lag(t, x, p, causal=False)
    assert lag == pytest.approx(-0.37, abs=1e-9)
    np.testing.assert_array_equal(pa[: xa.size - 37], xa[: xa.size - 37])
    lag_causal, *_ = compensate_lag(t, x, p)
    assert lag_causal >= 0.0
    limited, *_ = compensate_lag(t, x, np.roll(x, 50), max_lag=0.3)  # true lag 0.5 s
    assert 0.0 <= limited <= 0.3


def test_normalised_pressure_against_the_identity_line():
    xi = np.linspace(0, 1, 100001)
    r = sine_linearity(xi, 0.7 * xi)
    assert r["p_max"] == 0.7 and r["max_dev"] < 1e-15 and r["rms"] < 1e-15
    # P = xi^2: deviation xi^2 - xi, mean square -> 1/5 - 1/2 + 1/3 = 1/30, largest 1/4
    r = sine_linearity(xi, 0.837 * xi**2)
    assert r["rms"] == pytest.approx(math.sqrt(1 / 30), rel=1e-4)
    assert r["max_dev"] == pytest.approx(0.25, abs=1e-12)
    assert r["p_max"] == pytest.approx(0.837)


@settings(max_examples=40, deadline=None)
@given(
    p=st.lists(st.floats(0.01, 1.0), min_size=2, max_size=20),
    scale=st.floats(1e-3, 1e3),
)
def test_sine_linearity_ignores_the_pressure_unit(p, scale):
    xi = np.linspace(0, 1, len(p))
    a = sine_linearity(xi, p)
    b = sine_linearity(xi, np.asarray(p) * scale)
    assert b["rms"] == pytest.approx(a["rms"], rel=1e-9, abs=1e-12)
    assert b["max_dev"] == pytest.approx(a["max_dev"], rel=1e-9, abs=1e-12)
    assert a["max_dev"] >= a["rms"] * (1 - 1e-12)


def test_sine_pipeline_recovers_the_static_curve():
    t, x, x_late = piecewise_sine(delay=0.08)
    p = 0.837 * x_late  # a linear actuator, delayed: perfectly linear after compensation
    lag, _, xa, pa = compensate_lag(t, x, p)
    r = sine_linearity(xa, pa)
    assert lag == pytest.approx(0.08, abs=1e-9)
    # p/max(p) = x/max(x), max(x) = 0.95: deviation x*(1/0.95 - 1)
    assert r["max_dev"] == pytest.approx(0.95 * (1 / 0.95 - 1), abs=1e-6)


# ---------------------------------------------------------------- bad input


T5 = np.arange(5.0)
P5 = np.ones(5)
U5 = np.array([0, 0, 0.5, 0.5, 0.5])


@pytest.mark.parametrize(
    ("call", "name"),
    [
        (lambda: staircase_levels([0, 1, 1, 2, 3], P5, U5), "t"),
        (lambda: staircase_levels([0.0], [1.0], [0.0]), "t"),
        (lambda: staircase_levels(T5, np.ones(4), U5), "p"),
        (lambda: staircase_levels(T5, P5, [0, 0, np.nan, 1, 1]), "u"),
        (lambda: staircase_levels(T5, P5, U5, [0, 1, 2, 0, 1]), "valve"),
        (lambda: staircase_levels(T5, P5, U5, settle=0.0), "settle"),
        (lambda: staircase_levels(T5, P5, U5, settle=1.5), "settle"),
        (lambda: staircase_levels(T5, P5, U5, atol=-1.0), "atol"),
        (lambda: staircase_levels(np.ones((5, 1)), P5, U5), "t"),
        (lambda: linear_fit_metrics([0.5, 0.5, 0.5], [1, 2, 3]), "xi"),
        (lambda: linear_fit_metrics([0, 1], [1, 2, 3]), "p_eq"),
        (lambda: linear_fit_metrics([0, 1], [1, np.inf]), "p_eq"),
        (lambda: step_time_constants(T5, P5, U5, fraction=0.0), "fraction"),
        (lambda: step_time_constants(T5, P5, U5, min_change=-0.1), "min_change"),
        (lambda: step_time_constants(T5, P5, U5, smooth=np.nan), "smooth"),
        (lambda: step_time_constants(T5, P5, U5, settle=2), "settle"),
        (lambda: compensate_lag([0, 1, 2, 4, 5], U5, np.arange(5.0)), "t"),
        (lambda: compensate_lag(T5, np.ones(5), np.arange(5.0)), "x_in"),
        (lambda: compensate_lag(T5, U5, P5), "p"),
        (lambda: compensate_lag(T5, U5, np.arange(5.0), max_lag=-1), "max_lag"),
        (lambda: sine_linearity([0, 1], [0, 0]), "p"),
        (lambda: sine_linearity([0, 1], [1, 2, 3]), "p"),
        (lambda: sine_linearity([0, np.nan], [1, 2]), "xi"),
    ],
)
def test_bad_input_names_the_argument(call, name):
    with pytest.raises(ValueError, match=rf"^{name}\b"):
        call()


# ---------------------------------------------------------------- the linear reference


def test_first_order_response_is_the_closed_form():
    from spa.openloop.reference import first_order_response

    t = np.arange(0, 10, 1e-3)
    step = first_order_response(t, np.ones(t.size), gain=0.8, tau=0.7, y0=0.1)
    np.testing.assert_allclose(step, 0.8 + (0.1 - 0.8) * np.exp(-t / 0.7), rtol=0, atol=1e-12)
    # a sine well after the start: gain/sqrt(1 + (w tau)^2), the phase lag atan(w tau)
    w, tau = 2 * np.pi * 0.5, 0.7
    y = first_order_response(t, np.sin(w * t), gain=1.0, tau=tau)
    late = t > 7
    expected = np.sin(w * (t - 5e-4) - math.atan(w * tau)) / math.hypot(1, w * tau)
    np.testing.assert_allclose(y[late], expected[late], atol=2e-3)  # held input: dt/2 delay
    with pytest.raises(ValueError, match="tau"):
        first_order_response(t, np.ones(t.size), gain=1.0, tau=0.0)
    with pytest.raises(ValueError, match="uniformly"):
        first_order_response([0.0, 1.0, 3.0], [1.0, 1.0, 1.0], gain=1.0, tau=1.0)
