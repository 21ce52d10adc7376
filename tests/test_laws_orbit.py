"""The averaged model and the exact periodic orbit on a valve with its own laws, against long
exact simulations (spa.simulate) and against the paper's closed forms as the nested case."""

from __future__ import annotations

import numpy as np
import pytest

from spa import ValveParams, modulate, simulate
from spa.model.averaging import (
    chattering_estimate,
    equilibrium,
    equilibrium_pressure,
    pseudo_steady_state,
    thresholds,
    time_constant,
    time_fractions,
)
from spa.model.laws import Laws
from spa.model.laws.orbit import (
    law_charge_integral,
    law_discharge_integral,
    law_orbit,
    law_train_orbit,
)
from spa.model.laws.rates import closed_rate, open_rate
from spa.model.periodic import (
    charge_integral,
    discharge_integral,
    dsm_mean,
    dsm_means,
    train_mean,
)
from spa.model.usable import rising_range, unusable_reason

LAWS = Laws(log_g=(0.0, 0.3, 0.5, 0.2), log_h=(0.0, -0.2, -0.4, -0.5), m=0.8)


def laws_valve(delay: str = "hold") -> ValveParams:
    """A slow valve on a compliant chamber: rates that vary with pressure, a linear-ish
    exhaust (m = 0.8)."""
    return ValveParams(c1=0.4, k2=0.6, tau2=0.4, t_on=0.015, t_off=0.025, laws=LAWS, delay=delay)


def settled_train(th: float, tl: float, params: ValveParams, dt: float) -> np.ndarray:
    """The last cycle of a long exact run of a periodic train (edges on the grid), started
    at the averaged equilibrium (only the transient depends on the start)."""
    nh, n = round(th / dt), round((th + tl) / dt)
    assert abs(nh * dt - th) < 1e-12 and abs(n * dt - th - tl) < 1e-12
    cycles = int(np.ceil(20.0 / (th + tl))) + 2
    u = np.tile(np.r_[np.ones(nh), np.zeros(n - nh)].astype(np.int8), cycles)
    p0 = float(equilibrium("pwm", th / (th + tl), params, f_w=1.0 / (th + tl)))
    p = simulate(u, dt, params, p0=p0)
    assert np.abs(p[-n:] - p[-2 * n : -n]).max() < 1e-9, "the run has not settled"
    return p[-n:]


@pytest.mark.parametrize("delay", ["hold", "transport"])
@pytest.mark.parametrize(
    ("th", "tl", "dt"),
    [(0.03, 0.03, 1e-5), (0.05, 0.3, 1e-5), (1.2, 0.8, 1e-4)],
    ids=["short", "long-low", "long"],
)
def test_train_orbit_is_the_settled_simulation(delay, th, tl, dt):
    p = laws_valve(delay)
    cycle = settled_train(th, tl, p, dt)
    hi, lo = (float(v) for v in pseudo_steady_state(th, tl, p))
    assert abs(cycle.max() - hi) < 1e-9
    assert abs(cycle.min() - lo) < 1e-9
    assert abs(cycle.mean() - float(train_mean(th, tl, p))) < 1e-8
    assert hi - lo > 1e-3  # a real ripple


def test_orbit_holds_where_the_cycle_is_not_short_against_the_local_time_constant():
    p = laws_valve()
    th, tl = 1.2, 0.8
    a1, a2 = time_fractions("pwm", th / (th + tl), p, f_w=1.0 / (th + tl))
    tau_m = float(time_constant(a1, a2, p))
    assert (th + tl) / tau_m > 3.0  # the cycle is long: the averaged model does not apply
    cycle = settled_train(th, tl, p, 1e-4)
    averaged = float(equilibrium_pressure(a1, a2, p))
    exact = float(train_mean(th, tl, p))
    assert abs(cycle.mean() - exact) < 1e-8
    assert abs(cycle.mean() - averaged) > 1e3 * abs(cycle.mean() - exact)


@pytest.mark.parametrize("delay", ["hold", "transport"])
@pytest.mark.parametrize(("xi", "period"), [(0.3, 0.05), (0.6, 0.4)])
def test_dsm_orbit_is_the_settled_simulation(delay, xi, period):
    p = laws_valve(delay)
    dt = 1e-4 if period > 0.1 else 1e-5
    u = modulate("dsm", np.full(round(20.0 / dt), xi), dt, period=period)
    pressure = simulate(u, dt, p)
    n = round(10 * period / dt)  # the pattern of 3/10 and 6/10 repeats every 10 ticks
    assert np.abs(pressure[-n:] - pressure[-2 * n : -n]).max() < 1e-9
    assert abs(pressure[-n:].mean() - float(dsm_mean(xi, period, p))) < 1e-8


def test_the_paper_laws_through_the_general_orbit_are_the_closed_forms():
    for p in (ValveParams(), ValveParams(delay="transport", t_on=0.02, t_off=0.01)):
        th = np.linspace(0.004, 0.2, 40)
        tl = np.linspace(0.2, 0.012, 40)
        hi, lo, mean = law_train_orbit(th, tl, p)
        paper_hi, paper_lo = pseudo_steady_state(th, tl, p)
        assert np.abs(hi - paper_hi).max() < 1e-12
        assert np.abs(lo - paper_lo).max() < 1e-12
        assert np.abs(mean - train_mean(th, tl, p)).max() < 1e-12
    p = ValveParams()
    assert abs(law_charge_integral(0.1, 0.6, 0.4, p) - charge_integral(0.1, 0.6, 0.4, p)) < 1e-14
    assert abs(law_discharge_integral(0.6, 0.05, p) - discharge_integral(0.6, 0.05, p)) < 1e-14


