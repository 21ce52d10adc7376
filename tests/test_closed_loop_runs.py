"""Closed-loop runs in the dataset contract: validate, ingest, simulate, replay."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml

from spa.closedloop.controller import PIController
from spa.closedloop.experiments import staircase_reference
from spa.closedloop.loop import simulate_closed_loop
from spa.closedloop.replay import RUN_COLUMNS, recorded_runs
from spa.datasets import check_dataset, ingest_dataset, read_runs
from spa.model.params import ValveParams
from spa.synthetic.runs import closed_loop_runs, simulate_run
from spa.synthetic.sensor import Sensor

MOD = {"type": "iipfm", "t_l": 0.02, "gain": 1.15}
CTRL = {"kp": 4.0, "ki": 4.5, "dt": 0.001}


def _bench(root: Path, controller: object = CTRL) -> Path:
    """A bench export of one closed-loop run: time in ms, pressure and set-point in kPa."""
    r = staircase_reference([0.1, 0.4], 1.5, 1e-3)
    run = simulate_closed_loop(r, 1e-3, MOD, PIController(kp=4.0, ki=4.5), ValveParams())
    folder = root / "raw" / "bench1"
    folder.mkdir(parents=True)
    doc = {
        "name": "bench1",
        "description": "closed loop",
        "origin": "bench",
        "rig": {"valve": "v", "actuator": "a", "sensors": "s", "controller": "c"},
        "units": {"time": "ms", "pressure": "kPa"},
        "columns": {"t": "time", "p": "P", "r": "setpoint", "valve": "cmd", "u": "xi"},
        "runs": [
            {
                "id": "cl1",
                "kind": "closed_loop",
                "file": "cl1.csv",
                "modulator": MOD,
                "controller": controller,
            }
        ],
    }
    (folder / "dataset.yaml").write_text(yaml.safe_dump(doc, sort_keys=False))
    table = run.rename(columns={"t": "time", "p": "P", "r": "setpoint", "valve": "cmd", "xi": "xi"})
    table["time"] *= 1000.0
    table["P"] *= 100.0
    table["setpoint"] *= 100.0
    table.to_csv(folder / "cl1.csv", index=False)
    return folder


def test_a_bench_closed_loop_run_validates_ingests_and_replays(tmp_path: Path) -> None:
    folder = _bench(tmp_path)
    problems, _ = check_dataset(folder)
    assert not [p for p in problems if p.is_error], problems
    ingest_dataset(folder, tmp_path / "runs")
    runs, metas = read_runs(tmp_path / "runs")
    assert metas["cl1"]["kind"] == "closed_loop"
    assert metas["cl1"]["controller"] == {"kp": 4.0, "ki": 4.5, "dt": 0.001}
    table = runs["cl1"]
    assert set(table.columns) == {"t", "p", "valve", "u", "r"}
    assert table["r"].iloc[0] == pytest.approx(0.1)  # kPa -> bar
    out = recorded_runs(runs, metas, ValveParams())
    assert list(out.columns) == list(RUN_COLUMNS)
    row = out.iloc[0]
    assert row.fit > 99.0  # the same model: the replay matches up to unit round-off
    assert row.rise_time_max == pytest.approx(row.rise_time_max_model, abs=0.01)


@pytest.mark.parametrize(
    ("controller", "message"),
    [
        (None, "needs its controller"),
        ({"kp": 1.0}, "kp and dt are required"),
        ({"kp": -1.0, "dt": 0.001}, ">= 0"),
        ({"kp": 1.0, "dt": 5.0}, "step in s"),
    ],
)
def test_a_closed_loop_run_needs_a_valid_controller(tmp_path, controller, message) -> None:
    folder = _bench(tmp_path, controller)
    problems, _ = check_dataset(folder)
    errors = [str(p) for p in problems if p.is_error]
    assert any(message in e and "controller" in e for e in errors), errors


def test_simulated_closed_loop_runs() -> None:
    params = ValveParams()
    cfg = {"levels": [0.2, 0.5], "hold": 1.0, "modulators": [MOD, {"type": "pwm", "f_w": 20.0}]}
    specs = closed_loop_runs(params, 1e-3, cfg)
    assert [s.id for s in specs] == ["closed_loop_iipfm-20ms-G1.15", "closed_loop_pwm-20Hz"]
    assert specs[0].controller["dt"] == 1e-3
    sensor = Sensor.from_mapping({"fs": 500.0, "noise": 0.0, "quantum": 0.0})
    table = simulate_run(specs[0], params, 1e-3, sensor, np.random.default_rng(0))
    assert list(table.columns) == ["t", "p", "valve", "u", "r"]
    assert len(table) == 1500  # 3 levels (up and down) of 1 s at 500 Hz
    # Noise-free and logged at every other step: the replay reproduces it.
    meta = {"kind": "closed_loop", "modulator": MOD, "controller": specs[0].controller}
    out = recorded_runs({"x": table}, {"x": meta}, params)
    assert out.iloc[0].fit > 99.9


def test_init_drafts_a_closed_loop_run_and_asks_for_its_controller(tmp_path: Path) -> None:
    from spa.datasets.draft_yaml import draft_dataset

    folder = _bench(tmp_path)
    (folder / "dataset.yaml").unlink()
    text = draft_dataset(folder)
    doc = yaml.safe_load(text)
    assert doc["columns"]["r"] == "setpoint" and doc["columns"]["p"] == "P"
    run = doc["runs"][0]
    assert run["kind"] == "closed_loop"
    assert run["modulator"]["type"] == "iipfm"
    assert run["controller"] == "TODO"  # the gains are not in the data
    (folder / "dataset.yaml").write_text(text)
    errors = [str(p) for p in check_dataset(folder)[0] if p.is_error]
    assert any("controller" in e for e in errors), errors
    doc["runs"][0]["controller"] = CTRL
    doc["rig"] = {"valve": "v"}
    (folder / "dataset.yaml").write_text(yaml.safe_dump(doc, sort_keys=False))
    errors = [str(p) for p in check_dataset(folder)[0] if p.is_error]
    assert errors == []
