"""The round trip on model-made valves spanning the range: plan (from what a lab knows:
its supply and a rough fill time) → the C player closed on the valve → its stream through
spa record → spa validate with no edit → identification: each delay inside its 95 %
interval and within one logging step of the truth. And the plan's margins, both ways."""

from __future__ import annotations

import io
from contextlib import redirect_stdout

import numpy as np
import pytest

from spa import simulate
from spa.cli import main
from spa.datasets import ingest_dataset, read_runs
from spa.identification import identify_with_config
from spa.model.params import ValveParams
from spa.plan.design import design_session
from spa.plan.folder import calibration_for, write_plan
from spa.plan.host import build_harness, planned_commands, play_session
from spa.plan.limits import Limits
from spa.plan.precision import predict_precision
from spa.plan.prior import prior_from_numbers
from spa.plan.record import record_stream

#: config/config.yaml's model-made valves, with the sensor noise of each.
VALVES = {
    "small-fast": (ValveParams(c1=0.12, k2=0.3, tau2=0.06, t_on=0.0008, t_off=0.0015), 0.002),
    "large-slow": (ValveParams(c1=1.8, k2=4.0, tau2=2.5, t_on=0.015, t_off=0.025), 0.01),
    "long-exhaust": (ValveParams(c1=0.6, k2=2.0, tau2=0.5, t_on=0.005, t_off=0.030), 0.005),
}


def _record_and_identify(tmp_path, design, plant, p_max: float, noise: np.ndarray) -> dict:
    """The session from its plan to its identification, as a lab runs it: the plan's folder,
    the C player closed on ``plant`` (commands -> pressure), its stream through spa record
    and spa validate with no edit, then the identification of the recordings (its
    ``to_dict()``). Asserts the player issued the plan's commands and every run recorded."""
    folder = tmp_path / "session"
    write_plan(folder, design)
    exe = build_harness(folder, tmp_path / "player")
    stream, cmds, _ = play_session(exe, design, plant, calibration_for(p_max), noise)
    assert np.array_equal(cmds, planned_commands(design))
    report = record_stream(folder, stream.splitlines())
    assert all(line.endswith("ok") for line in report), report
    buf = io.StringIO()
    with redirect_stdout(buf):
        assert main(["validate", str(folder)]) == 0, buf.getvalue()
    ingest_dataset(folder, tmp_path / "runs")
    runs, metas = read_runs(tmp_path / "runs")
    res = identify_with_config(runs, {k: m["kind"] for k, m in metas.items()}, metas=metas)
    return res.to_dict()


@pytest.mark.parametrize("name", list(VALVES))
def test_round_trip_identifies_the_delays_within_one_step(name, tmp_path):
    truth, noise = VALVES[name]
    prior = prior_from_numbers(truth.k2, 5 * truth.tau2)  # what the lab knows
    limits = Limits(p_max=1.25 * truth.k2)
    design = design_session(prior, limits, pilot=True, precondition=1)
    n = planned_commands(design).size
    out = _record_and_identify(
        tmp_path,
        design,
        lambda u: simulate(u, design.dt, truth),
        limits.p_max,
        np.random.default_rng(1).normal(0.0, noise, n),
    )
    for delay in ("t_on", "t_off"):
        est = out[delay]
        true = getattr(truth, delay)
        assert est["lo"] <= true <= est["hi"], (name, delay, est, true)
        assert abs(est["value"] - true) <= design.dt, (name, delay, est["value"], true)


def test_margins_hold_three_times_both_ways_and_fail_without_them():
    limits = Limits(p_max=1.0)
    cal = calibration_for(1.0)
    kept = predict_precision(design_session(ValveParams(), limits, pilot=True), cal)
    assert kept["met"].all(), kept[~kept["met"]].to_string()
    bare = predict_precision(design_session(ValveParams(), limits, pilot=True, margin=1.0), cal)
    slow = bare[bare["corner"] == "3x slower"]
    assert not slow["met"].any() and "keep the valve open longer" in slow["note"].iloc[0]
    assert bare[bare["corner"] == "prior"]["met"].all()


def _physical(name: str):
    from pathlib import Path

    import yaml

    from spa.synthetic.runs import dataset_plant

    cfg = yaml.safe_load((Path(__file__).parents[1] / "config" / "config.yaml").read_text())
    return dataset_plant(cfg["simulated"][name])


@pytest.mark.parametrize("name", ["phys-finger", "phys-choked", "phys-balloon"])
def test_round_trip_on_the_full_configs_physical_plants(name, tmp_path):
    from spa.synthetic.physical import run_plant_in_c

    plant, equivalent = _physical(name)
    prior = prior_from_numbers(plant.supply, 5 * equivalent.tau2)
    limits = Limits(p_max=1.25 * plant.supply)
    design = design_session(prior, limits, pilot=True, precondition=1)
    n = planned_commands(design).size
    out = _record_and_identify(
        tmp_path,
        design,
        lambda u: run_plant_in_c(plant, u, design.dt)[1],
        limits.p_max,
        np.random.default_rng(2).normal(0.0, plant.noise, n),
    )
    k2 = out["k2"]["value"]
    assert abs(k2 - plant.supply) < 0.1 * plant.supply, (name, k2)


@pytest.mark.parametrize("factor", [3.0, 1.0 / 3.0], ids=["3x-slower", "3x-faster"])
def test_a_nominal_plan_recorded_on_a_valve_three_times_off_still_identifies(factor, tmp_path):
    """The plan's margins, recorded: a pilot planned for the paper's valve, played by the C
    player on a valve 3x slower (or faster) than that prior, validates and identifies, every
    parameter's 95 % interval holding the truth."""
    from spa.plan.prior import scaled

    truth = scaled(ValveParams(), factor)
    limits = Limits(p_max=1.0)
    design = design_session(ValveParams(), limits, pilot=True, precondition=1)
    assert design.margins["time_scale"] >= 3.0
    n = planned_commands(design).size
    got = _record_and_identify(
        tmp_path,
        design,
        lambda u: simulate(u, design.dt, truth),
        limits.p_max,
        np.random.default_rng(4).normal(0.0, 0.003, n),
    )
    for name in ("c1", "k2", "tau2", "t_on", "t_off"):
        est, true = got[name], getattr(truth, name)
        assert est["fallback"] is None, (name, est)
        assert est["lo"] <= true <= est["hi"], (factor, name, est, true)


def test_a_plan_that_misses_its_targets_is_resized_until_it_meets_more():
    """Sized from predicted precision: runs sized for the prior alone (no margin) miss the
    3x-slower corner; the plan resizes itself (longer runs, more replicates) and misses less."""
    from spa.plan.precision import size_for_targets

    limits = Limits(p_max=1.0)
    cal = calibration_for(1.0)

    def make(replicates, margin):
        return design_session(
            ValveParams(), limits, pilot=True, replicates=replicates, margin=margin
        )

    first = predict_precision(make(3, 1.0), cal)
    design, table, said = size_for_targets(make, 3, 1.0, cal)
    assert said and "3x slower" in said[0] and "replicates" in said[0]
    assert design.margins["time_scale"] > 1.0
    assert (~table["met"]).sum() < (~first["met"]).sum(), table.to_string()
