"""The exact closed loop: open-loop equality per modulator, a plain-Python reference, the plant."""

from __future__ import annotations

import numpy as np
import pytest

import spa
from spa.closedloop.controller import PIController, interp
from spa.closedloop.loop import _segment, closed_loop_arrays
from spa.closedloop.reference import closed_loop_reference
from spa.model.modulators import MODULATORS, Modulator
from spa.model.modulators.kernels import KERNELS
from spa.model.params import ValveParams
from spa.model.plant import segment_pressure, segment_pressure_scalar

DT = 1e-3
SETTINGS = {
    "pwm": {"type": "pwm", "f_w": 20.0},
    "ipfm": {"type": "ipfm", "t_h": 0.02, "gain": 1.0},
    "iipfm": {"type": "iipfm", "t_l": 0.02, "gain": 1.15},
    "dsm": {"type": "dsm", "period": 0.02},
}
PARAMS = ValveParams(c1=0.5, k2=0.8, tau2=0.7, t_on=0.004, t_off=0.009)


def _replay(xi: np.ndarray) -> tuple[np.ndarray, PIController]:
    # Kp = Ki = 0 and a feed-forward that returns xi[k] at the set-point k: the loop is open.
    k = np.arange(xi.size, dtype=np.float64)
    return k, PIController(kp=0.0, ki=0.0, feedforward=(tuple(k), tuple(xi)))


def test_every_modulator_has_a_kernel() -> None:
    assert set(MODULATORS) <= set(KERNELS)


def test_kernels_share_the_open_loop_tolerance_and_pulse_widths() -> None:
    import importlib

    from spa.model.modulators.kernels._common import EPS, pulse_steps

    mods = importlib.import_module("spa.model.modulators")
    pulses = getattr(mods, "_pulses", None)
    eps = getattr(mods, "_EPS", None) if pulses is None else pulses.EPS
    steps = getattr(mods, "_steps", None) if pulses is None else pulses.steps
    assert eps == EPS
    for width in (0.001, 0.0015, 0.0025, 0.02, 0.0199, 0.1):
        assert pulse_steps(width, 1e-3) == steps(width, 1e-3)


@pytest.mark.parametrize("f_w", [20.0, 7.3])
def test_lpwm_kernel_is_pwm_of_the_model_inverse_duty(f_w: float) -> None:
    from spa.model.modulators.kernels import lpwm

    rng = np.random.default_rng(5)
    xi = np.clip(np.repeat(rng.uniform(-0.1, 1.1, 30), 97), 0.0, 1.0)
    cfg = lpwm.configure({"f_w": f_w}, DT)
    st = np.array(lpwm.INITIAL, dtype=np.float64)
    u = [lpwm.step(k, x, cfg, st) for k, x in enumerate(xi)]
    p = ValveParams()
    s = np.sqrt(p.k2 * xi)
    a, b = s * p.tau2, (p.k2 - s * s) * p.c1
    with np.errstate(invalid="ignore", divide="ignore"):
        d = (a * (1 - p.t_off * f_w) + b * p.t_on * f_w) / (a + b)
    d = np.clip(np.where(xi <= 0, 0.0, np.where(xi >= 1, 1.0, d)), 0.0, 1.0)
    np.testing.assert_array_equal(u, spa.modulate("pwm", d, DT, f_w=f_w))


if "lpwm" in MODULATORS:  # the model-inverse PWM, where spa.model.modulators has it
    SETTINGS["lpwm"] = {"type": "lpwm", "f_w": 20.0}


