"""End to end on each compliant balloon of the full configuration, whose identification
chose its own laws: the closed-loop stage's functions design on the laws valve (built from
params.yaml's laws record), make a promise and export a header that compiles strictly and
equals the Python loop; closed on the balloon in C, the header keeps its verified promise."""

from __future__ import annotations

import shutil
import subprocess
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import yaml

from spa.closedloop.controller import PIController
from spa.closedloop.experiments import staircase_reference, step_periods
from spa.closedloop.loop import closed_loop_arrays
from spa.closedloop.promise import design_for_dataset, promise_kept
from spa.identification import identify_with_config, load_params
from spa.identification.identified import read_identified
from spa.model.modulators import Modulator
from spa.synthetic.balloons import BALLOON_SEEDS, SHORT_SESSION, compliant_balloons
from spa.synthetic.physical import close_loop_in_c, measure_staircase

ROOT = Path(__file__).resolve().parents[1]
CONFIG = yaml.safe_load((ROOT / "config" / "config.yaml").read_text())
CLOSED_LOOP = {**CONFIG["closed_loop"], "levels_fraction": [0.2, 0.4, 0.6]}
DT = 1e-3
NAMES = ("balloon-06", "balloon-04")
MODULATORS = SHORT_SESSION["modulators"]
EXPERIMENTS = SHORT_SESSION["experiments"]

_HARNESS = r"""
#include <stdio.h>
#include "controller.h"

int main(void)
{
    spa_ctrl_state s;
    spa_ctrl_output o;
    double r, p;
    spa_ctrl_init(&s, 0.0);
    while (scanf("%lf %lf", &r, &p) == 2) {
        o = spa_ctrl_step(&s, r, p);
        printf("%d %.17g\n", o.valve, o.xi);
    }
    return 0;
}
"""


@pytest.fixture(scope="module", params=NAMES)
def stage(request, tmp_path_factory):
    """Each balloon's dataset, identified through the pipeline's identify entry, and the
    closed-loop stage's design on the laws valve of its params.yaml."""
    from spa.datasets import read_runs
    from spa.synthetic.runs import generate_dataset

    name = request.param
    plant = compliant_balloons()[name]
    cfg = {
        "plant": {"kind": "physical", **plant.to_mapping()},
        "controller_dt": DT,
        "sensor": {"fs": 1000.0},
        "modulators": MODULATORS,
    }
    folder = tmp_path_factory.mktemp("balloon") / name
    generate_dataset(name, cfg, EXPERIMENTS, BALLOON_SEEDS[name], folder)
    runs, metas = read_runs(folder)
    kinds = {r: m["kind"] for r, m in metas.items()}
    identified = identify_with_config(runs, kinds, {}, metas=metas).to_dict()
    assert identified["laws"]["chosen"] == "identified"
    valve = read_identified(identified)
    valve = replace(valve, params=load_params(identified))  # the laws valve, built once
    assert valve.params.laws is not None
    result, bench = design_for_dataset(
        identified, runs, metas, MODULATORS, CLOSED_LOOP, valve=valve
    )
    return plant, valve, result, bench


def test_the_laws_valves_header_compiles_strictly_and_equals_the_python_loop(stage, tmp_path):
    cc = shutil.which("cc")
    assert cc, "no C compiler 'cc' on the PATH (make test installs one)"
    _, valve, result, bench = stage
    ctl = result.controllers
    mod = Modulator.from_mapping(ctl["setting"])
    assert "Flash:" in bench.header
    (tmp_path / "controller.h").write_text(bench.header)
    (tmp_path / "main.c").write_text(_HARNESS)
    exe = tmp_path / "main"
    cmd = [cc, "-std=c99", "-O2", "-Wall", "-Wextra", "-pedantic", "-Werror",
           str(tmp_path / "main.c"), "-o", str(exe), "-lm"]  # fmt: skip
    subprocess.run(cmd, check=True, capture_output=True, text=True)
    # The shipped PI, as the header's comment records it.
    said = bench.header[bench.header.index("Controller: ") + 12 :].split("\n", 1)[0]
    ctrl = PIController.from_mapping(yaml.safe_load(said))
    levels = [float(v) for v in bench.summary["promise"]["levels"]]
    r = staircase_reference(levels, 2.0, DT)
    p, xi, u = closed_loop_arrays(r, DT, mod, ctrl, valve.params, 0.0)
    assert 0 < u.mean() < 1
    rows = "\n".join(f"{float(a)!r} {float(b)!r}" for a, b in zip(r, p, strict=True))
    out = subprocess.run([str(exe)], input=rows + "\n", capture_output=True, text=True)
    got = np.loadtxt(out.stdout.splitlines(), ndmin=2)
    np.testing.assert_array_equal(got[:, 0], u)
    np.testing.assert_array_equal(got[:, 1], xi)


def test_the_verified_promise_holds_on_the_balloon_in_c(stage, tmp_path):
    plant, valve, result, bench = stage
    summary = bench.summary
    promise = summary["promise"]
    assert summary["verified"], bench.sentence
    assert promise.get("kept"), bench.sentence
    header = tmp_path / "controller.h"
    header.write_text(bench.header)
    levels, hold = [float(v) for v in promise["levels"]], float(promise["hold"])
    run = close_loop_in_c(header, plant, levels, hold, lead=hold, rng=np.random.default_rng(7))
    mod = Modulator.from_mapping(result.controllers["setting"])
    period = step_periods(mod, valve.params, levels, DT)
    _, measured = measure_staircase(run, period, skip=hold, r_initial=levels[0])
    _, actual = measure_staircase(run, period, column="p_true", skip=hold, r_initial=levels[0])
    measured = {**measured, "worst_ripple_pp": actual["worst_ripple_pp"]}
    verdict = promise_kept(measured, promise, CLOSED_LOOP["max_overshoot"])
    assert verdict["promised"] and verdict["kept"], (verdict, measured, promise)
