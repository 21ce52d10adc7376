"""Output-error refinement, delay conventions, the logging-step rule and model adequacy."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest

from spa.identification import identify_with_config
from spa.identification.adequacy import Adequacy, adequacy_clause, assess
from spa.identification.longrun import andrews_bandwidth, newey_west
from spa.identification.refine import block_means, chain_runs, replay_kernel
from spa.model.modulators import modulate
from spa.model.params import ValveParams
from spa.model.plant import replay, run_start_pressures, simulate
from spa.synthetic import Sensor, identification_runs
from spa.synthetic.runs import run_seed, simulate_run
from spa.tuning.valve import tune

NAMES = ("c1", "k2", "tau2", "t_on", "t_off")
CONFIG = {"identification": {"max_delay": 0.06}}


def _staircase(params: ValveParams, dt: float, f_w: float, delay: str, rng, every: int = 1):
    xi = np.repeat(np.arange(0.0, 1.01, 0.1), int(3.0 / dt))
    u = modulate("pwm", xi, dt, f_w=f_w)
    p = simulate(u, dt, params, 0.0, delay=delay)
    idx = np.arange(0, u.size, every)
    noisy = p[idx] + rng.normal(0.0, 0.003, idx.size)
    return pd.DataFrame({"t": idx * dt, "p": noisy, "valve": u[idx], "u": xi[idx]})


def _dataset(params: ValveParams, fs: float, delay: str = "hold", seed: int = 0):
    dt = 1e-3
    every = round(1.0 / (fs * dt))
    sensor = Sensor(fs=fs, noise=0.003, quantum=0.0)
    specs = identification_runs(params, dt)
    runs = {s.id: simulate_run(s, params, dt, sensor, run_seed(seed, "t", s.id)) for s in specs}
    kinds = {s.id: s.kind for s in specs}
    rng = np.random.default_rng(seed)
    for f_w in (10.0, 20.0):
        rid = f"staircase_pwm{f_w:g}"
        runs[rid] = _staircase(params, dt, f_w, delay, rng, every)
        kinds[rid] = "staircase"
    mods = {rid: ("pwm" if rid.startswith("staircase") else "") for rid in runs}
    if delay == "transport":  # the whole bench is the transport plant, pulse runs too
        for s in specs:
            t = runs[s.id]["t"].to_numpy()
            p = simulate(s.valve, dt, params, s.p0, delay="transport")[::every]
            runs[s.id]["p"] = p + rng.normal(0.0, 0.003, t.size)
    return runs, kinds, mods


def test_chain_runs_equals_the_plain_python_recurrence() -> None:
    rng = np.random.default_rng(1)
    level = rng.integers(0, 2, 500).astype(bool)
    active = rng.uniform(0, 0.05, 500)
    prm = ValveParams()
    np.testing.assert_allclose(
        chain_runs(level, active, 0.2, prm.c1, prm.k2, prm.tau2),
        run_start_pressures(level, active, 0.2, prm),
        rtol=0,
        atol=1e-15,
    )


def test_replay_kernel_equals_the_vectorised_replay() -> None:
    rng = np.random.default_rng(8)
    starts = np.r_[0.0, np.sort(rng.uniform(0, 5, 300))]
    level = np.arange(starts.size) % 2 == 1
    prm = ValveParams(t_on=0.004, t_off=0.012)
    hold = np.where(level, prm.t_on, prm.t_off)
    hold[0] = 0.0
    t = np.sort(rng.uniform(0, 6, 4000))
    t[0] = 0.0
    np.testing.assert_allclose(
        replay_kernel(starts, level, hold, 0.3, prm.c1, prm.k2, prm.tau2, t),
        replay(t, starts, level, hold, 0.3, prm),
        rtol=0,
        atol=1e-14,
    )


def test_block_means_and_newey_west() -> None:
    assert block_means(np.arange(6.0), 3).tolist() == [1.0, 4.0]
    s = np.random.default_rng(2).normal(size=(400, 2))
    np.testing.assert_allclose(newey_west(s, 0), s.T @ s)
    ar = np.zeros(2000)
    e = np.random.default_rng(3).normal(size=2000)
    for k in range(1, ar.size):
        ar[k] = 0.9 * ar[k - 1] + e[k]
    assert andrews_bandwidth(ar) > andrews_bandwidth(e)


def test_recovers_its_own_valve_and_reports_both_conventions() -> None:
    truth = ValveParams(0.4, 1.5, 0.5, 0.006, 0.015)
    runs, kinds, mods = _dataset(truth, 1000.0)
    res = identify_with_config(
        runs, kinds, CONFIG, modulators=mods, command_dt=dict.fromkeys(runs, 1e-3)
    )
    for name in NAMES:
        assert getattr(res, name).contains(getattr(truth, name)), name
    d = res.to_dict()
    assert d["delay_convention"]["chosen"] == "hold"
    assert set(d["delay_convention"]) >= {"hold", "transport", "heldout_fit"}
    assert d["adequacy"]["adequate"] is True
    assert d["adequacy"]["measured_modulators"] == ["pwm"]
    assert "staircase_pwm20" in d["refinement"]["informed_by"]["t_on"]
    assert not res.warnings


def test_500_hz_log_of_a_slow_exhaust_covers_or_warns() -> None:
    """A 500 Hz log of a 1 kHz controller, t_on 9 ms and t_off 38 ms (a bench user's case):
    the controller's step is not known, so each logged edge lies anywhere in its 2 ms step."""
    truth = ValveParams(0.533, 0.837, 0.826, 0.009, 0.038)
    runs, kinds, mods = _dataset(truth, 500.0, seed=4)
    res = identify_with_config(runs, kinds, CONFIG, modulators=mods)
    d = res.to_dict()
    assert d["refinement"]["n_edges_off"] > 0
    for name in ("t_on", "t_off"):
        est = getattr(res, name)
        unresolved = any(w.startswith(f"{name} is not resolved") for w in res.warnings)
        assert est.contains(getattr(truth, name)) or unresolved, (name, est)
    # nothing declares how the command relates to the log and nothing replays it: the
    # edges are taken on the tick and each delay's interval reaches one step (2 ms) above
    assert d["valve_edges"]["rule"] == "undecided"
    resolved = [name for name in ("t_on", "t_off") if getattr(res, name).resolved]
    assert resolved == ["t_on", "t_off"], "both delays are resolved from this log"
    for name in resolved:
        assert "up to 2 ms before the logged ones" in getattr(res, name).method
    # the pulse fit of this log has edges of both kinds (so no "(n_edges_...: 0)" warning)
    assert d["fits"]["pulse"]["n_edges_on"] > 0 and d["fits"]["pulse"]["n_edges_off"] > 0


def test_no_falling_edge_is_never_silent() -> None:
    truth = ValveParams()
    runs, kinds, _mods = _dataset(truth, 1000.0)
    base = identify_with_config(runs, kinds, {**CONFIG, "identification": {"refine": False}})
    from spa.identification.refined import refine_result

    only_rising = {"charge": runs["charge"]}
    # the simulated controller's step: the log starts with the command (a run without an edge
    # is replayed from its first sample only then)
    res = refine_result(base, only_rising, kinds, command_dt={"charge": 1e-3})
    assert any("t_off is not resolved: no falling valve edge" in w for w in res.warnings)
    assert res.t_off.lo == 0.0 and res.t_off.hi == pytest.approx(0.05)
    assert "params.yaml" not in res.to_dict()  # plain content
    assert res.to_dict()["warnings"] == list(res.warnings)


def test_refinement_improves_the_fit_of_a_plant_that_is_not_the_hold_model() -> None:
    """Transport-delay data (the valve keeps its connection during its dead time) fitted by the
    hold convention: the pulse fit's delays describe the staircases poorly; the refinement
    improves every staircase's FIT and the transport convention is chosen."""
    truth = ValveParams(0.533, 0.837, 0.826, 0.004, 0.025)
    runs, kinds, mods = _dataset(truth, 1000.0, delay="transport", seed=5)
    res = identify_with_config(
        runs, kinds, CONFIG, modulators=mods, command_dt=dict.fromkeys(runs, 1e-3)
    )
    ref = res.refinement
    assert ref is not None
    for rid in ("staircase_pwm10", "staircase_pwm20"):
        assert ref["fit_after"][rid] >= ref["fit_before"][rid]
    assert res.delay_convention["chosen"] == "transport"
    tr = res.delay_convention["transport"]
    assert abs(tr["t_on"] - truth.t_on) < 1e-3 and abs(tr["t_off"] - truth.t_off) < 1e-3


def test_poor_adequacy_says_so_and_names_the_worst_run() -> None:
    held = {"stair_pwm20": 62.0, "stair_pwm10": 70.0, "pulse": 95.0}
    a = assess(
        held,
        {k: v + 5 for k, v in held.items()},
        dict.fromkeys(held, 98.0),
        {"stair_pwm20": "pwm", "stair_pwm10": "pwm", "pulse": ""},
    )
    assert not a.adequate
    assert a.worst_run == "stair_pwm20"
    assert "does not describe this valve well enough" in a.sentence
    clause = adequacy_clause(a, "pwm")
    assert clause == (
        "the model does not describe this valve well enough (held-out FIT 62 % on run stair_pwm20)"
    )
    assert Adequacy.from_mapping(a.to_dict()) == a
    both = adequacy_clause(a, "dsm")
    assert "not measured with this modulator" in both


def test_adequacy_clause_is_empty_when_adequate_and_measured() -> None:
    a = assess({"s": 97.0}, {"s": 97.5}, {"s": 98.0}, {"s": "pwm"})
    assert a.adequate and adequacy_clause(a, "pwm") == ""
    assert adequacy_clause(None, "pwm") == ""
    assert "nan" not in adequacy_clause(Adequacy(adequate=False), "pwm")


def test_poor_fit_dataset_gets_an_unverified_recommendation() -> None:
    a = assess({"stair": 40.0}, {"stair": 55.0}, {"stair": 97.0}, {"stair": "pwm"})
    params = {n: {"value": v} for n, v in ValveParams().as_dict().items()}
    result = tune({**params, "adequacy": a.to_dict()}, n_xi=20)
    rec = result.recommendation
    assert rec["verified"] is False
    assert "does not describe this valve well enough" in rec["sentence"]
    assert "stair" in rec["sentence"]
    assert "nan" not in rec["sentence"].lower().replace("nan ", "")
    good = assess({"stair": 97.0}, {"stair": 97.0}, {"stair": 98.0}, {"stair": "pwm"})
    measured = good.to_dict()
    measured["measured_modulators"] = ["pwm", "ipfm", "iipfm", "dsm", "lpwm"]
    rec = tune({**params, "adequacy": measured}, n_xi=20).recommendation
    assert rec["verified"] is True and "Not verified" not in rec["sentence"]
    rec = tune({**params, "adequacy": {**measured, "measured_modulators": []}}, n_xi=20)
    assert "not measured with this modulator" in rec.recommendation["sentence"]
    assert math.isfinite(len(rec.sentence))


def test_without_a_pulse_run_the_delays_come_from_the_other_runs() -> None:
    truth = ValveParams(0.533, 0.837, 0.826, 0.006, 0.020)
    runs, kinds, mods = _dataset(truth, 1000.0, seed=7)
    del runs["pulse"], kinds["pulse"], mods["pulse"]
    res = identify_with_config(
        runs, kinds, CONFIG, modulators=mods, command_dt=dict.fromkeys(runs, 1e-3)
    )
    assert any(w.startswith("the pulse fit gave no delays (no pulse run") for w in res.warnings)
    assert not res.fallback
    for name in ("t_on", "t_off"):
        assert getattr(res, name).contains(getattr(truth, name)), name
    with pytest.raises(Exception, match="no pulse run"):
        identify_with_config(runs, kinds, {"identification": {"refine": False}})


def test_a_poorly_described_valve_gets_sentences_that_say_so() -> None:
    """End to end: a plant that is not the model (its sensor lags by 0.4 s and saturates)
    is identified as inadequate, and the tuning's sentence says so and names the worst run."""
    from scipy.signal import lfilter

    truth = ValveParams()
    runs, kinds, mods = _dataset(truth, 1000.0, seed=9)
    a = 1e-3 / 0.4
    for table in runs.values():
        p = np.clip(table["p"].to_numpy(), 0.0, None)
        lagged = lfilter([a], [1.0, a - 1.0], p, zi=[p[0] * (1.0 - a)])[0]
        table["p"] = truth.k2 * np.tanh(2.5 * lagged / truth.k2)
    # the paper's laws: a static sensor map would be a change of variable the actuator's own
    # laws absorb; the lag they cannot, and the residuals' whiteness check names it
    paper = {**CONFIG, "identification": {**CONFIG.get("identification", {}), "laws": "paper"}}
    res = identify_with_config(
        runs, kinds, paper, modulators=mods, command_dt=dict.fromkeys(runs, 1e-3)
    )
    d = res.to_dict()
    assert d["adequacy"]["adequate"] is False
    worst = d["adequacy"]["worst_run"]["run"]
    rec = tune(d, n_xi=20).recommendation
    assert rec["verified"] is False
    assert "does not describe this valve well enough" in rec["sentence"]
    assert worst in rec["sentence"]
    auto = identify_with_config(
        runs, kinds, CONFIG, modulators=mods, command_dt=dict.fromkeys(runs, 1e-3)
    ).to_dict()
    assert auto["adequacy"]["checks_passed"] is False
    assert "a lagging sensor" in auto["adequacy"]["sentence"]


def test_fit_csv_shows_the_fit_before_the_refinement(tmp_path) -> None:
    import yaml

    from spa.validation import validate_runs, with_fit_before_refinement

    truth = ValveParams(t_on=0.004, t_off=0.025)
    runs, kinds, mods = _dataset(truth, 1000.0, delay="transport", seed=5)
    res = identify_with_config(
        runs, kinds, CONFIG, modulators=mods, command_dt=dict.fromkeys(runs, 1e-3)
    )
    path = tmp_path / "params.yaml"
    path.write_text(yaml.safe_dump(res.to_dict()))
    table = validate_runs(runs, res.to_valve_params(), None, kinds)
    out = with_fit_before_refinement(table, runs, path, None, kinds)
    assert (
        list(out.columns).index("fit_before_refinement")
        == list(out.columns).index("fit_percent") - 1
    )
    stair = out.set_index("run").loc["staircase_pwm20"]
    assert stair["fit_percent"] > stair["fit_before_refinement"]
    path.write_text(yaml.safe_dump({k: v for k, v in res.to_dict().items() if k != "refinement"}))
    assert "fit_before_refinement" not in with_fit_before_refinement(table, runs, path, None, kinds)
