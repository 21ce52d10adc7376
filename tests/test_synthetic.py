"""Simulated datasets: inputs, sensor model, experiment design, determinism."""

from __future__ import annotations

import numpy as np
import pytest

from spa import ValveParams, simulate
from spa.synthetic import (
    Ringing,
    RunSpec,
    Sensor,
    chirp_input,
    identification_runs,
    modulated_runs,
    run_seed,
    simulate_run,
    sine_input,
    staircase_input,
)

P = ValveParams()
EXPERIMENTS = {
    "staircase": {"step": 0.1, "hold": 1.0},
    "sine": {"frequency": 1.0, "amplitudes": [0.4, 0.2], "periods_per_level": 2, "settle": 1.0},
    "chirp": {"f0": 0.1, "f1": 50.0, "duration": 5.0},
}


def test_staircase_has_eleven_levels_of_five_seconds():
    t = np.arange(55_000) * 1e-3
    xi = staircase_input(t)
    levels, counts = np.unique(xi, return_counts=True)
    np.testing.assert_allclose(levels, np.arange(11) / 10, atol=1e-12)
    assert set(counts) == {5000}


def test_sine_amplitude_decreases_piecewise():
    t = np.arange(0, 6.0, 1e-3)
    x = sine_input(t, 1.0, [0.4, 0.2], periods_per_level=2)
    assert x[t < 2].max() == pytest.approx(0.9, abs=1e-4)
    assert x[(t >= 2) & (t < 4)].max() == pytest.approx(0.7, abs=1e-4)
    np.testing.assert_allclose(x[t >= 4.001], 0.5)


def test_chirp_instantaneous_frequency_sweeps_linearly():
    fs = 10_000.0
    t = np.arange(0, 10.0, 1 / fs)
    x = chirp_input(t, f0=1.0, f1=21.0, duration=10.0)
    assert x.min() == pytest.approx(0.25, abs=1e-3)
    assert x.max() == pytest.approx(0.75, abs=1e-3)
    # count zero crossings (of x - offset) in the first and last second: 2*f each
    s = np.sign(x - 0.5)
    first = np.count_nonzero(np.diff(s[t < 1]) != 0) / 2
    last = np.count_nonzero(np.diff(s[t >= 9]) != 0) / 2
    assert first == pytest.approx(2.0, abs=1)  # mean frequency over [0, 1] s is 2 Hz
    assert last == pytest.approx(20.0, abs=1)  # mean frequency over [9, 10] s is 20 Hz


def test_noise_free_run_is_the_exact_simulation_sampled():
    dt = 1e-4
    spec = modulated_runs(
        [{"type": "pwm", "f_w": 20.0}], dt, {"staircase": EXPERIMENTS["staircase"]}
    )[0]
    df = simulate_run(
        spec, P, dt, Sensor(fs=1000.0, noise=0.0, quantum=0.0), np.random.default_rng(0)
    )
    u = np.asarray(spec.xi)
    from spa import modulate

    exact = simulate(modulate("pwm", u, dt, f_w=20.0), dt, P)
    np.testing.assert_array_equal(df["p"].to_numpy(), exact[::10])
    np.testing.assert_allclose(df["t"].to_numpy(), np.arange(len(df)) * 1e-3, atol=1e-12)
    assert list(df.columns) == ["t", "p", "valve", "u"]


def test_sensor_noise_and_quantisation():
    dt = 1e-3
    spec = RunSpec("c", "charge", p0=0.5, valve=np.zeros(20_000, np.int8))
    # a discharge that reaches 0 and stays: after ~1 s the logged signal is pure sensor error
    df = simulate_run(spec, P, dt, Sensor(noise=0.005, quantum=0.001), np.random.default_rng(1))
    tail = df["p"].to_numpy()[5000:]
    assert tail.std() == pytest.approx(0.005, rel=0.05)
    np.testing.assert_allclose(tail / 0.001, np.round(tail / 0.001), atol=1e-9)


def test_ringing_follows_edges():
    dt = 1e-4
    valve = np.r_[np.zeros(1000, np.int8), np.ones(1000, np.int8)]
    spec = RunSpec("r", "pulse", p0=0.3, valve=valve)
    ring = Ringing(amplitude=0.02, frequency=100.0, damping=50.0)
    clean = simulate_run(
        spec, P, dt, Sensor(fs=10_000, noise=0, quantum=0), np.random.default_rng(0)
    )
    rung = simulate_run(
        spec, P, dt, Sensor(fs=10_000, noise=0, quantum=0, ringing=ring), np.random.default_rng(0)
    )
    diff = rung["p"].to_numpy() - clean["p"].to_numpy()
    assert np.all(diff[:1000] == 0)
    s = np.arange(1000) * dt
    np.testing.assert_allclose(
        diff[1000:], 0.02 * np.exp(-50 * s) * np.sin(2 * np.pi * 100 * s), atol=1e-12
    )


