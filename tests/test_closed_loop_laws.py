"""The closed loop on a valve with its own laws: open-loop pieces against the simulation, the
compiled loop against plain Python and the per-sample reference, LPWM's inverse of the laws."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

import spa
from spa.closedloop.controller import PIController
from spa.closedloop.loop import closed_loop_arrays, closed_loop_many
from spa.closedloop.reference import closed_loop_reference
from spa.model import averaging
from spa.model.laws import Laws
from spa.model.modulators import Modulator
from spa.model.modulators.kernels import KERNELS
from spa.model.modulators.lpwm import law_weights
from spa.model.params import ValveParams
from spa.model.plant import loop_laws

DT = 1e-3
LAWS = Laws(log_g=(0.0, 0.3, 0.5, 0.2), log_h=(0.0, -0.2, -0.4, -0.5), m=0.8)
VALVE = ValveParams(c1=0.5, k2=0.8, tau2=0.7, t_on=0.004, t_off=0.009, laws=LAWS)
SETTINGS = {
    "pwm": {"type": "pwm", "f_w": 20.0},
    "ipfm": {"type": "ipfm", "t_h": 0.02, "gain": 1.0},
    "iipfm": {"type": "iipfm", "t_l": 0.02, "gain": 1.15},
    "dsm": {"type": "dsm", "period": 0.02},
}


def _replay(xi: np.ndarray) -> tuple[np.ndarray, PIController]:
    # Kp = Ki = 0 and a feed-forward that returns xi[k] at the set-point k: the loop is open.
    k = np.arange(xi.size, dtype=np.float64)
    return k, PIController(kp=0.0, ki=0.0, feedforward=(tuple(k), tuple(xi)))


@pytest.mark.parametrize("delay", ["hold", "transport"])
@pytest.mark.parametrize("kind", sorted(SETTINGS))
def test_open_loop_pieces_follow_the_laws_simulation(kind: str, delay: str) -> None:
    valve = replace(VALVE, delay=delay)
    rng = np.random.default_rng(3)
    n = 6000
    t = np.arange(n) * DT
    xi = np.clip(np.repeat(rng.uniform(-0.1, 1.1, 12), n // 12) + 0.05 * np.sin(40 * t), 0, 1)
    r, ctrl = _replay(xi)
    mod = Modulator.from_mapping(SETTINGS[kind])
    p, x, u = closed_loop_arrays(r, DT, mod, ctrl, valve, p0=0.2)
    np.testing.assert_array_equal(x, xi)
    np.testing.assert_array_equal(u, mod.modulate(xi, DT))
    assert 0 < u.sum() < n
    expected = spa.simulate(u, DT, valve, p0=0.2)
    np.testing.assert_allclose(p, expected, rtol=0, atol=1e-9)
    # The laws move the pressure: the paper's valve of the same constants is elsewhere.
    paper = spa.simulate(u, DT, replace(valve, laws=None), p0=0.2)
    assert np.abs(paper - expected).max() > 0.01


@pytest.mark.parametrize("kind", ["pwm", "iipfm", "dsm"])
def test_compiled_loop_equals_plain_python_and_the_reference(kind: str) -> None:
    n = 1500
    r = np.repeat([0.1, 0.6, 0.3], n // 3)
    mod = Modulator.from_mapping(SETTINGS[kind])
    ctrl = PIController(kp=(0.8, 2.0, 1.0), ki=(1.0, 4.0, 2.0), schedule=(0.1, 0.4, 0.7))
    p, x, u = closed_loop_arrays(r, DT, mod, ctrl, VALVE, p0=0.05, integral0=0.1)
    p_ref, x_ref, u_ref = closed_loop_reference(r, DT, mod, ctrl, VALVE, 0.05, integral0=0.1)
    np.testing.assert_array_equal(u, u_ref)
    np.testing.assert_allclose(p, p_ref, rtol=0, atol=1e-9)
    np.testing.assert_allclose(x, x_ref, rtol=0, atol=1e-9)
    p_py, x_py, u_py = closed_loop_arrays(
        r[:500], DT, mod, ctrl, VALVE, 0.05, integral0=0.1, compiled=False
    )
    np.testing.assert_array_equal(u_py, u[:500])
    np.testing.assert_array_equal(p_py, p[:500])
    np.testing.assert_array_equal(x_py, x[:500])


def test_many_plants_with_laws_equal_one_by_one() -> None:
    r = np.repeat([0.2, 0.5], 800)
    ctrl = PIController(kp=1.0, ki=3.0)
    valves = [VALVE, replace(VALVE, c1=0.6, tau2=0.5), replace(VALVE, laws=None)]
    p0, i0 = [0.0, 0.1, 0.05], [0.0, 0.2, 0.1]
    mod = SETTINGS["iipfm"]
    many = closed_loop_many(r, DT, mod, ctrl, valves, p0, i0)
    plain = closed_loop_many(r[:300], DT, mod, ctrl, valves, p0, i0, compiled=False)
    for j, v in enumerate(valves):
        one = closed_loop_arrays(r, DT, mod, ctrl, v, p0[j], integral0=i0[j])
        for a, b, c in zip(many, one, plain, strict=True):
            np.testing.assert_array_equal(a[j], b)
            np.testing.assert_array_equal(c[j], b[:300])


def test_the_paper_valve_takes_the_closed_forms() -> None:
    assert loop_laws(replace(VALVE, laws=None))[0] is False
    assert loop_laws(VALVE)[0] is True
    assert loop_laws(replace(VALVE, laws=Laws()))[0] is False  # the paper's laws are None


def test_supply_change_restarts_on_the_new_supplys_laws() -> None:
    # Open loop, valve held open: before the change the pressure charges towards k2, after it
    # towards the new supply, along the laws of the valve with that supply.
    n, k = 4000, 1500
    r, ctrl = _replay(np.ones(n))
    p, _, _ = closed_loop_arrays(r, DT, SETTINGS["pwm"], ctrl, VALVE, 0.0, k2_change=(k, 0.6))
    first = spa.simulate(np.ones(k + 1, dtype=np.int8), DT, VALVE, 0.0)
    np.testing.assert_allclose(p[: k + 1], first, rtol=0, atol=1e-9)
    after = spa.simulate(np.ones(n - k, dtype=np.int8), DT, replace(VALVE, k2=0.6), p[k])
    np.testing.assert_allclose(p[k:], after, rtol=0, atol=1e-9)


@pytest.mark.parametrize("delay", ["hold", "transport"])
def test_lpwm_inverts_the_laws_equilibrium(delay: str) -> None:
    valve = replace(VALVE, delay=delay)
    mod = Modulator.from_mapping({"type": "lpwm", "f_w": 14.2}).bind(valve)
    xi = np.linspace(0.02, 0.98, 49)
    d = mod.spec.duty(xi, mod.settings, valve)
    xi = xi[(d > 0.0) & (d < 1.0)]  # a duty clipped at 0 or 1 inverts nothing (transport)
    assert xi.size > 40
    a1, a2 = mod.spec.fractions(xi, mod.settings, valve)
    peq = averaging.equilibrium_pressure(a1, a2, valve)
    assert np.abs(peq - valve.k2 * xi).max() < 1e-4 * valve.k2
    # The paper's closed form would miss the laws' equilibrium by far more.
    paper = replace(valve, laws=None)
    d_paper = mod.spec.duty(xi, mod.settings, paper)
    alpha2 = d_paper - valve.on_loss * 14.2
    alpha1 = 1.0 - d_paper - valve.off_loss * 14.2
    off = averaging.equilibrium_pressure(alpha1, alpha2, valve)
    assert np.abs(off - valve.k2 * xi).max() > 0.01


def test_lpwm_kernel_reads_the_laws_table_as_the_averaged_model() -> None:
    mod = Modulator.from_mapping({"type": "lpwm", "f_w": 14.2}).bind(VALVE)
    kernel = KERNELS["lpwm"]
    cfg = kernel.configure(dict(mod.settings), DT, VALVE)
    table = law_weights(mod.settings, VALVE)
    assert table is not None and cfg[8] == table.size - 1
    np.testing.assert_array_equal(cfg[9:], table)
    assert kernel.configure(dict(mod.settings), DT, replace(VALVE, laws=None))[8] == 0.0
    xi = np.random.default_rng(2).uniform(0.0, 1.0, 400)
    expected = mod.spec.duty(xi, mod.settings, VALVE)
    np.testing.assert_array_equal([kernel.duty(x, cfg) for x in xi], expected)
    np.testing.assert_array_equal([kernel.duty.py_func(x, cfg) for x in xi], expected)
    # Fed the duty's PWM, the closed-loop kernel gives the open-loop PWM's command.
    xs = np.clip(np.repeat(xi[:30], 97), 0.0, 1.0)
    st = np.array(kernel.INITIAL, dtype=np.float64)
    u = [kernel.step(k, x, cfg, st) for k, x in enumerate(xs)]
    d = mod.spec.duty(xs, mod.settings, VALVE)
    np.testing.assert_array_equal(u, spa.modulate("pwm", d, DT, f_w=14.2))


def test_lpwm_thresholds_invert_the_table() -> None:
    valve = replace(VALVE, t_on=0.01, t_off=0.02)
    plain = Modulator.from_mapping({"type": "lpwm", "f_w": 14.2})
    s = dict(plain.bind(VALVE).settings)  # another valve's inverse, on this plant's laws
    dead, sat = plain.spec.thresholds(s, valve)
    d = plain.spec.duty(np.array([float(dead), float(sat)]), s, valve)
    f = 14.2
    np.testing.assert_allclose(d, [valve.on_loss * f, 1 - valve.off_loss * f], atol=1e-12)
    own = dict(plain.bind(valve).settings)
    dead, sat = plain.spec.thresholds(own, valve)
    assert float(dead) == pytest.approx(0.0, abs=1e-12)
    assert float(sat) == pytest.approx(1.0, abs=1e-12)


@pytest.mark.parametrize(("on", "start", "end"), [(True, 0.1, 0.6), (False, 0.7, 0.15)])
def test_transit_time_follows_the_laws(on: bool, start: float, end: float) -> None:
    from spa.closedloop.comparison import transit_time
    from spa.model.plant import mode_time

    t = float(mode_time(on, start, end, VALVE))
    dt = 1e-5
    n = int(t / dt)
    u = np.full(n + 2, int(on), dtype=np.int8)
    p = spa.simulate(u, dt, replace(VALVE, t_on=0.0, t_off=0.0), p0=start)
    # The simulated mode passes `end` between the samples around t.
    lo, hi = sorted((p[n], p[n + 1]))
    assert lo - 1e-6 <= end <= hi + 1e-6
    # The paper's times of the same constants differ: the transit is the laws'.
    paper = float(mode_time(on, start, end, replace(VALVE, laws=None)))
    assert abs(paper - t) > 0.05 * t
    assert transit_time([0.15, 0.6], VALVE) >= max(
        float(mode_time(True, 0.15, 0.6, VALVE)), float(mode_time(False, 0.6, 0.15, VALVE))
    )


def test_a_laws_box_that_breaks_every_promise_says_which_law_to_record_more_of():
    """No promise over a laws valve's box: the sentence names the law whose band is widest
    and what narrows it; with the paper's laws, or a promise kept, it says nothing of it."""
    from spa.closedloop.bench_text import bench_sentence, laws_envelope

    valve = ValveParams(
        c1=0.5, tau2=1.0, laws=Laws(log_g=(0.0, 0.3, 0.2, 0.1), log_h=(0.0, -0.2, -0.3, -0.4))
    )
    box = {"tau2": (0.8, 1.25), "c1": (0.5 / 2.8, 0.5 * 2.8), "k2": (0.8, 0.9)}
    envelope = laws_envelope(valve, box)
    assert envelope == pytest.approx({"charge": 1.25, "exhaust": 2.8})
    summary = {"tau_c": 0.3, "n_corners": 32, "promise": {"kept": False}}
    said = bench_sentence({**summary, "laws_envelope": envelope})
    assert "The exhaust law is the widest part of the box" in said
    assert "×2.8 either way" in said and "more discharges" in said
    assert "widest part" not in bench_sentence(summary)  # no laws: nothing to say
    assert laws_envelope(ValveParams(), box) == {}
    narrow = laws_envelope(valve, {"tau2": (0.9, 1.1), "c1": (0.45, 0.55)})
    assert "widest part" not in bench_sentence({**summary, "laws_envelope": narrow})
    kept = {**summary, "promise": {"kept": True, "tau_c": 0.3, "hold": 2.0, "overshoot": 5.0}}
    assert "widest part" not in bench_sentence({**kept, "laws_envelope": envelope})
