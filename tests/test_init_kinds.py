"""``spa init`` and ``spa validate`` on logs with a quiet lead-in and a set-point column."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml

from spa.cli import main
from spa.datasets.draft import guess_kind, guess_roles

ROOT = Path(__file__).resolve().parents[1]
FS = 500.0  # Hz, the gripper's log
T = np.arange(0.0, 4.0, 1.0 / FS)
LEAD = 0.3  # s the valve is held before its one switch
K2, TAU2, C1, T_ON, T_OFF = 1.2, 0.6, 0.5, 0.007, 0.038


def _charge() -> tuple[np.ndarray, np.ndarray]:
    valve = (T >= LEAD).astype(float)
    el = np.maximum(T - LEAD - T_ON, 0.0)
    return valve, K2 * (1.0 - np.exp(-el / TAU2))


def _discharge() -> tuple[np.ndarray, np.ndarray]:
    valve = (T < LEAD).astype(float)
    el = np.maximum(T - LEAD - T_OFF, 0.0)
    return valve, np.maximum(np.sqrt(K2) - el / (2.0 * C1), 0.0) ** 2


def test_a_charge_behind_a_quiet_lead_in_is_a_charge():
    """Issue case 4: a log holding the valve 0.3 s before its one switch was drafted
    ``kind: pulse  # valve switches 1 times``."""
    valve, p = _charge()
    guess = guess_kind(T, p, valve)
    assert guess.value == "charge", guess
    assert "open from t = 0.3 s" in guess.reason and "rises" in guess.reason
    valve, p = _discharge()
    assert guess_kind(T, p, valve).value == "discharge"
    # a charge that closes the valve again at the end of the log is still a charge
    valve, p = _charge()
    valve[T > 3.8] = 0.0
    assert guess_kind(T, p, valve).value == "charge"


def test_pulses_and_a_contradicting_pressure_stay_pulses():
    valve = ((T % 0.5) < 0.3).astype(float)
    assert guess_kind(T, np.cumsum(valve), valve).value == "pulse"
    valve, p = _charge()
    assert guess_kind(T, p[::-1], valve).value == "pulse"  # opens, pressure falls: not clean


@pytest.mark.parametrize("name", ["ref", "ref [psi]", "setpoint", "r [bar]", "Reference (psi)"])
def test_set_point_columns_are_recognised(name):
    """Issue case 4: the set-point column ``ref [psi]`` was not recognised."""
    valve, p = _charge()
    r = np.where(T > 2.0, 10.0, 5.0)
    roles = guess_roles({"time [s]": T, "p [psi]": 14.5 * p, "valve": valve, name: r})
    assert roles["r"].value == name, roles["r"]
    assert roles["p"].value == "p [psi]"


def test_a_ref_holding_a_fraction_beside_a_pressure_in_psi_is_the_input():
    valve = ((T % 0.05) < 0.02).astype(float)
    roles = guess_roles({"t": T, "p": 14.5 * np.cumsum(valve) / valve.sum(), "valve": valve,
                         "ref": np.where(T > 2.0, 0.6, 0.3)})  # fmt: skip
    assert roles["r"].value is None and roles["u"].value == "ref"


def _write(folder: Path, name: str, valve: np.ndarray, p: np.ndarray) -> None:
    pd.DataFrame({"time [s]": T, "p [bar]": p, "valve": valve.astype(int)}).to_csv(
        folder / name, index=False
    )


@pytest.fixture
def lab(tmp_path: Path) -> Path:
    folder = tmp_path / "lab"
    folder.mkdir()
    _write(folder, "charge.csv", *_charge())
    _write(folder, "discharge.csv", *_discharge())
    pulses = ((T % 0.5) >= 0.2).astype(float)
    _write(folder, "pulse.csv", pulses, 0.5 + 0.1 * pulses)
    return folder


def test_init_drafts_lead_in_logs_as_charge_and_discharge(lab: Path, capsys):
    assert main(["init", str(lab)]) == 0
    draft = yaml.safe_load((lab / "dataset.yaml").read_text())
    kinds = {r["file"]: r["kind"] for r in draft["runs"]}
    assert kinds == {"charge.csv": "charge", "discharge.csv": "discharge", "pulse.csv": "pulse"}
    text = (lab / "dataset.yaml").read_text()
    assert "valve switches 1 times" not in text


def test_validate_checks_each_run_kind_against_its_valve(lab: Path, capsys):
    """Issue case 4: ``spa validate`` passed a charge log declared ``kind: pulse`` and
    ``spa identify`` then failed with "no charge run"."""
    assert main(["init", str(lab)]) == 0
    spec = lab / "dataset.yaml"
    draft = yaml.safe_load(spec.read_text())
    capsys.readouterr()
    for run in draft["runs"]:
        if run["file"] == "charge.csv":
            run["kind"] = "pulse"
        if run["file"] == "discharge.csv":
            run["kind"] = "charge"
    spec.write_text(yaml.safe_dump(draft, sort_keys=False))
    assert main(["validate", str(lab)]) != 0
    out = capsys.readouterr().out
    charge_id = next(r["id"] for r in draft["runs"] if r["file"] == "charge.csv")
    assert f"pulse run {charge_id!r}: the valve switches once (opens at t = 0.3 s" in out
    assert "Is it a charge run (kind: charge)?" in out
    # the discharge log declared a charge opens the valve during its lead-in: it passes
    # this check; a charge run whose valve never opens does not
    _write(lab, "closed.csv", np.zeros_like(T), np.full_like(T, 0.01))
    draft["runs"].append({"id": "closed", "kind": "charge", "file": "closed.csv"})
    spec.write_text(yaml.safe_dump(draft, sort_keys=False))
    assert main(["validate", str(lab)]) != 0
    assert "charge run 'closed': the valve never opens" in capsys.readouterr().out
