"""spa's model plant in C (spa/synthetic/model_plant.c): spa.simulate stepped one tick at a
time, built under -std=c99 -Wall -Wextra -pedantic -Werror, equal to spa.simulate to 1e-12
bar under both delay conventions; the plan's player closed on it plays exactly what it plays
on spa.simulate; a valve with its own laws is refused, by name."""

from __future__ import annotations

import shutil
from dataclasses import replace

import numpy as np
import pandas as pd
import pytest

from spa import simulate
from spa.model.laws import Laws
from spa.model.params import ValveParams
from spa.plan.design import design_session
from spa.plan.folder import write_plan
from spa.plan.host import (
    build_harness,
    planned_commands,
    play_on_model,
    play_on_plant,
    play_session,
    session_ticks,
)
from spa.plan.limits import Limits
from spa.plan.record import read_plan
from spa.synthetic._model_c import MODEL_CFLAGS, model_constants, run_model_in_c

pytestmark = pytest.mark.skipif(shutil.which("cc") is None, reason="no C compiler 'cc'")

VALVES = {
    "nominal": ValveParams(),
    "fast-on slow-off": ValveParams(c1=0.2, k2=4.0, tau2=0.1, t_on=0.012, t_off=0.002),
    "no delays": ValveParams(t_on=0.0, t_off=0.0),
    "no exhaust delay": ValveParams(t_on=0.004, t_off=0.0),
}


def _commands(seed: int, n: int) -> np.ndarray:
    """Runs of geometric length (mean ~7 ticks): many pulses shorter than the delays, edges
    during holds; and one run in 50 of 3 s, long enough to fill or empty the actuator."""
    rng = np.random.default_rng(seed)
    lengths = np.where(rng.random(n) < 0.02, 3000, rng.geometric(0.15, n))
    u = np.repeat(np.arange(lengths.size) % 2, lengths)[:n].astype(np.int8)
    return u if seed % 2 else 1 - u  # one draw starts with the valve open (settled)


@pytest.mark.parametrize("delay", ["hold", "transport"])
@pytest.mark.parametrize("name", list(VALVES))
def test_the_twin_equals_simulate(name, delay):
    valve = replace(VALVES[name], delay=delay)
    for seed, p0 in ((1, 0.0), (2, 0.3)):
        u = _commands(seed, 20000)
        p = run_model_in_c(valve, u, 1e-3, p0=p0)
        expected = simulate(u, 1e-3, valve, p0)
        assert p.shape == expected.shape
        assert np.abs(p - expected).max() <= 1e-12, (name, delay, seed)
        assert np.ptp(expected) > 0.5 * valve.k2  # the draw swings the pressure


def test_the_twin_builds_under_the_players_strict_flags():
    """run_model_in_c builds with these (a warning fails the build), as the player does."""
    strict = {"-std=c99", "-Wall", "-Wextra", "-pedantic", "-Werror", "-ffp-contract=off"}
    assert strict <= set(MODEL_CFLAGS)
    from spa.plan.host import STRICT

    assert strict <= set(STRICT)


def test_the_conventions_differ_and_the_twin_follows_each():
    """The same command through the two conventions gives different pressures: the twin
    does not merely agree with one of them."""
    u = _commands(3, 5000)
    hold = run_model_in_c(VALVES["nominal"], u, 1e-3)
    transport = run_model_in_c(replace(VALVES["nominal"], delay="transport"), u, 1e-3)
    assert np.abs(hold - transport).max() > 1e-3


def test_a_valve_with_its_own_laws_is_refused_by_name(tmp_path):
    lawful = ValveParams(laws=Laws(log_g=(0.0, 0.3, 0.5, 0.2), log_h=(0.0, -0.2, -0.4, -0.5)))
    with pytest.raises(ValueError, match=r"paper's two laws only.*ValveParams\.laws"):
        model_constants(lawful)
    with pytest.raises(ValueError, match=r"ValveParams\.laws"):
        run_model_in_c(lawful, np.zeros(10, np.int8), 1e-3)
    with pytest.raises(TypeError, match="ValveParams"):
        model_constants({"c1": 0.5})  # type: ignore[arg-type]
    assert model_constants(replace(lawful, laws=None))[-1] == 0.0


