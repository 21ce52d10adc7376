"""Real logs: coarse, unstamped, charge-and-discharge-only logs are taken as far as their samples
go and no further, and the delays follow the log's edge-timing rule.

The datasets are made here (spa.synthetic.coarse, the exact model, the physical plant), never
read from or written to raw/.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest

from spa.identification import identify_with_config
from spa.identification.diagnostics import repeats_agree, whiteness
from spa.identification.edges import dataset_edge_timing, edge_timing
from spa.identification.identified import read_identified
from spa.model.params import ValveParams
from spa.synthetic.coarse import coarse_runs

ARDUINO = ValveParams(c1=0.084, k2=0.88, tau2=0.092, t_on=0.012, t_off=0.018)


def _kinds(runs: dict[str, pd.DataFrame]) -> dict[str, str]:
    return {rid: rid.split("_")[0] for rid in runs}


@pytest.fixture(scope="module")
def arduino() -> dict[str, pd.DataFrame]:
    return coarse_runs(ARDUINO, np.random.default_rng(7))


def test_a_50_hz_charge_and_discharge_log_identifies_the_rates(arduino) -> None:
    """Five charges and five discharges of 50 samples at 20 ms (the Arduino log): the closed
    forms give c1, k2, tau2 with intervals that cover the truth (benchmarks/coarse_coverage.py
    measures the rate over 200 valves)."""
    res = identify_with_config(arduino, _kinds(arduino), {})
    assert "too short for a Savitzky-Golay derivative" in res.c1.method
    hits = dict.fromkeys(("c1", "k2", "tau2"), 0)
    for seed in range(8):
        runs = coarse_runs(ARDUINO, np.random.default_rng(seed))
        res = identify_with_config(runs, _kinds(runs), {})
        for name in hits:
            est = getattr(res, name)
            assert est.fallback is None and est.lo < est.value < est.hi
            assert abs(est.value / getattr(ARDUINO, name) - 1) < 0.03, (name, est)
            hits[name] += est.contains(getattr(ARDUINO, name))
    assert min(hits.values()) >= 6, hits


def test_an_unresolved_delay_is_an_interval_never_a_point(arduino) -> None:
    res = identify_with_config(arduino, _kinds(arduino), {"identification": {"max_delay": 0.05}})
    for name in ("t_on", "t_off"):
        est = getattr(res, name)
        assert not est.resolved
        assert (est.lo, est.hi) == (0.0, 0.05)
        assert est.lo <= est.value <= est.hi
        assert est.fallback is None
        assert any(
            w.startswith(f"{name} is not resolved") and "on the pressure's clock" in w
            for w in res.warnings
        )
    d = res.to_dict()
    assert d["t_on"]["resolved"] is False
    ident = read_identified(d)
    # every design downstream gets the interval's worst case and the box spans it
    assert ident.unresolved == {"t_on": (0.0, 0.05), "t_off": (0.0, 0.05)}
    assert ident.params.t_on == 0.05 and ident.intervals["t_on"] == (0.0, 0.05)
    assert d["adequacy"]["modulated_assessed"] is False
    assert "not assessed" in d["adequacy"]["sentence"]


def test_the_tuning_says_it_is_unverified_on_an_unresolved_delay(arduino) -> None:
    from spa.tuning import tune
    from spa.tuning.cost import DEFAULT_SWEEPS

    res = identify_with_config(arduino, _kinds(arduino), {})
    coarse = {k: {**g, "step": g["step"] * 10} for k, g in DEFAULT_SWEEPS.items()}
    out = tune(res.to_dict(), sweeps=coarse, n_xi=30)
    rec = out.recommendation
    assert rec["unresolved"]["t_on"] == [0.0, res.t_on.hi]
    assert rec.get("verified") is not True
    assert "not resolved by the data" in rec["sentence"]


def test_a_fallback_is_marked_with_the_interval_it_really_has(tmp_path) -> None:
    runs, metas = _simulated(tmp_path, [{"type": "pwm", "f_w": 20.0}], "fb")
    kinds = {r: m["kind"] for r, m in metas.items()}
    cfg = {
        "identification": {"use_fallback": True, "tail_fraction": 0.97},
        "nominal": ValveParams().as_dict(),
    }
    res = identify_with_config(runs, kinds, cfg, metas=metas)
    # refined, so not the nominal value any more (the top-level list names those only)
    assert "c1" not in res.fallback
    assert "started from the nominal value" in (res.c1.fallback or "")
    # refined on the runs with edges: its interval is the data's, not the distance to 0.533
    assert res.c1.contains(TRUTH.c1)
    assert res.c1.hi - res.c1.lo < 0.2 * TRUTH.c1
    assert res.to_dict()["c1"]["fallback"]
    # where nothing refines it, a fallback keeps its nominal value and no interval
    arduino_runs = coarse_runs(ARDUINO, np.random.default_rng(2), repeats=2)
    res = identify_with_config(arduino_runs, _kinds(arduino_runs), cfg)
    assert res.c1.value == ValveParams().c1 and res.c1.lo is None and res.c1.fallback
    assert "c1" in res.fallback


def test_sensor_noise_is_the_sensors_not_the_models_residual(arduino) -> None:
    res = identify_with_config(arduino, _kinds(arduino), {})
    noise = res.to_dict()["noise"]
    assert noise["upper_bound"] is False
    assert abs(noise["sensor"] - 0.004) < 0.3 * 0.004, noise


def test_a_throttled_vent_repeat_is_flagged_and_the_model_not_called_adequate() -> None:
    runs = coarse_runs(ARDUINO, np.random.default_rng(3))
    throttled = ValveParams(c1=20 * ARDUINO.c1, k2=ARDUINO.k2, tau2=ARDUINO.tau2)
    slow = coarse_runs(throttled, np.random.default_rng(4), repeats=1, samples=250)
    runs["discharge_5"] = slow["discharge_1"]
    res = identify_with_config(runs, _kinds(runs), {})
    checks = res.to_dict()["checks"]
    assert checks["repeats_agree"] is False
    assert checks["repeats"]["c1"]["outlier"] == "discharge_5"
    assert res.adequacy["adequate"] is False
    assert any("repeats disagree on c1: run discharge_5" in w for w in res.warnings)


def test_repeats_that_agree_pass_the_chi_square() -> None:
    rng = np.random.default_rng(0)
    est = {f"r{i}": 0.5 + 0.01 * rng.normal() for i in range(5)}
    assert repeats_agree("c1", est, dict.fromkeys(est, 0.01)).agree


def test_a_charge_with_two_time_constants_fails_the_whiteness_test() -> None:
    """A second state (heat exchange: a fast and a slow approach) is named, not absorbed."""
    rng = np.random.default_rng(5)
    t = np.arange(0, 4.0, 0.005)
    k2 = 0.8
    p = k2 * (1 - 0.6 * np.exp(-t / 0.1) - 0.4 * np.exp(-t / 1.0)) + rng.normal(0, 0.002, t.size)
    charge = pd.DataFrame({"t": t, "p": p})
    fit_runs = {"charge_1": charge, **coarse_runs(ARDUINO, rng, repeats=1, fs=200.0)}
    fit_runs.pop("charge_1", None)
    fit_runs["charge_1"] = charge
    res = identify_with_config(fit_runs, _kinds(fit_runs), {})
    assert res.checks["whiteness"]["charge_1"]["white"] is False
    assert any("not white on run(s) charge_1" in w for w in res.warnings)
    model = identify_with_config(
        coarse_runs(ARDUINO, np.random.default_rng(6), fs=200.0),
        _kinds(coarse_runs(ARDUINO, np.random.default_rng(6), fs=200.0)),
        {},
    )
    assert model.checks["white"] is True


def test_whiteness_band_and_statistic() -> None:
    rng = np.random.default_rng(1)
    white = whiteness("w", rng.normal(size=500))
    assert white.white and white.lags == 20
    ar = np.zeros(500)
    e = rng.normal(size=500)
    for k in range(1, 500):
        ar[k] = 0.7 * ar[k - 1] + e[k]
    red = whiteness("r", ar)
    assert not red.white and 1 in red.outside and red.q > red.q_limit


# --------------------------------------------------------------------------------------------
# The edge-timing rule
# --------------------------------------------------------------------------------------------

TRUTH = ValveParams(c1=0.45, k2=1.2, tau2=0.4, t_on=0.004, t_off=0.007)


def _simulated(tmp_path, modulators, name="x"):
    from spa.datasets import read_runs
    from spa.synthetic.runs import generate_dataset

    cfg = {
        "params": TRUTH.as_dict(),
        "controller_dt": 1e-4,
        "sensor": {"fs": 1000.0, "noise": 0.004, "quantum": 0.001},
        "modulators": modulators,
    }
    exp = {
        "identification": {"charge_time": 3.0, "discharge_time": 2.0, "repeats": 2},
        "staircase": {"step": 0.2, "hold": 2.0},
    }
    generate_dataset(name, cfg, exp, 1, tmp_path / name)
    return read_runs(tmp_path / name)


def test_edges_on_the_logs_tick_give_the_delays_within_a_tenth_of_a_millisecond(tmp_path):
    """Commands at 0.1 ms, logged at 1 ms, every edge on a log tick (PWM 20 Hz, ΔΣ 20 ms,
    pulses of whole ms): no half step is added."""
    runs, metas = _simulated(
        tmp_path, [{"type": "pwm", "f_w": 20.0}, {"type": "dsm", "period": 0.02}]
    )
    res = identify_with_config(runs, {r: m["kind"] for r, m in metas.items()}, {}, metas=metas)
    assert res.valve_edges["rule"] == "on_tick"
    for name in ("t_on", "t_off"):
        est = getattr(res, name)
        assert abs(est.value - getattr(TRUTH, name)) < 1e-4, (name, est.value)
        assert est.contains(getattr(TRUTH, name))


def test_edges_off_the_logs_tick_are_detected_as_sampled_and_covered(tmp_path):
    runs, metas = _simulated(
        tmp_path,
        [{"type": "iipfm", "t_l": 0.0203, "gain": 1.2}, {"type": "ipfm", "t_h": 0.0207}],
        "y",
    )
    stairs = [r for r, m in metas.items() if m["kind"] == "staircase"]
    for rid in stairs:
        timing = edge_timing(runs[rid], metas[rid])
        assert (timing.rule, timing.source) == ("sampled", "modulator replayed")
        assert timing.width == pytest.approx(0.0009)
    res = identify_with_config(runs, {r: m["kind"] for r, m in metas.items()}, {}, metas=metas)
    for name in ("t_on", "t_off"):
        assert getattr(res, name).contains(getattr(TRUTH, name)), name
    assert "middle of their" in res.t_on.method


def test_a_declared_rule_wins_and_an_undecided_one_is_one_sided() -> None:
    t = np.arange(200) * 0.02
    valve = (np.arange(200) // 20) % 2
    run = pd.DataFrame({"t": t, "p": 0.0 * t, "valve": valve})
    assert edge_timing(run, {"valve_edges": "on_tick"}).shifts(3).tolist() == [0, 0, 0]
    assert edge_timing(run, {"valve_edges": "sampled"}).shifts(2).tolist() == [0.01, 0.01]
    undecided = edge_timing(run, {})
    assert (undecided.rule, undecided.width) == ("undecided", 0.02)
    with pytest.raises(ValueError, match="valve_edges must be one of on_tick, sampled"):
        edge_timing(run, {"valve_edges": "ontick"})
    # a pulse run follows the dataset's modulated runs when a replay decided them all
    from spa.model.modulators import modulate

    u = np.repeat([0.2, 0.5, 0.8], 100)
    stair = pd.DataFrame(
        {
            "t": np.arange(300) * 0.001,
            "p": 0.0,
            "u": u,
            "valve": modulate("pwm", u, 0.001, f_w=20.0),
        }
    )
    pulse = pd.DataFrame({"t": np.arange(200) * 0.001, "p": 0.0, "valve": valve})
    timings = dataset_edge_timing(
        {"stair": stair, "pulse": pulse},
        {"stair": {"modulator": {"type": "pwm", "f_w": 20.0}}, "pulse": {}},
    )
    assert timings["stair"].rule == "on_tick"
    assert (timings["pulse"].rule, timings["pulse"].source) == (
        "on_tick",
        "the dataset's modulated runs",
    )


def test_no_estimate_lies_outside_its_own_bounds(arduino) -> None:
    runs = {rid: t.assign(valve=int(rid.startswith("charge"))) for rid, t in arduino.items()}
    res = identify_with_config(runs, _kinds(runs), {"identification": {"max_delay": 0.05}})
    bounded = [n for n in ("c1", "k2", "tau2", "t_on", "t_off") if getattr(res, n).lo is not None]
    assert bounded == ["c1", "k2", "tau2", "t_on", "t_off"], "every estimate has its bounds"
    for name in bounded:
        est = getattr(res, name)
        assert est.lo <= est.value <= est.hi, (name, est)
    assert res.t_on.hi <= 0.05 and res.t_off.hi <= 0.05
    assert not math.isnan(res.k2.value)


def test_the_sensor_noise_of_a_choked_4_bar_plant_is_its_own(tmp_path) -> None:
    """The full config's phys-choked plant (8 mbar noise, 2 mbar ADC step, 4 mbar mains hum):
    the reported sensor noise is within 30 % of the noise it was given, not the model's
    residual (choked flow is not the paper's law: ~150 mbar)."""
    from pathlib import Path

    import yaml

    from spa.datasets import read_runs
    from spa.synthetic.runs import generate_dataset

    root = Path(__file__).resolve().parents[1]
    cfg = yaml.safe_load((root / "config" / "config.yaml").read_text())
    ds = {**cfg["simulated"]["phys-choked"], "modulators": [{"type": "pwm", "f_w": 20.0}]}
    exp = {"identification": cfg["experiments"]["identification"]}
    exp["staircase"] = {"step": 0.25, "hold": 2.0}
    generate_dataset("phys-choked", ds, exp, 1, tmp_path / "choked")
    runs, metas = read_runs(tmp_path / "choked")
    res = identify_with_config(runs, {r: m["kind"] for r, m in metas.items()}, {}, metas=metas)
    given = ds["plant"]["noise"]
    assert abs(res.noise["sensor"] - given) < 0.3 * given, res.noise
    assert res.noise["upper_bound"] is False
    assert res.noise["model_residual"] > 5 * given  # reported, under its own name


def test_a_coarse_log_of_a_physical_plant_identifies() -> None:
    """The physical plant (not the model) logged at 50 Hz as five charges and discharges."""
    from spa.synthetic.draws import random_plant
    from spa.synthetic.physical import equivalent_params

    plant = random_plant(np.random.default_rng(1), full=False)
    runs = coarse_runs(equivalent_params(plant), np.random.default_rng(2), plant=plant)
    res = identify_with_config(runs, _kinds(runs), {})
    assert abs(res.k2.value / plant.supply - 1) < 0.05
    assert not res.t_on.resolved and not res.t_off.resolved
