"""The four modulators against the literal per-step rules and Appendix A."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from spa import check_settings, modulate

import reference as ref

DTS = st.sampled_from([1e-5, 1e-4, 2.5e-4, 1e-3])
XI = st.floats(0.0, 1.0)


def rising_edges(u: np.ndarray) -> int:
    return int(np.count_nonzero(np.diff(u.astype(int)) == 1))


def falling_edges(u: np.ndarray) -> int:
    return int(np.count_nonzero(np.diff(u.astype(int)) == -1))


# ---- literal rules --------------------------------------------------------------------


@st.composite
def cases(draw):
    kind = draw(st.sampled_from(["pwm", "ipfm", "iipfm", "dsm"]))
    dt = draw(DTS)
    n = draw(st.integers(1, 2500))
    hold = draw(st.integers(1, 300))
    # exclude sub-1e-6 fractions: there a one-ulp difference in event times flips a tie
    levels = draw(
        st.lists(XI.filter(lambda x: x == 0 or x > 1e-6), min_size=1, max_size=n // hold + 1)
    )
    xi = np.repeat(levels, hold)[:n]
    if xi.size < n:
        xi = np.pad(xi, (0, n - xi.size), mode="edge")
    steps = draw(st.floats(1.0, 150.0))
    if kind == "pwm":
        # a PWM period needs two controller steps, and a valve cannot follow 10 kHz
        steps = max(steps, 2.0, 1e-4 / dt)
        s = {"f_w": 1.0 / (steps * dt)}
    elif kind == "dsm":
        s = {"period": steps * dt}
    else:
        gain = draw(st.sampled_from([1.0, 1.15, 0.8, 2.0]))
        assume(gain * steps >= 1.0)
        s = {("t_h" if kind == "ipfm" else "t_l"): steps * dt, "gain": gain}
    return kind, xi, dt, s


@settings(max_examples=300, deadline=None)
@given(cases())
def test_matches_literal_per_step_rules(case):
    kind, xi, dt, s = case
    np.testing.assert_array_equal(modulate(kind, xi, dt, **s), ref.MODULATE[kind](xi, dt, **s))


def test_output_is_int8_zero_one_same_length():
    xi = np.linspace(0, 1, 1001)
    for kind, s in [
        ("pwm", {"f_w": 20}),
        ("ipfm", {"t_h": 0.02}),
        ("iipfm", {"t_l": 0.02}),
        ("dsm", {"period": 0.02}),
    ]:
        u = modulate(kind, xi, 1e-3, **s)
        assert u.dtype == np.int8
        assert u.shape == xi.shape
        assert set(np.unique(u)) <= {0, 1}


# ---- Appendix A: duty and firing frequency for constant input ----------------------


@settings(max_examples=80, deadline=None)
@given(xi=XI, dt=DTS, n_period=st.integers(2, 400), periods=st.integers(20, 60))
def test_pwm_duty_and_frequency(xi, dt, n_period, periods):
    assume(n_period * dt >= 1e-4)  # up to 10 kHz
    f_w = 1.0 / (n_period * dt)
    u = modulate("pwm", np.full(n_period * periods, xi), dt, f_w=f_w)
    # duty xi, to one step per period
    assert abs(u.mean() - xi) <= 1.0 / n_period + 1e-12
    # one pulse per period when 0 < duty < 1
    if 0 < u.mean() < 1 and round(xi * n_period) not in (0, n_period):
        assert rising_edges(u) in (periods - 1, periods)


@settings(max_examples=80, deadline=None)
@given(
    xi=st.floats(0.02, 1.0),
    dt=DTS,
    n_width=st.integers(1, 200),
    gain=st.sampled_from([1.0, 1.15, 1.5, 3.0]),
)
def test_ipfm_duty_and_frequency(xi, dt, n_width, gain):
    t_h = n_width * dt
    duration_steps = int(200 * gain * n_width / xi) + 10
    u = modulate("ipfm", np.full(duration_steps, xi), dt, t_h=t_h, gain=gain)
    duration = duration_steps * dt
    firings = np.floor(xi * (duration_steps - 1) / (gain * n_width) + 1e-9)
    gap = n_width * (gain / xi - 1)  # steady low time in steps
    if gap >= 2:  # separate pulses: frequency xi/(G t_h), width t_h
        assert rising_edges(u) == firings
        assert abs(rising_edges(u) / duration - xi / (gain * t_h)) <= 2.0 / duration + 1e-9
        assert abs(u.mean() - xi / gain) <= 2 * n_width / duration_steps
    elif xi >= gain:  # G = 1, xi = 1: the pulses join into one long high
        assert rising_edges(u) == 1
        assert falling_edges(u) == 0


@settings(max_examples=80, deadline=None)
@given(
    xi=st.floats(0.0, 0.98),
    dt=DTS,
    n_width=st.integers(1, 200),
    gain=st.sampled_from([1.0, 1.15, 1.5, 3.0]),
)
def test_iipfm_duty_and_frequency(xi, dt, n_width, gain):
    t_l = n_width * dt
    duration_steps = int(200 * gain * n_width / (1 - xi)) + 10
    u = modulate("iipfm", np.full(duration_steps, xi), dt, t_l=t_l, gain=gain)
    duration = duration_steps * dt
    assert u[0] == 1  # high by default
    gap = n_width * (gain / (1 - xi) - 1)  # steady high time in steps
    if gap >= 2:  # separate low pulses: frequency (1-xi)/(G t_l), low width t_l
        freq = falling_edges(u) / duration
        assert abs(freq - (1 - xi) / (gain * t_l)) <= 2.0 / duration + 1e-9
        assert abs((1 - u.mean()) - (1 - xi) / gain) <= 2 * n_width / duration_steps
    elif 1 - xi >= gain:  # G = 1, xi = 0: the low pulses join; stays low
        assert falling_edges(u) == 1
        assert rising_edges(u) == 0


@settings(max_examples=80, deadline=None)
@given(xi=XI, dt=DTS, n_period=st.integers(1, 100), ticks=st.integers(50, 400))
def test_dsm_duty_and_pattern(xi, dt, n_period, ticks):
    period = n_period * dt
    u = modulate("dsm", np.full(n_period * ticks, xi), dt, period=period)
    per_tick = u[::n_period]
    # first-order ΔΣ: running error |sum(xi) - sum(u)| <= 1/2 at every tick
    err = np.cumsum(np.full(ticks, xi)) - np.cumsum(per_tick)
    assert np.abs(err).max() <= 0.5 + 1e-9
    assert abs(per_tick.mean() - xi) <= 0.5 / ticks + 1e-12
    # true firing rate of the first-order pattern is min(xi, 1-xi)/T (isolated ones or zeros);
    # the paper's 2 xi (1-xi)/T is an approximation that agrees at 0, 1/2 and 1
    assert abs(rising_edges(u) / ticks - min(xi, 1 - xi)) <= 1.0 / ticks + 1e-9


def test_ipfm_with_unit_gain_stays_high_at_full_input():
    u = modulate("ipfm", np.ones(5000), 1e-4, t_h=0.02)
    first = int(np.argmax(u))
    assert first == 200  # integrator reaches G*t_h after 20 ms
    assert u[first:].all()


def test_iipfm_with_unit_gain_stays_low_at_zero_input():
    u = modulate("iipfm", np.zeros(5000), 1e-4, t_l=0.02)
    first = int(np.argmin(u))
    assert first == 200
    assert not u[first:].any()


def test_input_is_clipped_to_unit_interval():
    xi = np.array([-0.5, 2.0, 0.3] * 300)
    for kind, s in [
        ("pwm", {"f_w": 50}),
        ("ipfm", {"t_h": 0.005}),
        ("iipfm", {"t_l": 0.005}),
        ("dsm", {"period": 0.005}),
    ]:
        np.testing.assert_array_equal(
            modulate(kind, xi, 1e-3, **s), modulate(kind, np.clip(xi, 0, 1), 1e-3, **s)
        )


# ---- bad input ----------------------------------------------------------------------


@pytest.mark.parametrize(
    ("kind", "settings_", "match"),
    [
        ("pwm", {"f_w": 2000.0}, "f_w"),  # period 0.5 ms < dt = 1 ms
        ("pwm", {"f_w": -1.0}, "f_w"),
        ("pwm", {}, "missing setting 'f_w'"),
        ("pwm", {"f_w": 20, "t_h": 0.1}, "unknown setting"),
        ("ipfm", {"t_h": 0.0}, "t_h"),
        ("ipfm", {"t_h": 0.0005}, "t_h"),  # shorter than dt
        ("ipfm", {"t_h": 0.002, "gain": 0.1}, "gain"),  # threshold shorter than dt
        ("iipfm", {"t_l": float("nan")}, "t_l"),
        ("iipfm", {"t_l": 0.02, "gain": "x"}, "gain"),
        ("dsm", {"period": 0.0001}, "period"),
        ("sdm", {"period": 0.02}, "unknown modulator kind"),
    ],
)
def test_bad_settings_raise_naming_them(kind, settings_, match):
    with pytest.raises(ValueError, match=match):
        modulate(kind, np.full(100, 0.5), 1e-3, **settings_)


@pytest.mark.parametrize("bad", [np.nan, np.inf])
def test_non_finite_input_raises(bad):
    xi = np.full(10, 0.5)
    xi[3] = bad
    with pytest.raises(ValueError, match=r"xi\[3\]"):
        modulate("pwm", xi, 1e-3, f_w=20)


def test_bad_dt_raises():
    with pytest.raises(ValueError, match="dt"):
        modulate("pwm", np.full(10, 0.5), 0.0, f_w=20)


def test_settings_out_of_physical_range_are_refused_with_the_range():
    """A frequency of 1e-300 Hz or a PWM period shorter than two controller steps is a typo or
    a unit slip: the message names the setting and the allowed range."""
    xi = np.full(100, 0.5)
    with pytest.raises(ValueError, match=r"'f_w' = 1e-300 is outside .* \[0.001, 10000\] Hz"):
        modulate("pwm", xi, 1e-3, f_w=1e-300)
    with pytest.raises(ValueError, match="above half the controller rate"):
        modulate("pwm", xi, 1e-3, f_w=600.0)
    assert modulate("pwm", xi, 1e-3, f_w=500.0).size == 100  # two steps per period
    with pytest.raises(ValueError, match=r"'t_l' = 1e-300 is outside"):
        modulate("iipfm", xi, 1e-3, t_l=1e-300)
    for bad in (True, "20", None):
        with pytest.raises((TypeError, ValueError), match="f_w"):
            check_settings("pwm", f_w=bad)


def test_a_mapping_cannot_smuggle_check_settings_arguments():
    from spa import Modulator

    with pytest.raises(ValueError, match=r"pwm: unknown setting\(s\) \['dt'\]"):
        Modulator.from_mapping({"type": "pwm", "f_w": 20, "dt": 0.001})
    with pytest.raises(ValueError, match=r"unknown setting\(s\) \['kind'\]"):
        Modulator.from_mapping({"type": "pwm", "f_w": 20, "kind": "x"})
