"""A valve in the transport-delay convention, through every part of spa that uses a valve.

The convention travels with the parameters (``ValveParams.delay``): the exact simulator, the
averaged model (time fractions, equilibrium, thresholds), the exact periodic means, LPWM's
inversion, the compiled closed loop and the identification that chooses it. Each is checked
against the exact simulation of the same convention (an invariant), never against a printed
number.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from spa.closedloop.controller import PIController
from spa.closedloop.loop import closed_loop_arrays
from spa.identification import identify_with_config
from spa.identification.results import load_params
from spa.model.averaging import equilibrium, pulse_times, time_fractions
from spa.model.modulators import Modulator, modulate
from spa.model.params import ValveParams
from spa.model.plant import simulate
from spa.model.steady_state import periodic_mean
from spa.model.thresholds import thresholds
from spa.synthetic import Sensor
from spa.synthetic.runs import dataset_runs, run_seed, simulate_run

SLOW_OPEN = ValveParams(t_on=0.020, t_off=0.005, delay="transport")
SLOW_CLOSE = ValveParams(c1=0.4, k2=2.0, tau2=0.5, t_on=0.004, t_off=0.023, delay="transport")
SETTINGS = (
    ("pwm", {"f_w": 20.0}),
    ("ipfm", {"t_h": 0.03}),
    ("iipfm", {"t_l": 0.03, "gain": 1.0}),
    ("dsm", {"period": 0.02}),
    ("lpwm", {"f_w": 20.0}),
)


def _bound(kind: str, settings: dict, valve: ValveParams) -> dict:
    mod = Modulator.from_mapping({"type": kind, **settings})
    return {k: v for k, v in mod.bind(valve).items() if k != "type"}


def _simulated_mean(kind: str, s: dict, xi: float, valve: ValveParams) -> float:
    dt, seconds = 2e-5, 10.0  # a fine step: PWM widths round to it
    n = int(seconds / dt)
    u = modulate(kind, np.full(n, xi), dt, **s)
    return float(simulate(u, dt, valve, 0.0)[n // 2 :].mean())


def test_the_convention_is_validated_and_round_trips() -> None:
    assert ValveParams().as_dict() == ValveParams(delay="hold").as_dict()
    assert "delay" not in ValveParams().as_dict()  # the paper's valves keep five numbers
    assert ValveParams(**SLOW_OPEN.as_dict()) == SLOW_OPEN
    with pytest.raises(ValueError, match=r"ValveParams\.delay must be one of hold, transport"):
        ValveParams(delay="dead")
    nested = {k: {"value": v} for k, v in SLOW_OPEN.as_dict().items() if k != "delay"}
    assert load_params({**nested, "delay": "transport"}) == SLOW_OPEN
    assert load_params(nested).delay == "hold"


@pytest.mark.parametrize("valve", [SLOW_OPEN, SLOW_CLOSE], ids=["slow-open", "slow-close"])
@pytest.mark.parametrize(("kind", "settings"), SETTINGS, ids=[k for k, _ in SETTINGS])
def test_periodic_mean_is_the_simulated_mean(kind: str, settings: dict, valve) -> None:
    s = _bound(kind, settings, valve)
    for xi in (0.3, 0.6):
        exact = float(periodic_mean(kind, xi, valve, **s))
        assert exact == pytest.approx(_simulated_mean(kind, s, xi, valve), abs=2e-3)


@pytest.mark.parametrize("valve", [SLOW_OPEN, SLOW_CLOSE], ids=["slow-open", "slow-close"])
@pytest.mark.parametrize(("kind", "settings"), SETTINGS, ids=[k for k, _ in SETTINGS])
def test_the_fractions_fill_the_period(kind: str, settings: dict, valve) -> None:
    """No hold under transport: alpha1 + alpha2 = 1, each in [0, 1]."""
    s = _bound(kind, settings, valve)
    xi = np.linspace(0.0, 1.0, 41)
    a1, a2 = (np.asarray(a) for a in time_fractions(kind, xi, valve, **s))
    np.testing.assert_allclose(a1 + a2, 1.0, atol=1e-12)
    assert np.all((a2 >= 0.0) & (a2 <= 1.0))


def test_pwm_fractions_are_the_shifted_edges() -> None:
    """PWM's plant charges from t_on after the rising edge to t_off after the falling one."""
    xi = np.array([0.35, 0.5, 0.7])
    _, a2 = time_fractions("pwm", xi, SLOW_OPEN, f_w=20.0)
    np.testing.assert_allclose(a2, xi + (SLOW_OPEN.t_off - SLOW_OPEN.t_on) * 20.0)
    dead, sat = thresholds("pwm", SLOW_OPEN, f_w=20.0)
    assert float(dead) == pytest.approx((SLOW_OPEN.t_on - SLOW_OPEN.t_off) * 20.0)
    assert float(sat) == 1.0  # a low pulse always discharges longer than it lasts


