"""A bench run driven by LPWM, the model-inverse PWM spa recommends, is described and
validated under the raw/ contract, with the valve constants the modulator inverts."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import yaml

import spa
from spa.datasets import load_spec, validate_dataset
from spa.model.modulators import kinds

DT = 1e-3  # the bench's logging and controller step, s
VALVE = {"c1": 0.45, "k2": 1.05, "tau2": 0.7, "t_on": 0.004, "t_off": 0.009}


def lpwm_dataset(folder: Path, modulator: dict, written: dict | None = None) -> Path:
    """A dataset folder with one LPWM staircase, simulated on the valve it inverts, and
    described in ``dataset.yaml`` with ``written`` (default: ``modulator``)."""
    t = np.arange(round(22 / DT)) * DT
    xi = np.minimum(np.floor(t / 2) / 10, 1.0)  # 0 -> 1 by 0.1 every 2 s
    valve = spa.modulate("lpwm", xi, DT, **{k: v for k, v in modulator.items() if k != "type"})
    p = spa.simulate(valve, DT, spa.ValveParams(**VALVE))
    folder.mkdir(parents=True)
    pd.DataFrame({"t": t, "p": p, "valve": valve, "u": xi}).to_csv(
        folder / "stair_lpwm.csv", index=False
    )
    spec = {
        "name": folder.name,
        "description": "one staircase through LPWM at 47 Hz",
        "origin": "synthetic",
        "rig": {"valve": "3/2 on/off solenoid valve (simulated)"},
        "runs": [
            {"id": "stair_lpwm", "kind": "staircase", "file": "stair_lpwm.csv",
             "modulator": written or modulator},
        ],
    }  # fmt: skip
    (folder / "dataset.yaml").write_text(yaml.safe_dump(spec, sort_keys=False))
    return folder


def test_an_lpwm_run_with_its_valve_constants_validates(tmp_path):
    modulator = {"type": "lpwm", "f_w": 47.0, **VALVE}
    folder = lpwm_dataset(tmp_path / "lpwm_bench", modulator)
    problems = validate_dataset(folder)
    assert [str(p) for p in problems if p.level == "error"] == []
    (run,) = load_spec(folder).runs
    assert run.modulator == modulator  # the constants are kept, not dropped or renamed


def test_an_lpwm_run_without_valve_constants_validates_and_a_typo_is_named(tmp_path):
    assert validate_dataset(lpwm_dataset(tmp_path / "a", {"type": "lpwm", "f_w": 47.0})) == []
    bad = {"type": "lpwm", "f_w": 47.0, "tau_2": 0.7}
    folder = lpwm_dataset(tmp_path / "b", {"type": "lpwm", "f_w": 47.0}, written=bad)
    problems = [str(p) for p in validate_dataset(folder)]
    assert any("tau_2" in p and "tau2" in p for p in problems), problems


def test_a_modulated_run_without_a_modulator_is_told_every_kind(tmp_path):
    folder = lpwm_dataset(tmp_path / "c", {"type": "lpwm", "f_w": 47.0})
    spec = yaml.safe_load((folder / "dataset.yaml").read_text())
    del spec["runs"][0]["modulator"]
    (folder / "dataset.yaml").write_text(yaml.safe_dump(spec))
    (problem,) = [str(p) for p in validate_dataset(folder) if "needs a modulator" in str(p)]
    for kind in kinds():
        assert f"type: {kind}" in problem, (kind, problem)


def test_the_contract_page_lists_every_modulator_kind():
    text = (Path(__file__).resolve().parents[1] / "raw" / "README.md").read_text()
    row = next(line for line in text.splitlines() if line.startswith("| `modulator` |"))
    for kind in kinds():
        assert f"type: {kind}" in row, kind
