"""The dataset contract's ``columns:``: an optional column left out (``null``), a canonical name
that gives way to a mapping claiming its file column, and the supply-pressure unit check."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml

from spa.datasets import load_spec, validate_dataset
from spa.datasets.checks import likelier_unit, supply_warning, typical_readings
from spa.datasets.contract import PRESSURE_UNITS

HEAD = {"description": "x", "origin": "bench", "rig": {}}


def _dataset(tmp_path: Path, spec: dict, kind: str = "charge") -> Path:
    """A dataset ``d`` of one run ``r`` (file ``r.csv``: time, the 0/1 command ``u``,
    pressure) described by ``spec`` (merged over the required keys)."""
    folder = tmp_path / "d"
    folder.mkdir(parents=True)
    t = np.arange(1000) * 1e-3
    pd.DataFrame({"time": t, "u": 1, "pressure": 0.6 * (1 - np.exp(-t / 0.1))}).to_csv(
        folder / "r.csv", index=False
    )
    doc = {"name": "d", **HEAD, **spec}
    doc.setdefault("runs", [{"id": "r", "kind": kind, "file": "r.csv"}])
    (folder / "dataset.yaml").write_text(yaml.safe_dump(doc, sort_keys=False))
    return folder


def _messages(folder: Path) -> list[str]:
    return [str(p) for p in validate_dataset(folder)]


def test_null_leaves_an_optional_column_out(tmp_path: Path) -> None:
    folder = _dataset(
        tmp_path, {"columns": {"t": "time", "p": "pressure", "valve": "u", "u": None}}
    )
    assert _messages(folder) == []
    run = load_spec(folder).runs[0]
    assert run.columns["u"] is None and run.columns["valve"] == "u"


def test_a_canonical_name_standing_for_itself_gives_way(tmp_path: Path) -> None:
    """``{valve: u}`` on a ``time,u,pressure`` log: ``u`` (not mapped) is left out, where
    it used to be refused as one file column serving two canonical ones."""
    folder = _dataset(tmp_path, {"columns": {"t": "time", "p": "pressure", "valve": "u"}})
    assert _messages(folder) == []
    assert load_spec(folder).runs[0].columns["u"] is None


def test_a_run_mapping_claims_the_column_the_dataset_left_standing(tmp_path: Path) -> None:
    spec = {
        "columns": {"t": "time", "p": "pressure"},
        "runs": [{"id": "r", "kind": "charge", "file": "r.csv", "columns": {"valve": "u"}}],
    }
    folder = _dataset(tmp_path, spec)
    assert _messages(folder) == []
    assert load_spec(folder).runs[0].columns == {
        "t": "time",
        "p": "pressure",
        "valve": "u",
        "u": None,
        "r": "r",
    }


def test_two_mapped_names_for_one_file_column_are_still_refused(tmp_path: Path) -> None:
    folder = _dataset(tmp_path, {"columns": {"t": "time", "p": "pressure", "valve": "x", "u": "x"}})
    (message,) = _messages(folder)
    assert "file column 'x' is used for several canonical columns ['valve', 'u']" in message
    assert "{u: null}" in message
    spec = {
        "columns": {"t": "time", "p": "pressure", "u": "u"},
        "runs": [{"id": "r", "kind": "pulse", "file": "r.csv", "columns": {"valve": "u"}}],
    }
    folder = _dataset(tmp_path / "run", spec)
    assert load_spec(folder).runs[0].columns["u"] is None  # u: u is its own name: it yields
    spec["columns"]["u"] = "duty"
    spec["runs"][0]["columns"] = {"valve": "duty"}
    (folder / "dataset.yaml").write_text(yaml.safe_dump({"name": "d", **HEAD, **spec}))
    (message,) = _messages(folder)
    assert "runs[0].columns" in message and "'duty' is used for several" in message


def test_pressure_cannot_be_left_out(tmp_path: Path) -> None:
    (message,) = _messages(_dataset(tmp_path, {"columns": {"p": None}}))
    assert "columns.p:" in message and "'p' cannot be left out (null)" in message


def test_time_left_out_needs_a_sample_step(tmp_path: Path) -> None:
    (message,) = _messages(_dataset(tmp_path, {"columns": {"t": None}}))
    assert "runs[0].sample_step [run 'r']" in message
    assert "columns: leaves out t (null)" in message and "sample_step: <s>" in message


def test_a_staircase_without_u_names_the_column_left_out(tmp_path: Path) -> None:
    spec = {
        "columns": {"t": "time", "p": "pressure", "valve": "u", "u": None},
        "runs": [
            {
                "id": "r",
                "kind": "staircase",
                "file": "r.csv",
                "modulator": {"type": "pwm", "f_w": 20},
            }
        ],
    }
    (message,) = _messages(_dataset(tmp_path, spec))
    assert "[run 'r']" in message and "leaves out u (null)" in message
    assert "a staircase run needs input fraction u" in message and "kind: pulse" in message


# --------------------------------------------------------------------------- supply units


def test_typical_readings_are_the_units_putting_the_supply_in_range() -> None:
    assert set(typical_readings(80.0)) == {"psi", "kPa"}
    assert set(typical_readings(2.0)) == {"bar"}
    assert typical_readings(1e5) == {}
    for unit, bar in typical_readings(300.0).items():
        assert 0.2 <= bar <= 6.0 and bar == pytest.approx(300.0 * PRESSURE_UNITS[unit])


@pytest.mark.parametrize(
    ("declared", "below", "above", "likelier"),
    [("psi", 58.5, 59.5, "kPa"), ("kPa", 485.0, 495.0, "mbar"), ("bar", 5.85, 5.95, "psi")],
)
def test_likelier_unit_where_another_reading_is_twice_nearer_1_bar(
    declared: str, below: float, above: float, likelier: str
) -> None:
    """The boundaries stated in the docstring, from the rule: the other reading's ratio to
    sqrt(0.2 * 6) bar is more than twice smaller."""
    assert likelier_unit(below, declared) is None
    unit, bar = likelier_unit(above, declared)
    assert unit == likelier and bar == pytest.approx(above * PRESSURE_UNITS[likelier])
    middle = math.sqrt(0.2 * 6.0)
    mine = above * PRESSURE_UNITS[declared]
    assert abs(math.log(mine / middle)) - abs(math.log(bar / middle)) > math.log(2.0)


def test_supply_warning_inside_the_plausible_range_names_the_likelier_unit() -> None:
    message = supply_warning(80 * PRESSURE_UNITS["psi"], "k2", "psi")
    assert message.startswith("k2 = 5.52 bar (80 psi) is unusual for a soft actuator's supply")
    assert "in kPa it would be 0.8 bar: pressure logged in kPa but declared psi?" in message
    assert supply_warning(0.6, "k2", "kPa") is None
    assert supply_warning(3.0, "k2", "bar") is None  # 3 bar, or 0.21 bar in psi: no call
    assert "outside the plausible" in supply_warning(0.0106, "k2", "kPa")  # unchanged


def test_a_unit_named_in_the_column_is_believed(tmp_path: Path) -> None:
    """80 in a column named ``p_psi`` declared psi is a 5.5 bar supply as stated: no warning;
    the same values in a column named ``pressure`` are warned about as likely kPa."""
    from spa.datasets.draft import guess_pressure_unit

    t = np.arange(1000) * 1e-3
    for name, warned in (("p_psi", False), ("pressure", True)):
        folder = tmp_path / name / "d"
        folder.mkdir(parents=True)
        frame = pd.DataFrame({"t": t, "valve": 1, name: 80 * (1 - np.exp(-t / 0.05))})
        frame.to_csv(folder / "r.csv", index=False)
        spec = {"name": "d", **HEAD, "units": {"pressure": "psi"}, "columns": {"p": name}}
        spec["runs"] = [{"id": "r", "kind": "charge", "file": "r.csv"}]
        (folder / "dataset.yaml").write_text(yaml.safe_dump(spec))
        messages = _messages(folder)
        assert len(messages) == warned and all("likely" not in m for m in messages)
        assert all("pressure logged in kPa but declared psi?" in m for m in messages)
        guess = guess_pressure_unit(frame[name], name)
        assert guess.value == ("kPa" if warned else "psi"), guess.reason
    assert guess_pressure_unit([0.0, 1e5], "P_kPa").value is None  # 1000 bar: name ignored


def test_validate_dot_names_the_folder(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """``spa validate .`` inside the dataset folder compares ``name`` with the folder's own
    name (it used to compare it with '')."""
    folder = _dataset(tmp_path, {"columns": {"t": "time", "p": "pressure", "valve": "u"}})
    monkeypatch.chdir(folder)
    assert _messages(Path(".")) == []