def test_same_seed_same_bytes_other_seed_other_noise():
    specs = identification_runs(P, 1e-3, charge_time=1.0, discharge_time=1.0, repeats=1)
    a = simulate_run(specs[0], P, 1e-3, Sensor(), run_seed(7, "sim", "charge"))
    b = simulate_run(specs[0], P, 1e-3, Sensor(), run_seed(7, "sim", "charge"))
    c = simulate_run(specs[0], P, 1e-3, Sensor(), run_seed(8, "sim", "charge"))
    assert a.equals(b)
    assert not a["p"].equals(c["p"])


def test_identification_runs_design():
    charge, discharge, pulse = identification_runs(P, 1e-3)
    assert charge.valve.all() and charge.p0 == 0.0
    assert not discharge.valve.any() and discharge.p0 == P.k2
    lows = np.diff(np.flatnonzero(np.diff(pulse.valve.astype(int)) != 0))[1::2] * 1e-3
    np.testing.assert_allclose(
        sorted(set(np.round(lows, 6))), [0.005, 0.01, 0.015, 0.02, 0.05, 0.1, 0.2]
    )


def test_modulated_run_ids_and_kinds():
    runs = modulated_runs(
        [{"type": "pwm", "f_w": 20.0}, {"type": "iipfm", "t_l": 0.02, "gain": 1.15}],
        1e-3,
        EXPERIMENTS,
    )
    assert [r.id for r in runs] == [
        "staircase_pwm-20Hz",
        "sine_pwm-20Hz",
        "chirp_pwm-20Hz",
        "staircase_iipfm-20ms-G1.15",
        "sine_iipfm-20ms-G1.15",
        "chirp_iipfm-20ms-G1.15",
    ]
    sine = runs[1]
    assert np.all(sine.xi[: round(1.0 / 1e-3)] == 0.5)  # settle at the offset


def test_logging_rate_must_divide_the_controller_step():
    spec = RunSpec("c", "charge", valve=np.ones(100, np.int8))
    with pytest.raises(ValueError, match="fs"):
        simulate_run(spec, P, 1e-3, Sensor(fs=300.0), np.random.default_rng(0))


def test_shipped_example_is_what_the_documented_command_makes(tmp_path):
    """raw/example is reproducible: `python -m spa example raw/example` rewrites it bit for bit."""
    from pathlib import Path

    from spa.cli import main

    assert main(["example", str(tmp_path / "example")]) == 0
    shipped = Path(__file__).resolve().parents[1] / "raw" / "example"
    names = sorted(p.name for p in shipped.iterdir())
    assert names == sorted(p.name for p in (tmp_path / "example").iterdir())
    text = [name for name in names if name.endswith((".csv", ".yaml"))]
    assert "dataset.yaml" in text and any(n.endswith(".csv") for n in text), text
    for name in text:  # text: exact; binary formats carry writer versions
        assert (shipped / name).read_bytes() == (tmp_path / "example" / name).read_bytes(), name


@pytest.mark.parametrize(
    "params",
    [
        ValveParams(c1=0.12, k2=0.3, tau2=0.06, t_on=0.0008, t_off=0.0015),
        ValveParams(),
        ValveParams(c1=2.0, k2=6.0, tau2=3.0, t_on=0.020, t_off=0.040),
    ],
    ids=["small-fast", "paper", "large-slow"],
)
def test_identification_experiment_for_scales_to_the_valve(params):
    from spa.synthetic import identification_experiment_for

    d = identification_experiment_for(params)
    empty = 2 * params.c1 * np.sqrt(params.k2)  # Eq. A1: from the supply to 0 bar
    assert d["charge_time"] >= params.t_on + 6 * params.tau2  # within 0.25 % of the supply
    assert d["discharge_time"] >= params.t_off + 1.5 * empty
    assert sum(low > params.t_off + 0.005 for low in d["low_times"]) >= 2
    assert any(low < params.t_off for low in d["low_times"]) or params.t_off <= 0.005
    assert d["high_time"] > 5 * params.t_on
    for key in ("charge_time", "discharge_time", "high_time", *range(len(d["low_times"]))):
        value = d["low_times"][key] if isinstance(key, int) else d[key]
        assert abs(value * 1000 - round(value * 1000)) < 1e-6  # whole ms: whole steps of dt
    specs = identification_runs(params, 1e-3, **d)  # the mapping is identification_runs' kwargs
    assert [s.id for s in specs] == ["charge", "discharge", "pulse"]
    assert specs[0].valve.size == round(d["charge_time"] / 1e-3)
    assert identification_experiment_for(params) == d  # pure: same valve, same design
