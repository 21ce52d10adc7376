"""The actuator's general two-mode laws (spa.model.laws): the value, its exact simulation
against an adaptive ODE reference, and the averaged equilibrium against Eqs. 5 and 9 and
against a long simulation's cycle mean."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from spa import modulate, simulate
from spa.model import averaging
from spa.model.laws import Laws
from spa.model.laws.equilibrium import law_equilibrium_pressure, law_time_constant
from spa.model.laws.rates import closed_rate, open_rate
from spa.model.laws.timemap import law_segment_pressure
from spa.model.params import ValveParams
from spa.model.plant import edge_indices, segment_pressure, transport_runs

# Law shapes: rates rising, falling and non-monotone with pressure, m from 1/2 to 1.
SHAPES = {
    "falling-exhaust": Laws(log_g=(0.0, 0.0, 0.0, 0.0), log_h=(0.4, 0.1, -0.3, -0.8), m=0.5),
    "non-monotone": Laws(log_g=(0.3, -0.9, 0.1, 0.4), log_h=(0.1, 0.8, -0.3, 0.2), m=0.7),
    "laminar": Laws(log_g=(-0.2, 0.2, 0.5, 0.6), log_h=(0.0, 0.3, 0.3, 0.0), m=1.0),
    "near-laminar": Laws(log_g=(0.5, 0.0, -0.5, -1.0), log_h=(-0.5, 0.0, 0.5, 0.2), m=0.95),
}
TOL = 1e-9  # bar


def _valve(name: str, delay: str = "hold") -> ValveParams:
    return ValveParams(
        c1=0.4, k2=0.6, tau2=0.5, t_on=0.004, t_off=0.008, delay=delay, laws=SHAPES[name]
    )


def _mode_ode(on: bool, p0: float, t: np.ndarray, prm: ValveParams) -> np.ndarray:
    """The mode's ODE integrated adaptively (DOP853, tight tolerances)."""
    if t.size == 0:
        return t.copy()

    def rate(_: float, x: np.ndarray) -> np.ndarray:
        p = np.maximum(x, 0.0)
        return open_rate(p, prm) if on else closed_rate(p, prm)

    sol = solve_ivp(
        rate, (0.0, float(t[-1]) + 1e-12), [p0], t_eval=t, method="DOP853", rtol=1e-13, atol=1e-15
    )
    assert sol.success
    return np.maximum(sol.y[0], 0.0)


def _hybrid_ode(u: np.ndarray, dt: float, prm: ValveParams) -> np.ndarray:
    """Reference: the plant's runs of constant connection, each mode integrated by ODE."""
    n = u.size
    t = np.arange(n) * dt
    k = np.concatenate(([0], edge_indices(u)))
    level = u[k].astype(bool)
    hold = np.where(level, prm.t_on, prm.t_off)
    hold[0] = 0.0
    starts = k * dt
    if prm.delay == "transport":
        starts, level = transport_runs(starts, level, hold)
        hold = np.zeros(starts.size)
    ends = np.append(starts[1:], np.inf)
    out = np.empty(n)
    p = 0.0
    for s, e, lv, hd in zip(starts, ends, level, hold, strict=True):
        idx = np.flatnonzero((t >= s) & (t < e))
        act = np.maximum(t[idx] - s - hd, 0.0)
        span = min(e, t[-1] + dt) - s - hd
        grid = np.append(act, max(span, 0.0)) if np.isfinite(e) else act
        uniq, inverse = np.unique(grid, return_inverse=True)
        vals = _mode_ode(bool(lv), p, uniq, prm)[inverse]
        out[idx] = vals[: idx.size]
        if np.isfinite(e) and grid.size:
            p = float(vals[-1])
    return out


def test_laws_value_checks_and_round_trip():
    laws = SHAPES["non-monotone"]
    prm = ValveParams(laws=laws)
    assert ValveParams(**prm.as_dict()) == prm
    assert prm.as_dict()["laws"]["m"] == 0.7
    # The paper's laws are the nested case, stored as None: one form of the paper's valve.
    assert ValveParams(laws=Laws()) == ValveParams()
    assert ValveParams(laws=Laws()).laws is None
    assert "laws" not in ValveParams().as_dict()
    with pytest.raises(ValueError, match=r"Laws\.m must be in \[0.5, 1\]"):
        Laws(m=0.4)
    with pytest.raises(ValueError, match="one value per knot"):
        Laws(log_g=(0.0, 0.1))
    with pytest.raises(ValueError, match="strictly increasing"):
        Laws(knots=(0.0, 0.5, 0.5, 1.0))
    with pytest.raises(ValueError, match="unknown keys"):
        ValveParams(laws={"log_g": [0.0] * 4, "tau": 1.0})
    with pytest.raises(ValueError, match=r"ValveParams\.laws must be a Laws"):
        ValveParams(laws=3.0)


def test_rates_are_positive_and_nest_the_paper():
    prm = ValveParams()
    p = np.linspace(0.0, prm.k2, 101)
    np.testing.assert_allclose(open_rate(p, prm), (prm.k2 - p) / prm.tau2, rtol=1e-15)
    np.testing.assert_allclose(closed_rate(p, prm), -np.sqrt(p) / prm.c1, rtol=1e-14, atol=1e-300)
    for laws in SHAPES.values():
        lv = ValveParams(laws=laws)
        assert np.all(open_rate(p[:-1], lv) > 0.0)
        assert np.all(closed_rate(p[1:], lv) < 0.0)