def test_lpwm_inverts_a_transport_valve() -> None:
    """LPWM bound to a transport valve makes the exact mean close to k2*xi (the averaged
    model's line; PWM's averaging error is small at 20 Hz on this slow plant)."""
    s = _bound("lpwm", {"f_w": 20.0}, SLOW_CLOSE)
    assert s["t_on"] == pytest.approx(SLOW_CLOSE.t_on - SLOW_CLOSE.t_off)
    for xi in (0.5, 0.7):  # where the duty is inside (0, 1); below, it would be negative
        t_h, t_l = (float(v) for v in pulse_times("lpwm", xi, SLOW_CLOSE, **s))
        assert t_h > 0.0 and t_l > 0.0
        assert float(equilibrium("lpwm", xi, SLOW_CLOSE, **s)) == pytest.approx(
            SLOW_CLOSE.k2 * xi, rel=1e-9
        )
        assert _simulated_mean("lpwm", s, xi, SLOW_CLOSE) == pytest.approx(
            SLOW_CLOSE.k2 * xi, rel=0.03
        )


@pytest.mark.parametrize("valve", [SLOW_OPEN, SLOW_CLOSE], ids=["slow-open", "slow-close"])
@pytest.mark.parametrize(
    "mod",
    [
        {"type": "pwm", "f_w": 20.0},
        {"type": "dsm", "period": 0.02},
        {"type": "iipfm", "t_l": 0.02, "gain": 1.15},
        {"type": "ipfm", "t_h": 0.02},
        {"type": "lpwm", "f_w": 20.0},
    ],
    ids=["pwm", "dsm", "iipfm", "ipfm", "lpwm"],
)
def test_closed_loop_is_the_simulator_on_its_own_command(valve, mod) -> None:
    """The compiled loop's edges in flight: its pressure is the exact transport simulation of
    the command it issued, and its plain-Python body gives the same bits (LPWM inverting
    the transport valve: its losses, one of them negative, in the kernel)."""
    mod = Modulator.from_mapping(mod).bind(valve)
    r = np.r_[np.full(2500, 0.3 * valve.k2), np.full(2500, 0.6 * valve.k2)]
    c = PIController(kp=1.0 / valve.k2, ki=2.0 / valve.k2)
    p, _, u = closed_loop_arrays(r, 1e-3, mod, c, valve, 0.0)
    np.testing.assert_allclose(p, simulate(u, 1e-3, valve, 0.0), atol=1e-12)
    p_py, _, u_py = closed_loop_arrays(r, 1e-3, mod, c, valve, 0.0, compiled=False)
    np.testing.assert_array_equal(u, u_py)
    np.testing.assert_array_equal(p, p_py)


def _dataset(truth: ValveParams, seed: int) -> tuple[dict, dict, dict]:
    from spa.synthetic import identification_experiment_for

    mods = ({"type": "pwm", "f_w": 20.0}, {"type": "dsm", "period": 0.02})
    cfg = {
        "controller_dt": 1e-3,
        "sensor": {"fs": 1000.0},
        "modulators": [dict(m) for m in mods],
        "params": truth.as_dict(),
    }
    experiments = {
        "identification": identification_experiment_for(truth),
        "staircase": {"step": 0.2, "hold": 3.0},
    }
    specs = dataset_runs(cfg, experiments)
    sensor = Sensor(fs=1000.0)
    runs = {
        s.id: simulate_run(s, truth, 1e-3, sensor, run_seed(seed, "transport", s.id)) for s in specs
    }
    kinds = {s.id: s.kind for s in specs}
    modulators = {s.id: (s.modulator["type"] if s.modulator else "") for s in specs}
    return runs, kinds, modulators