def test_orbit_integrals_are_the_time_integral_of_the_simulation():
    p = laws_valve()
    dt = 1e-5
    n = round(0.5 / dt)
    up = simulate(np.ones(n, dtype=np.int8), dt, ValveParams(**{**p.as_dict(), "t_on": 1e-12}))
    area = np.trapezoid(up, dx=dt)
    assert abs(float(law_charge_integral(0.0, up[-1], (n - 1) * dt, p)) - area) < 1e-9
    down = simulate(np.zeros(n, dtype=np.int8), dt, p, p0=0.5)
    assert abs(float(law_discharge_integral(0.5, down[-1], p)) - np.trapezoid(down, dx=dt)) < 1e-8


def test_batched_orbits_do_not_depend_on_the_batch():
    paper, law = ValveParams(), laws_valve()
    xi = np.linspace(0.0, 1.0, 21)
    batch = dsm_means(xi, [0.02, 0.05], [paper, law], max_denominator=20)
    alone_paper = dsm_means(xi, [0.02], [paper], max_denominator=20)[0]
    assert np.array_equal(batch[0], alone_paper)  # bit for bit
    assert np.array_equal(batch[1], dsm_mean(xi, 0.05, law, max_denominator=20))
    without = ValveParams(**{**law.as_dict(), "laws": None})
    assert not np.allclose(batch[1], dsm_mean(xi, 0.05, without, max_denominator=20), atol=1e-3)
    starts, _ = law_orbit([[0.01, 0.02], [0.03, 0.01]], 0.0, 2, law)
    one, _ = law_orbit([[0.03, 0.01]], 0.0, 2, law)
    assert np.array_equal(starts[1], one[0])


def test_chattering_estimate_uses_the_charge_law():
    p = laws_valve()
    pe = np.array([0.1, 0.3, 0.5, 0.6])
    got = np.asarray(chattering_estimate(0.02, pe, p))
    want = np.where(pe < p.k2, 0.02 * open_rate(pe, p), 0.0)
    np.testing.assert_allclose(got, want, rtol=1e-14, atol=0.0)
    paper = np.asarray(chattering_estimate(0.02, pe, ValveParams(**{**p.as_dict(), "laws": None})))
    assert np.abs(got - paper).max() > 1e-3


def test_averaged_model_follows_the_laws_with_each_modulators_fractions():
    law = laws_valve()
    paper = ValveParams(**{**law.as_dict(), "laws": None})
    xi = np.linspace(0.0, 1.0, 41)
    for kind, settings in (("pwm", {"f_w": 20.0}), ("ipfm", {"t_h": 0.04})):
        # The fractions (and so the thresholds) depend on the delays alone ...
        assert np.array_equal(
            np.asarray(time_fractions(kind, xi, law, **settings)),
            np.asarray(time_fractions(kind, xi, paper, **settings)),
        )
        assert thresholds(kind, law, **settings) == thresholds(kind, paper, **settings)
        # ... the equilibrium is where the laws' averaged rate vanishes.
        a1, a2 = (np.asarray(a) for a in time_fractions(kind, xi, law, **settings))
        peq = np.asarray(equilibrium(kind, xi, law, **settings))
        inside = (a1 > 0) & (a2 > 0)
        rate = a2 * open_rate(peq, law) + a1 * closed_rate(peq, law)
        assert np.abs(rate[inside]).max() < 1e-12
        assert np.abs(peq - np.asarray(equilibrium(kind, xi, paper, **settings))).max() > 0.01
        # tau_m is the inverse slope of that rate
        slope = a2 * open_rate(peq, law, slope=True) + a1 * closed_rate(peq, law, slope=True)
        tau = np.asarray(time_constant(a1, a2, law))
        np.testing.assert_allclose(tau[inside], -1.0 / slope[inside], rtol=1e-12)
    pwm = np.asarray(equilibrium("pwm", xi, law, f_w=20.0))
    ipfm = np.asarray(equilibrium("ipfm", xi, law, t_h=0.04))
    assert np.abs(pwm - ipfm).max() > 0.01  # PWM and IPFM differ
    lo, hi = rising_range({"type": "pwm", "f_w": 20.0}, law)
    assert lo == 0.0 and hi == pytest.approx(float(pwm.max()))
    assert unusable_reason({"type": "pwm", "f_w": 20.0}, law) is None


@pytest.mark.parametrize(
    "laws",
    [LAWS, Laws(m=1.0), Laws(log_g=(1.0, -1.0, 1.0, 0.0), log_h=(0.0, 0.5, -0.5, 1.0), m=0.6)],
    ids=["compliant", "laminar", "wavy"],
)
def test_averaged_equilibrium_is_bracketed_by_the_rate_at_every_fraction(laws):
    p = ValveParams(laws=laws)
    rng = np.random.default_rng(47)
    a1 = np.concatenate((rng.uniform(0.0, 1.0, 2000), [1e-9, 0.5, 1.0]))
    a2 = np.concatenate((rng.uniform(0.0, 1.0, 2000), [0.5, 1e-9, 1e-12]))
    peq = np.asarray(equilibrium_pressure(a1, a2, p))
    inside = (a1 > 0) & (a2 > 0)
    assert np.all((peq >= 0.0) & (peq <= p.k2))
    step = 1e-12 * p.k2
    below = a2 * open_rate(peq - step, p) + a1 * closed_rate(np.maximum(peq - step, 0.0), p)
    above = a2 * open_rate(peq + step, p) + a1 * closed_rate(peq + step, p)
    # the averaged rate changes sign across P_eq: rising below it, falling above it
    assert np.all((below[inside] > 0.0) | (peq[inside] <= step))
    assert np.all((above[inside] < 0.0) | (peq[inside] >= p.k2 - step))
