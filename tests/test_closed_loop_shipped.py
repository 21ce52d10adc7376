"""One shipped controller: on a slow 2.5 bar valve whose promise lengthens tau_c, the header,
controllers.yaml's chosen entry, the sentence and every row marked chosen name the same loop
(spa.closedloop.shipped)."""

from __future__ import annotations

import re

import numpy as np
import pandas as pd
import pytest
import yaml

from spa.closedloop.bench import apply_bench, bench_outputs
from spa.closedloop.comparison import closed_loop
from spa.closedloop.shipped import comparison_name
from spa.model.params import ValveParams
from spa.stages.closed_loop import write_closed_loop

# A slow valve (t_on 15 ms, t_off 30 ms) on a fast 2.5 bar actuator: the gain-scheduled PI
# at the stage's tau_c (1.6 s on these levels) overshoots over the box merged with a +-30 %
# gain error, and the promise (three levels, 0.25, 1.5 and 2 bar) holds only at 2.4 s.
VALVE = ValveParams(c1=0.6, k2=2.5, tau2=0.5, t_on=0.015, t_off=0.030)
CFG = {
    "levels_fraction": [0.1, 0.6, 0.8],
    "step_hold": 1.0,
    "sine": {"offset": 0.35, "amplitude": 0.1, "frequency": 0.5, "duration": 3.0, "skip": 1.0},
}
ERROR = {"gain": (0.8, 1.3)}


@pytest.fixture(scope="module")
def shipped(tmp_path_factory):
    result = closed_loop(VALVE, [{"type": "pwm", "f_w": 20.0}], None, CFG)
    result.controllers["controller"] = "scheduled"  # the loop the promise is made for
    bench = bench_outputs(result, VALVE, None, CFG, 0.004, model_error=ERROR)
    design_gains = result.controllers["controllers"]["pwm-20Hz"]["scheduled"]
    apply_bench(result, bench)
    out = tmp_path_factory.mktemp("closed_loop")
    paths = {k: out / f"{k}.{ext}" for k, ext in (
        ("table", "csv"), ("controllers", "yaml"), ("fig10_csv", "csv"), ("fig11_csv", "csv"),
        ("recorded", "csv"), ("robust", "csv"), ("header", "h"), ("sketch", "ino"),
    )}  # fmt: skip
    write_closed_loop(result, pd.DataFrame(), {k: str(v) for k, v in paths.items()}, bench)
    return result, bench, design_gains, paths


def _header_array(header: str, name: str) -> list[float]:
    found = re.search(rf"spa_ctrl_{name}\[\d+\] = \{{([^}}]*)\}}", header)
    assert found, name
    return [float(v) for v in found.group(1).split(",")]


def test_the_promise_lengthens_tau_c_on_this_valve(shipped):
    result, bench, _, _ = shipped
    promise = bench.summary["promise"]
    assert promise["kept"] and promise["tau_c"] > result.controllers["tau_c"]
    assert bench.shipped is not None and bench.shipped.tau_c == promise["tau_c"]


def test_header_gains_equal_the_chosen_entry_and_the_sentence(shipped):
    _, bench, design_gains, paths = shipped
    written = yaml.safe_load(paths["controllers"].read_text())
    entry = written["controllers"]["pwm-20Hz"]
    chosen = entry[written["controller"]]
    header = paths["header"].read_text()
    kp, ki = _header_array(header, "kp"), _header_array(header, "ki")
    np.testing.assert_allclose(kp, chosen["kp"], rtol=1e-12)
    np.testing.assert_allclose(ki, chosen["ki"], rtol=1e-12)
    assert entry["tau_c"] == bench.summary["promise"]["tau_c"] == written["shipped_tau_c"]
    # the sentence names the shipped gains and tau_c, not the stage's design
    said = f"Kp = {min(chosen['kp']):.3g}–{max(chosen['kp']):.3g} /bar"
    assert said in written["sentence"]
    assert f"designed at τ_c = {entry['tau_c']:.3g} s" in written["sentence"]
    old = f"Kp = {min(design_gains['kp']):.3g}–{max(design_gains['kp']):.3g} /bar"
    assert old != said and old not in written["sentence"]
    assert f"tau_c = {entry['tau_c']:g} s" in header
    # the design at the stage's tau_c is kept, labelled for comparison
    kept = entry["for_comparison"]
    assert kept["tau_c"] == written["tau_c"] and kept["scheduled"]["kp"] == design_gains["kp"]
    assert "for comparison" in kept["note"] and "not shipped" in kept["note"]


def test_every_chosen_row_is_the_shipped_loop(shipped):
    result, bench, _, paths = shipped
    robust = pd.read_csv(paths["robust"])
    row = robust[robust["chosen"]].iloc[0]
    assert row["tau_c"] == pytest.approx(bench.summary["promise"]["tau_c"], rel=1e-12)
    assert row["tau_c_robust"] == pytest.approx(row["tau_c"], rel=1e-12)
    assert row["worst_overshoot"] == pytest.approx(bench.summary["promise"]["overshoot"])
    table = pd.read_csv(paths["table"])
    mine = table[(table.modulator == "pwm-20Hz") & (table.controller == "scheduled")]
    stair = mine[(mine.experiment == "staircase") & (mine.metric == "overshoot")]
    assert len(stair) == 1
    rows = pd.DataFrame(bench.shipped.rows)
    shipped_over = rows[(rows.experiment == "staircase") & (rows.metric == "overshoot")]
    assert stair["max"].iloc[0] == pytest.approx(shipped_over["max"].iloc[0])
    compared = table[table.controller == comparison_name("scheduled", result.controllers["tau_c"])]
    assert not compared.empty and set(compared.experiment) >= {"staircase", "steps", "sine"}
    # the figures' data show the shipped loop alone under its name
    for key in ("fig10_csv", "fig11_csv"):
        frame = pd.read_csv(paths[key])
        assert not frame.controller.str.contains("for comparison").any(), key