@pytest.mark.parametrize("delay", ["hold", "transport"])
def test_identification_chooses_the_convention_that_made_the_data(delay: str) -> None:
    truth = ValveParams(c1=0.5, k2=1.2, tau2=0.6, t_on=0.006, t_off=0.022, delay=delay)
    runs, kinds, mods = _dataset(truth, seed=5)
    res = identify_with_config(
        runs, kinds, {"seed": 5}, modulators=mods, command_dt=dict.fromkeys(runs, 1e-3)
    )
    got = res.to_valve_params()
    assert got.delay == delay
    assert res.to_dict().get("delay", "hold") == delay
    for name in ("t_on", "t_off"):
        est = getattr(res, name)
        assert est.lo <= getattr(truth, name) <= est.hi, (name, est)


def test_a_convention_set_by_the_config_is_kept() -> None:
    truth = ValveParams(c1=0.5, k2=1.2, tau2=0.6, t_on=0.006, t_off=0.022, delay="transport")
    runs, kinds, mods = _dataset(truth, seed=6)
    res = identify_with_config(
        runs,
        kinds,
        {"seed": 6, "identification": {"delay_convention": "hold"}},
        modulators=mods,
        command_dt=dict.fromkeys(runs, 1e-3),
    )
    assert res.to_valve_params().delay == "hold"
    assert res.delay_convention["setting"] == "hold"
    with pytest.raises(ValueError, match="delay_convention must be auto, hold or transport"):
        identify_with_config(runs, kinds, {"identification": {"delay_convention": "fast"}})


def test_the_box_spans_the_delays_mean_and_difference() -> None:
    """With the difference's own interval, no corner has delays at opposite ends of their
    intervals: each corner's t_off - t_on is inside the difference's interval."""
    from spa.identification.identified import corners, read_intervals

    est = ValveParams(t_on=0.025, t_off=0.026, delay="transport")
    source = {
        "t_on": {"value": 0.025, "lo": 0.022, "hi": 0.029},
        "t_off": {"value": 0.026, "lo": 0.023, "hi": 0.030},
        "delay_difference": {"value": 0.001, "lo": 0.0005, "hi": 0.0015},
    }
    box = read_intervals(source)
    valves = corners(est, box)
    assert len(valves) == 4
    for v in valves:
        assert v.delay == "transport"
        assert 0.0005 - 1e-12 <= v.t_off - v.t_on <= 0.0015 + 1e-12
        assert 0.0225 - 1e-12 <= 0.5 * (v.t_on + v.t_off) <= 0.0295 + 1e-12
    apart = corners(est, {k: box[k] for k in ("t_on", "t_off")})
    assert max(v.t_off - v.t_on for v in apart) == pytest.approx(0.008)


def test_a_transport_identification_states_the_difference() -> None:
    truth = ValveParams(c1=0.5, k2=1.2, tau2=0.6, t_on=0.006, t_off=0.022, delay="transport")
    runs, kinds, mods = _dataset(truth, seed=7)
    res = identify_with_config(
        runs, kinds, {"seed": 7}, modulators=mods, command_dt=dict.fromkeys(runs, 1e-3)
    )
    d = res.to_dict()["delay_difference"]
    assert d["lo"] <= truth.t_off - truth.t_on <= d["hi"]
    from spa.report.params import params_table

    table = params_table(res.to_dict())
    row = table[table["parameter"] == "t_off - t_on"].iloc[0]
    assert row["95 % lo"] == pytest.approx(d["lo"]) and row["unit"] == "s"
    # both delays are read at the command edges, each on its own direction's edges: their
    # errors are independent and the difference's interval is their intervals' hypotenuse
    assert res.to_dict()["delay_convention"]["chosen_by"].startswith("the command edges")
    assert d["method"].startswith("the two delays read at the command edges")
    widths = (res.t_on.hi - res.t_on.lo, res.t_off.hi - res.t_off.lo)
    assert d["hi"] - d["lo"] == pytest.approx(math.hypot(*widths), rel=1e-6)