@pytest.mark.parametrize("name", sorted(SHAPES))
@pytest.mark.parametrize("on", [True, False])
def test_one_mode_matches_the_ode(name, on):
    prm = _valve(name)
    t = np.linspace(0.0, 4.0, 801)
    starts = (0.0, 0.2, 0.59) if on else (0.6, 0.35, 0.05, 0.9)  # 0.9 > k2: from above
    for p0 in starts:
        got = law_segment_pressure(on, p0, t, prm)
        ref = _mode_ode(on, p0, t, prm)
        assert np.max(np.abs(got - ref)) < TOL, (name, on, p0)


@pytest.mark.parametrize("delay", ["hold", "transport"])
@pytest.mark.parametrize("name", sorted(SHAPES))
def test_simulation_matches_the_hybrid_ode(name, delay):
    prm = _valve(name, delay)
    dt = 1e-3
    t = np.arange(3000) * dt
    xi = 0.5 + 0.4 * np.sin(2 * np.pi * 0.7 * t)
    u = modulate("pwm", xi, dt, f_w=10.0)
    got = simulate(u, dt, prm)
    ref = _hybrid_ode(u, dt, prm)
    assert np.max(np.abs(got - ref)) < TOL
    # A run's end is the next run's start: the chain and the samples agree.
    assert np.all(np.abs(np.diff(got)) < 0.01)


def test_paper_laws_keep_the_closed_forms_bit_for_bit():
    prm = ValveParams()
    dt = 1e-4
    u = modulate("iipfm", np.linspace(0, 1, 20000), dt, t_l=0.02, gain=1.15)
    for delay in ("hold", "transport"):
        a = simulate(u, dt, ValveParams(laws=Laws()), delay=delay)
        b = simulate(u, dt, prm, delay=delay)
        assert np.array_equal(a, b)
    e = np.linspace(0.0, 3.0, 301)
    ch = prm.k2 + (0.2 - prm.k2) * np.exp(-e / prm.tau2)
    root = np.maximum(np.sqrt(0.7) - e / (2.0 * prm.c1), 0.0)
    assert np.array_equal(segment_pressure(True, 0.2, e, ValveParams(laws=Laws())), ch)
    assert np.array_equal(segment_pressure(False, 0.7, e, prm), root * root)
    # The general time maps, run on the paper's laws, agree with the closed forms.
    for on, p0 in ((True, 0.2), (False, 0.7)):
        ref = segment_pressure(on, p0, e, prm)
        assert np.max(np.abs(law_segment_pressure(on, p0, e, prm) - ref)) < 1e-11


def test_equilibrium_and_time_constant_nest_eqs_5_and_9():
    prm = ValveParams()
    a1 = np.linspace(-0.1, 1.0, 23)[:, None]
    a2 = np.linspace(-0.1, 1.0, 23)[None, :]
    eq5 = averaging.equilibrium_pressure(a1, a2, prm)
    assert law_equilibrium_pressure(a1, a2, prm) is not None
    assert np.array_equal(law_equilibrium_pressure(a1, a2, prm), eq5)
    assert np.max(np.abs(law_equilibrium_pressure(a1, a2, prm, Laws()) - eq5)) < 1e-15
    eq9 = averaging.time_constant(a1, a2, prm)
    general = law_time_constant(a1, a2, prm, Laws())
    assert np.array_equal(np.isnan(general), np.isnan(eq9))
    ok = ~np.isnan(eq9)
    np.testing.assert_allclose(general[ok], eq9[ok], rtol=1e-13)


@pytest.mark.parametrize("name", sorted(SHAPES))
def test_equilibrium_balances_the_rates(name):
    prm = _valve(name)
    a1 = np.array([0.1, 0.3, 0.5, 0.8])
    a2 = 1.0 - a1 - 0.05
    peq = law_equilibrium_pressure(a1, a2, prm)
    rate = a2 * open_rate(peq, prm) + a1 * closed_rate(peq, prm)
    assert np.all(np.abs(rate) < 1e-12)
    assert np.all((peq > 0.0) & (peq < prm.k2))
    # tau_m is the inverse slope: a small step's rate is -(step)/tau_m.
    tau = law_time_constant(a1, a2, prm)
    step = 1e-6
    r = a2 * open_rate(peq + step, prm) + a1 * closed_rate(peq + step, prm)
    np.testing.assert_allclose(-step / r, tau, rtol=1e-4)


@pytest.mark.parametrize("name", ["non-monotone", "laminar"])
def test_equilibrium_is_the_cycle_mean_of_a_short_cycle(name):
    """A long exact simulation under a short PWM cycle settles where the averaged rates
    balance; the gap closes as the cycle shortens (as its square: the first-order terms of
    the two modes' ripples cancel)."""
    prm = ValveParams(c1=0.4, k2=0.6, tau2=0.5, t_on=0.0, t_off=0.0, laws=SHAPES[name])
    gaps = []
    for f_w in (50.0, 200.0):
        dt = 1.0 / f_w / 100
        n = round(6.0 / dt)
        u = modulate("pwm", np.full(n, 0.45), dt, f_w=f_w)
        p = simulate(u, dt, prm)
        cycle = round(1.0 / f_w / dt)
        mean = p[-50 * cycle :].mean()
        a1, a2 = averaging.time_fractions("pwm", 0.45, prm, f_w=f_w)
        gaps.append(abs(mean - float(law_equilibrium_pressure(a1, a2, prm))))
    assert gaps[1] < 1e-5
    assert gaps[1] < gaps[0] / 8