@pytest.mark.parametrize("kind", sorted(SETTINGS))
@pytest.mark.parametrize("seed", [0, 1])
def test_open_loop_replay_equals_modulate_and_simulate(kind: str, seed: int) -> None:
    rng = np.random.default_rng(seed)
    # A staircase with noise, values at both ends (dead-zone and saturation), and a chirp.
    n = 6000
    t = np.arange(n) * DT
    xi = np.clip(np.repeat(rng.uniform(-0.1, 1.1, 12), n // 12) + 0.05 * np.sin(40 * t), 0, 1)
    xi[:300] = 0.0
    xi[-300:] = 1.0
    r, ctrl = _replay(xi)
    mod = Modulator.from_mapping(SETTINGS[kind])
    p, x, u = closed_loop_arrays(r, DT, mod, ctrl, PARAMS, p0=0.2)
    np.testing.assert_array_equal(x, xi)
    expected_u = mod.modulate(xi, DT)
    np.testing.assert_array_equal(u, expected_u)
    assert 0 < u.sum() < n  # the test exercises both commands
    expected_p = spa.simulate(expected_u, DT, PARAMS, p0=0.2)
    np.testing.assert_allclose(p, expected_p, rtol=0, atol=1e-12)


@pytest.mark.parametrize("kind", sorted(SETTINGS))
@pytest.mark.parametrize(
    "ctrl",
    [
        PIController(kp=1.5, ki=3.0),
        PIController(kp=(0.8, 2.0, 1.0), ki=(1.0, 4.0, 2.0), schedule=(0.1, 0.4, 0.7)),
        PIController(kp=0.5, ki=1.0, feedforward=((0.0, 0.4, 0.8), (0.0, 0.45, 0.95))),
        PIController(kp=40.0, ki=200.0),  # saturates: exercises the conditional integration
    ],
    ids=["pi", "scheduled", "feedforward", "saturating"],
)
def test_compiled_loop_equals_plain_python_reference(kind: str, ctrl: PIController) -> None:
    n = 1500
    r = np.repeat([0.1, 0.6, 0.3], n // 3)
    mod = Modulator.from_mapping(SETTINGS[kind])
    p, x, u = closed_loop_arrays(r, DT, mod, ctrl, PARAMS, p0=0.05, integral0=0.1)
    p_ref, x_ref, u_ref = closed_loop_reference(r, DT, mod, ctrl, PARAMS, 0.05, integral0=0.1)
    np.testing.assert_array_equal(u, u_ref)
    np.testing.assert_allclose(p, p_ref, rtol=0, atol=1e-12)
    np.testing.assert_allclose(x, x_ref, rtol=0, atol=1e-12)
    # The same loop run as plain Python (numba's py_func) agrees as well.
    p_py, _, u_py = closed_loop_arrays(
        r[:400], DT, mod, ctrl, PARAMS, 0.05, integral0=0.1, compiled=False
    )
    np.testing.assert_array_equal(u_py, u[:400])
    np.testing.assert_allclose(p_py, p[:400], rtol=0, atol=1e-12)


def test_anti_windup_holds_the_integrator_when_saturated() -> None:
    # A set-point above k2 cannot be reached: xi saturates at 1 and stays there; with the
    # integrator held, xi leaves saturation as soon as the set-point drops below the pressure.
    r = np.concatenate([np.full(3000, 2.0), np.full(3000, 0.2)])
    ctrl = PIController(kp=0.5, ki=5.0)
    df = spa.simulate_closed_loop(r, DT, SETTINGS["iipfm"], ctrl, PARAMS)
    xi = df["xi"].to_numpy()
    assert xi[1000:3000].min() > 0.999  # held at the limit (it dips below 1 by one step's Ki*dt*e)
    # Without the conditional integration I would have grown by about Ki*(r - p)*2 s = 12 and
    # kept xi at 1 for seconds; held, xi falls below 0.2 at the first step after the drop.
    assert xi[3000] < 0.2


def test_pi_reaches_the_set_point() -> None:
    ctrl = PIController(kp=1.0, ki=3.0)
    df = spa.simulate_closed_loop(np.full(8000, 0.45), DT, SETTINGS["iipfm"], ctrl, PARAMS)
    assert abs(df["p"].to_numpy()[-2000:].mean() - 0.45) < 0.01
    assert list(df.columns) == ["t", "r", "p", "xi", "valve"]
    assert df["valve"].dtype == np.int8


@pytest.mark.parametrize("on", [True, False])
def test_compiled_segment_is_the_plant_formula(on: bool) -> None:
    rng = np.random.default_rng(3)
    p0 = rng.uniform(0, 0.8, 200)
    e = rng.uniform(-0.01, 2.0, 200)
    expected = segment_pressure(on, p0, e, PARAMS)
    prm = (PARAMS.c1, PARAMS.k2, PARAMS.tau2)
    plain = [segment_pressure_scalar(on, a, b, *prm) for a, b in zip(p0, e, strict=True)]
    compiled = [_segment(on, a, b, *prm) for a, b in zip(p0, e, strict=True)]
    np.testing.assert_allclose(plain, expected, rtol=0, atol=1e-15)  # math.exp vs np.exp
    np.testing.assert_allclose(compiled, plain, rtol=0, atol=1e-15)


def test_interp_is_exact_at_nodes_and_held_outside() -> None:
    xp, fp = [0.0, 0.3, 1.0], [2.0, 5.0, 1.0]
    assert [interp(x, xp, fp) for x in xp] == fp
    assert interp(-1.0, xp, fp) == 2.0 and interp(3.0, xp, fp) == 1.0
    assert interp(0.15, xp, fp) == pytest.approx(3.5)


def test_controller_rejects_bad_values() -> None:
    with pytest.raises(ValueError, match="schedule"):
        PIController(kp=(1.0, 2.0), ki=1.0)
    with pytest.raises(ValueError, match=">= 0"):
        PIController(kp=-1.0)
    with pytest.raises(ValueError, match="increasing"):
        PIController(kp=(1.0, 2.0), schedule=(0.5, 0.1))
    with pytest.raises(ValueError, match="feedforward"):
        PIController(kp=1.0, feedforward=((0.0, 1.0), (0.0, 1.5)))
    ff = ((0.0,), (0.3,))
    c = PIController(kp=(1.0, 2.0), ki=(0.5, 0.7), schedule=(0.1, 0.5), feedforward=ff)
    assert PIController.from_mapping(c.to_mapping()) == c


def test_bad_modulator_for_the_step_is_refused() -> None:
    with pytest.raises(ValueError, match="f_w"):
        spa.simulate_closed_loop([0.1] * 10, 0.1, {"type": "pwm", "f_w": 20.0}, PIController(1.0))