@pytest.mark.parametrize("delay", ["hold", "transport"])
def test_the_player_plays_on_the_twin_what_it_plays_on_simulate(tmp_path, delay):
    """A pilot session closed tick by tick on the model in C gives the stream that the
    player gives on spa.simulate of the same valve (iterated to a fixed point), command
    for command and line for line."""
    valve = ValveParams(c1=0.12, k2=0.3, tau2=0.06, t_on=0.0008, t_off=0.0015, delay=delay)
    design = design_session(valve, Limits(p_max=0.4), pilot=True, precondition=1)
    folder = tmp_path / "pilot"
    write_plan(folder, design)
    n = session_ticks(folder)
    noise = np.random.default_rng(4).normal(0.0, 0.002, n)
    stream, commands = play_on_model(folder, valve, noise, work=tmp_path)
    assert np.array_equal(commands, planned_commands(design))
    exe = build_harness(folder, tmp_path / "player")
    cal = read_plan(folder)["calibration"]
    ref, ref_commands, _ = play_session(
        exe, design, lambda u: simulate(u, design.dt, valve), cal, noise
    )
    assert np.array_equal(commands, ref_commands)
    assert stream == ref
    assert play_on_plant(folder, valve, noise, work=tmp_path)[0] == stream


def test_a_model_valve_keeps_its_promise_closed_on_its_twin(tmp_path):
    """small-fast (the full configuration's model-made valve): its pilot played on the model
    in C → the stages → spa plan --verify, its closed-loop staircases through controller.h
    by the player on the model in C. Every promise row has a verdict, inside the session's
    band on the same valve (and at most one outside its own 95 % band); the identified
    delays lie within their intervals and one tick of the truth."""
    from pathlib import Path

    import yaml

    from spa.plan.prior import prior_from_numbers
    from spa.plan.record import record_stream
    from spa.plan.roundtrip import stages_in_memory, verify_on

    config = yaml.safe_load((Path(__file__).parents[1] / "config" / "config.yaml").read_text())
    entry = config["simulated"]["small-fast"]
    truth = ValveParams(**entry["params"])
    sd = float(entry["sensor"]["noise"])
    limits = Limits(p_max=1.25 * truth.k2)
    design = design_session(
        prior_from_numbers(truth.k2, 5 * truth.tau2), limits, pilot=True, precondition=1
    )
    folder = tmp_path / "small-fast"
    write_plan(folder, design)
    noise = np.random.default_rng(2).normal(0.0, sd, session_ticks(folder))
    stream, _ = play_on_model(folder, truth, noise)
    assert all(line.endswith("ok") for line in record_stream(folder, stream.splitlines()))
    cfg = {**config["closed_loop"], "levels_fraction": [0.2, 0.4, 0.6]}
    stages = stages_in_memory(folder, tmp_path / "results", config["analytic"]["selected"], cfg)
    for d in ("t_on", "t_off"):
        got = stages["identified"][d]
        assert got["lo"] <= getattr(truth, d) <= got["hi"], d
        assert abs(got["value"] - getattr(truth, d)) <= design.dt, d
    assert stages["promise"].get("kept"), "the closed loop made no promise on small-fast"
    done = verify_on(tmp_path / "verify", tmp_path / "results", truth, limits.p_max, noise_sd=sd)
    plan = read_plan(done.folder)
    loops = [r for r in plan["runs"] if r["kind"] == "closed_loop"]
    assert loops and (done.folder / "player" / "controller.h").is_file()
    for run in loops:  # closed on the pressure: the valve switches through every staircase
        assert pd.read_csv(done.folder / run["file"])["valve"].nunique() == 2, run["id"]
    promise = done.frame[done.frame["part"] == "promise"]
    assert len(promise) == len(loops) * len(plan["verify"]["promise"]["bands"])
    # each 95 % band lets one measurement in twenty out on the valve identified; the
    # session's verdict (its Sidak level over every prediction) is what must hold
    assert (promise["session"] == "inside").all(), promise.to_string()
    assert (promise["verdict"] == "kept").sum() >= len(promise) - 1, promise.to_string()
