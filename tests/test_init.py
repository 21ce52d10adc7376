"""``spa init``: the guessers of spa.datasets.draft against simulated runs whose truth is known,
and the draft dataset.yaml written for a copy of raw/example."""

from __future__ import annotations

import hashlib
import shutil
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pytest
import yaml

import spa.datasets.draft_read as draft_read
import spa.datasets.draft_yaml as dy
from spa.cli import main
from spa.datasets import check_dataset
from spa.datasets.draft import (
    guess_kind,
    guess_modulator,
    guess_pressure_unit,
    guess_roles,
    guess_time_unit,
)
from spa.datasets.yaml_loader import _UniqueKeyLoader
from spa.model.modulators import get_kind
from spa.model.params import ValveParams
from spa.synthetic.example import EXAMPLE_PARAMS
from spa.synthetic.runs import identification_runs, modulated_runs, simulate_run
from spa.synthetic.sensor import Sensor

ROOT = Path(__file__).resolve().parents[1]
EXAMPLE = ROOT / "raw" / "example"
DT = 1e-3
SENSOR = Sensor(fs=1000.0, noise=0.004, quantum=0.001)
MODULATORS: list[dict[str, Any]] = [
    {"type": "pwm", "f_w": 20.0},
    {"type": "pwm", "f_w": 12.5},
    {"type": "ipfm", "t_h": 0.02, "gain": 1.2},
    {"type": "ipfm", "t_h": 0.01},
    {"type": "iipfm", "t_l": 0.02, "gain": 1.15},
    {"type": "dsm", "period": 0.005},
    {"type": "dsm", "period": 0.01},  # around u = 0.5 most highs and lows last one clock
]
EXPERIMENTS = {
    "staircase": {"step": 0.25, "hold": 1.5},
    # u reaches 0 and 1 mid-run: back-to-back IPFM (IIPFM) pulses merge there
    "sine": {"frequency": 0.5, "amplitudes": [0.5, 0.3, 0.2], "periods_per_level": 2},
    "chirp": {"f0": 0.5, "f1": 20.0, "duration": 12.0},
}


def _simulated(spec: Any) -> pd.DataFrame:
    return simulate_run(spec, EXAMPLE_PARAMS, DT, SENSOR, np.random.default_rng(7))


# --------------------------------------------------------------------------- roles


def test_roles_of_the_example_columns() -> None:
    t = np.arange(500.0)
    g = guess_roles(
        {
            "xi_ref": np.repeat([0.0, 0.5, 1.0, 0.5, 0.2], 100),
            "time_ms": t,
            "valve_cmd": (t % 7 < 3).astype(float),
            "P_act_kPa": 50 + 10 * np.sin(t / 30),
        }
    )
    assert {k: v.value for k, v in g.items()} == {
        "t": "time_ms",
        "valve": "valve_cmd",
        "u": "xi_ref",
        "p": "P_act_kPa",
        "r": None,
    }
    assert all(v.reason for v in g.values())


def test_roles_pressure_in_bar_within_0_1_is_not_taken_for_u() -> None:
    t = np.linspace(0, 5, 501)
    g = guess_roles({"t": t, "p_bar": 0.8 * (1 - np.exp(-t)), "valve": np.ones_like(t)})
    assert g["p"].value == "p_bar" and g["u"].value is None
    # unnamed: the only column left is the pressure, and the reason says it may be bar
    g = guess_roles({"a": t, "b": 0.8 * (1 - np.exp(-t))})
    assert g["p"].value == "b" and "bar" in g["p"].reason and g["u"].value is None


def test_roles_names_and_scores_break_ties() -> None:
    n = np.arange(1000.0)
    t = n * 1e-3 + 1e-7 * np.sin(n)  # uneven steps lose against the sample index...
    g = guess_roles({"index": n, "time_s": t, "P1": np.sin(n), "P2": 3 * np.sin(n)})
    assert g["t"].value == "time_s"  # ...but the name wins
    assert g["p"].value == "P2" and "largest variance" in g["p"].reason
    g = guess_roles({"x": np.sin(n)})
    assert g["t"].value is None and "strictly increasing" in g["t"].reason


def test_roles_skip_columns_with_nan() -> None:
    t = np.arange(10.0)
    g = guess_roles({"t": t, "p": np.where(t > 5, np.nan, t)})
    assert g["p"].value is None


# --------------------------------------------------------------------------- units


@pytest.mark.parametrize(
    ("step", "unit"),
    [
        (1e-3, "s"),  # 1 kHz in s
        (1.0, "ms"),  # 1 kHz in ms
        (1e-5, "s"),  # 100 kHz in s
        (1e-2, "s"),  # 100 Hz in s (or 100 kHz in ms: the rule takes s)
        (0.1, "ms"),  # 10 kHz in ms
        (10.0, "ms"),  # 100 Hz in ms
        (20.0, None),  # 50 Hz in ms or a sample counter: undecided
        (1e-7, None),
    ],
)
def test_time_unit_from_the_median_step(step: float, unit: str | None) -> None:
    t = np.arange(200) * step
    t[50:] += 3 * step  # a gap does not move the median
    assert guess_time_unit(t).value == unit


@pytest.mark.parametrize(
    ("factor", "unit"),
    [(1.0, "bar"), (1 / 0.0689475729, "psi"), (100.0, "kPa"), (1000.0, "mbar")],
)
def test_pressure_unit_from_4_bar_in_each_unit(factor: float, unit: str) -> None:
    p = np.linspace(-0.02, 4.0, 1000) * factor
    g = guess_pressure_unit(p)
    assert g.value == unit and g.reason


def test_pressure_unit_limits_and_a_spike() -> None:
    assert guess_pressure_unit([0.0, 5.8]).value == "bar"
    assert guess_pressure_unit([0.0, 6.1]).value == "psi"
    assert guess_pressure_unit([0.0, 601.0]).value == "mbar"
    assert guess_pressure_unit([0.0, 6001.0]).value is None
    p = np.r_[np.linspace(0, 3, 5000), 900.0]  # one glitch above the 99.9th percentile
    assert guess_pressure_unit(p).value == "bar"


# --------------------------------------------------------------------------- kind, modulator


def test_kind_of_the_identification_runs() -> None:
    specs = identification_runs(EXAMPLE_PARAMS, DT, repeats=1)
    assert {s.kind for s in specs} > {"pulse"}, "runs other than pulses are checked without valve"
    for spec in specs:
        run = _simulated(spec)
        g = guess_kind(run["t"], run["p"], run["valve"])
        assert g.value == spec.kind, g.reason
        # without the valve column: charge and discharge from the pressure's trend
        if spec.kind != "pulse":
            assert guess_kind(run["t"], run["p"]).value == spec.kind


@pytest.mark.parametrize("mod", MODULATORS, ids=lambda m: "-".join(map(str, m.values())))
def test_kind_and_modulator_of_modulated_runs(mod: dict[str, Any]) -> None:
    for spec in modulated_runs([mod], DT, EXPERIMENTS):
        run = _simulated(spec)
        kind = guess_kind(run["t"], run["p"], run["valve"], run["u"])
        assert kind.value == spec.kind, f"{spec.id}: {kind.reason}"
        g = guess_modulator(run["t"], run["valve"], run["u"])
        assert g.value is not None, f"{spec.id}: {g.reason}"
        assert g.value["type"] == mod["type"], f"{spec.id}: {g.reason}"
        for key, value in mod.items():
            if key != "type":
                assert g.value[key] == pytest.approx(value, rel=0.03), f"{spec.id}: {g.reason}"
        assert g.value.get("gain", 1.0) == pytest.approx(mod.get("gain", 1.0), rel=0.03)


def test_every_configured_modulator_on_short_runs() -> None:
    """The modulators of config/config.yaml's simulated dataset, each on a staircase, a sine
    and a chirp (short ones): every kind, type and setting is recognised."""
    cfg = yaml.safe_load((ROOT / "config" / "config.yaml").read_text())
    # LPWM's duty is not u (it inverts a valve the log does not name): not guessable
    mods = [m for m in cfg["simulated"]["sim"]["modulators"] if get_kind(m["type"]).guess_rank < 10]
    wrong = []
    for spec in modulated_runs(mods, DT, EXPERIMENTS):
        run = _simulated(spec)
        kind = guess_kind(run["t"], run["p"], run["valve"], run["u"]).value
        mod = guess_modulator(run["t"], run["valve"], run["u"]).value
        want = dict(spec.modulator)
        if want["type"] in ("ipfm", "iipfm"):
            want.setdefault("gain", 1.0)
            if mod is not None:
                mod.setdefault("gain", 1.0)
        kind_of = want.pop("type")
        if kind != spec.kind or mod is None or mod.pop("type") != kind_of:
            wrong.append((spec.id, kind, mod))
        elif mod != pytest.approx(want, rel=0.02):
            wrong.append((spec.id, kind, mod))
    assert not wrong and len(mods) >= 19


def test_modulator_settings_in_s_and_hz_whatever_the_sampling() -> None:
    t = np.arange(20000) * 1e-4  # 10 kHz
    xi = np.where(t < 1, 0.3, 0.7)
    from spa.model.modulators import modulate

    v = modulate("iipfm", xi, 1e-4, t_l=0.0125, gain=1.0)
    assert guess_modulator(t, v, xi).value == {"type": "iipfm", "t_l": 0.0125}


def test_undecidable_input_and_valve() -> None:
    rng = np.random.default_rng(1)
    t = np.arange(5000) * DT
    u = rng.uniform(0, 1, t.size)
    kind = guess_kind(t, np.zeros_like(t), None, u)
    assert kind.value is None and kind.reason.startswith("could not tell")
    v = (rng.uniform(size=t.size) < 0.5).astype(float)
    mod = guess_modulator(t, v, u)
    assert mod.value is None and "could not tell" in mod.reason
    assert guess_modulator(t, np.r_[np.zeros(100), np.ones(4900)], u).value is None
    flat = guess_kind(t, np.zeros_like(t))
    assert flat.value is None and "neither rises nor falls" in flat.reason


def test_input_with_two_levels_is_not_a_staircase() -> None:
    t = np.arange(4000) * DT
    g = guess_kind(t, None, None, np.where(t < 2, 0.2, 0.8))
    assert g.value is None and "neither a staircase" in g.reason


# --------------------------------------------------------------------------- the YAML draft


@pytest.mark.parametrize("value", ["1e3", "on", "no", "it's", "a: b", "12", "~", "x # y"])
def test_scalar_reads_back_as_written(value: str) -> None:
    assert yaml.load(f"k: {dy._scalar(value)}", Loader=_UniqueKeyLoader) == {"k": value}


def test_run_ids_are_safe_and_unique() -> None:
    files = ["a b.csv", "sub/A b.csv", "y.csv", "c.mat", "sub/c.parquet", "é.csv", "x/.y.csv"]
    ids = dy._run_ids(files)
    assert ids == ["a_b", "sub-A_b", "y", "c", "sub-c", "_", "y-2"]


def test_the_detected_options_reach_the_reader(monkeypatch, tmp_path: Path) -> None:
    seen: list[Any] = []

    class Reader:  # every reader is built as Reader(path, options) (spa.datasets.readers)
        def __init__(self, path: Path, options: dict[str, Any] | None = None) -> None:
            seen.append(options)

    monkeypatch.setattr(draft_read, "READERS", {"new": Reader})
    dy._open(tmp_path, "new", {"sep": ";"})
    dy._open(tmp_path, "new", {})
    assert seen == [{"sep": ";"}, None]
    assert isinstance(dy._detect_options(tmp_path / "nothing.csv"), dict)


def _digests(folder: Path) -> dict[str, str]:
    return {
        p.relative_to(folder).as_posix(): hashlib.sha256(p.read_bytes()).hexdigest()
        for p in sorted(folder.rglob("*"))
        if p.is_file()
    }


@pytest.fixture
def example(tmp_path: Path) -> Path:
    """A copy of raw/example without its dataset.yaml."""
    folder = tmp_path / "example"
    shutil.copytree(EXAMPLE, folder)
    (folder / "dataset.yaml").unlink()
    return folder


def test_init_drafts_the_example_as_its_author_described_it(example: Path, capsys) -> None:
    before = _digests(example)
    assert main(["init", str(example)]) == 0
    assert "5 run(s), 0 TODO(s)" in capsys.readouterr().out
    after = _digests(example)
    assert set(after) - set(before) == {"dataset.yaml"}  # only the draft is written
    assert {k: after[k] for k in before} == before  # data files untouched
    draft = yaml.load((example / "dataset.yaml").read_text(), Loader=_UniqueKeyLoader)
    truth = yaml.safe_load((EXAMPLE / "dataset.yaml").read_text())
    assert draft["units"] == truth["units"] and draft["columns"] == truth["columns"]
    got = {r["file"]: (r["id"], r["kind"], r.get("modulator")) for r in draft["runs"]}
    want = {r["file"]: (r["id"], r["kind"], r.get("modulator")) for r in truth["runs"]}
    assert got == want
    assert main(["validate", str(example)]) == 0
    assert "OK, 5 run(s), 0 warning(s)" in capsys.readouterr().out


def test_init_refuses_to_overwrite_without_force(example: Path, capsys) -> None:
    spec = example / "dataset.yaml"
    spec.write_text("mine\n")
    assert main(["init", str(example)]) == 1
    assert "--force" in capsys.readouterr().out and spec.read_text() == "mine\n"
    assert main(["init", str(example), "--force"]) == 0
    assert spec.read_text().startswith("# Draft written by `spa init`")


def test_init_refuses_a_folder_without_data(tmp_path: Path, capsys) -> None:
    (tmp_path / "notes.txt").write_text("x")
    assert main(["init", str(tmp_path)]) == 1
    assert "no data file" in capsys.readouterr().out
    assert main(["init", str(tmp_path / "missing")]) == 1
    assert not (tmp_path / "dataset.yaml").exists()


def test_init_marks_what_it_cannot_tell_and_validate_reports_it(example: Path, capsys) -> None:
    rng = np.random.default_rng(3)
    t = np.arange(3000.0)
    pd.DataFrame(
        {"time_ms": t, "P_act_kPa": rng.normal(50, 5, t.size), "xi_ref": rng.uniform(size=t.size)}
    ).to_csv(example / "noise.csv", index=False)
    (example / "broken.mat").write_bytes(b"not a mat file")
    (example / "readme.txt").write_text("notes")
    (example / ".hidden.csv").write_text("t,p\n0,1\n")
    assert main(["init", str(example)]) == 0
    assert "7 run(s), 3 TODO(s)" in capsys.readouterr().out
    text = (example / "dataset.yaml").read_text()
    assert "Not drafted (not a data table): readme.txt" in text and ".hidden" not in text
    assert "kind: TODO  # could not tell: cannot read it" in text
    assert "kind: TODO  # could not tell: u oscillates with uneven periods" in text
    assert "modulator: TODO  # could not tell the modulator: no valve column" in text
    problems, _ = check_dataset(example)
    todo = [str(p) for p in problems if "TODO" in str(p)]
    assert len(todo) == 3, todo
    assert any("run 'noise'" in p and "unknown kind 'TODO'" in p for p in todo)
    assert any("run 'broken'" in p for p in todo)
    assert main(["validate", str(example)]) == 1


def test_files_with_different_columns_get_per_run_columns(tmp_path: Path) -> None:
    folder = tmp_path / "mixed"
    folder.mkdir()
    t = np.arange(2000) * 1e-3
    charge = 1.0 - np.exp(-t / 0.3)
    pd.DataFrame({"time": t, "P": charge, "V": 1}).to_csv(folder / "a.csv", index=False)
    pd.DataFrame({"zeit": t, "druck": charge[::-1], "V": 0}).to_csv(folder / "b.csv", index=False)
    text = dy.draft_dataset(folder)
    doc = yaml.load(text, Loader=_UniqueKeyLoader)
    assert "columns" not in doc and doc["units"] == {"time": "s", "pressure": "bar"}
    assert [r["columns"]["t"] for r in doc["runs"]] == ["time", "zeit"]
    assert [r["kind"] for r in doc["runs"]] == ["charge", "discharge"]


def test_detected_file_options_are_written_once_or_per_run(
    example: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(draft_read, "_detect_options", lambda path: {"sep": ",", "skip_rows": 0})
    doc = yaml.load(dy.draft_dataset(example), Loader=_UniqueKeyLoader)
    assert doc["csv"] == {"sep": ",", "skip_rows": 0}
    assert all("csv" not in r for r in doc["runs"])
    monkeypatch.setattr(draft_read, "_detect_options", lambda path: {"skip_rows": len(path.stem)})
    doc = yaml.load(dy.draft_dataset(example), Loader=_UniqueKeyLoader)
    assert "csv" not in doc
    assert {r["file"]: r.get("csv") for r in doc["runs"]} == {
        "charge.csv": {"skip_rows": 6},
        "discharge.csv": {"skip_rows": 9},
        "pulse.csv": {"skip_rows": 5},
        "staircase_iipfm-20ms-G1.2.mat": None,
        "staircase_pwm-20Hz.parquet": None,
    }


def test_data_files_search_sub_folders_and_skip_the_rest(tmp_path: Path) -> None:
    for rel in ["a.csv", "dataset.yaml", "B.PARQUET", "id/x.mat", "id/deep/y.csv", "notes.md"]:
        (tmp_path / rel).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / rel).write_text("")
    for rel in [".git/z.csv", "id/.y.csv", "a/b/c/too_deep.csv"]:
        (tmp_path / rel).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / rel).write_text("")
    files, skipped = dy.data_files(tmp_path)
    assert files == ["B.PARQUET", "a.csv", "id/deep/y.csv", "id/x.mat"]
    assert skipped == ["notes.md"]


def test_recorded_date_from_the_files_own_headers(tmp_path) -> None:
    """LVM Date, TDMS wf_start_time, MAT v7.3 'Created on:'; CSV gives none."""
    from file_writers import mat73_file, write_lvm

    from spa.datasets.recorded import header_date, session_date

    t = np.arange(10) * 1e-3
    write_lvm(tmp_path / "a.lvm", [[{"X_Value": t, "p": t}]], decimal=".")
    assert header_date(tmp_path / "a.lvm") == "2025-03-03"
    with mat73_file(tmp_path / "b.mat") as f:
        f["t"] = t
    assert header_date(tmp_path / "b.mat") == "2025-03-03"
    from nptdms import ChannelObject, GroupObject, TdmsWriter

    start = np.datetime64("2024-12-30T23:59:00")
    with TdmsWriter(str(tmp_path / "c.tdms")) as writer:
        props = {"wf_start_time": start, "wf_increment": 1e-3}
        writer.write_segment([GroupObject("g"), ChannelObject("g", "p", t, properties=props)])
    assert header_date(tmp_path / "c.tdms") == "2024-12-30"
    pd.DataFrame({"t": t}).to_csv(tmp_path / "d.csv", index=False)
    assert header_date(tmp_path / "d.csv") is None
    (tmp_path / "e.lvm").write_bytes(b"LabVIEW Measurement\nDate\t2025/13/45\n")  # no such day
    assert header_date(tmp_path / "e.lvm") is None
    assert session_date(tmp_path, ["a.lvm", "c.tdms", "d.csv"]) == (
        "2024-12-30",
        "from the header of c.tdms, the earliest of 2 files with one",
    )


def test_init_fills_recorded_or_leaves_a_todo_comment(tmp_path) -> None:
    from file_writers import write_lvm

    from spa.datasets import load_spec

    csvs = tmp_path / "csvs"
    shutil.copytree(EXAMPLE, csvs, ignore=shutil.ignore_patterns("*.mat", "*.parquet", "*.yaml"))
    text = dy.draft_dataset(csvs)
    assert "# recorded: YYYY-MM-DD  TODO: the day of the session (no file header" in text
    lvm = tmp_path / "lvm"
    lvm.mkdir()
    table = pd.read_csv(EXAMPLE / "charge.csv")
    write_lvm(lvm / "charge.lvm", [[{"X_Value": table["time_ms"], "p": table["P_act_kPa"]}]], ".")
    text = dy.draft_dataset(lvm)
    assert "recorded: 2025-03-03  # from the header of charge.lvm" in text
    (lvm / "dataset.yaml").write_text(text.replace("TODO", "charge"))
    try:
        assert load_spec(lvm).recorded == "2025-03-03"
    except Exception as exc:  # other TODOs of the draft: the date itself is accepted
        assert "recorded" not in str(exc)


@pytest.mark.parametrize(
    ("value", "expected"),
    [("2025-03-04", "2025-03-04"), ("2025-03-04T14:02:00", "2025-03-04T14:02"), ("March", None)],
)
def test_recorded_is_an_iso_date_or_a_named_error(tmp_path, value, expected) -> None:
    from spa.datasets import DatasetError, load_spec

    folder = tmp_path / "example"
    shutil.copytree(EXAMPLE, folder)
    spec = folder / "dataset.yaml"
    spec.write_text(spec.read_text().replace("origin:", f"recorded: {value}\norigin:", 1))
    if expected:
        assert load_spec(folder).recorded == expected
    else:
        with pytest.raises(DatasetError, match="recorded must be an ISO 8601 date"):
            load_spec(folder)


# --------------------------------------------------------------------------- a lab's own valve

#: A valve unlike the paper's (k2 0.6 bar, c1 0.3, tau2 0.3 s, t_on 8 ms, t_off 20 ms).
LAB_VALVE = ValveParams(c1=0.3, k2=0.6, tau2=0.3, t_on=0.008, t_off=0.020)
PSI = 0.0689475729


def _bench_session(
    folder: Path,
    params: ValveParams = LAB_VALVE,
    scale: float = 1.0,
    names: tuple[str, str, str] = ("time", "u", "pressure"),
) -> dict[str, pd.DataFrame]:
    """Charge, discharge and pulse runs of ``params`` written as a logger would: one CSV per
    run with columns ``names`` (time in s, the 0/1 valve command, pressure times ``scale``);
    returns the simulated run tables (t in s, p in bar) by run id."""
    folder.mkdir(parents=True)
    runs = {}
    for spec in identification_runs(params, DT, repeats=1):
        run = simulate_run(spec, params, DT, SENSOR, np.random.default_rng(11))
        t, cmd, p = names
        log = pd.DataFrame({t: run["t"], cmd: run["valve"], p: (run["p"] * scale).round(6)})
        log.to_csv(folder / f"{spec.id}.csv", index=False)
        runs[spec.id] = run
    return runs


def _ingested(folder: Path, out: Path) -> dict[str, pd.DataFrame]:
    from spa.datasets import ingest_dataset, read_run_table

    return {p.stem: read_run_table(p)[0] for p in ingest_dataset(folder, out)}


def test_a_log_with_one_command_column_drafts_what_validate_and_ingest_accept(
    tmp_path: Path, capsys
) -> None:
    """``time,u,pressure`` with ``u`` the 0/1 valve command: the draft maps it to ``valve``,
    leaves the input fraction out (``u: null``, the cost said in a comment), and validate
    and ingest accept it: t in s, p in bar, valve 0/1, no u."""
    folder = tmp_path / "lab"
    truth = _bench_session(folder)
    assert main(["init", str(folder)]) == 0
    assert "3 run(s), 0 TODO(s)" in capsys.readouterr().out
    text = (folder / "dataset.yaml").read_text()
    draft = yaml.load(text, Loader=_UniqueKeyLoader)
    assert draft["columns"] == {"t": "time", "p": "pressure", "valve": "u", "u": None}
    notes = " ".join(x.strip().lstrip("# ") for x in text.splitlines() if x.strip()[:1] == "#")
    assert "No input fraction is recorded" in notes and "would lose the timing" in notes
    assert [(r["id"], r["kind"]) for r in draft["runs"]] == [
        ("charge", "charge"),
        ("discharge", "discharge"),
        ("pulse", "pulse"),
    ]
    assert main(["validate", str(folder)]) == 0
    assert "OK, 3 run(s), 0 warning(s)" in capsys.readouterr().out
    tables = _ingested(folder, tmp_path / "runs")
    for rid, table in tables.items():
        assert list(table.columns) == ["t", "p", "valve"]
        assert table["valve"].dtype == np.int8
        np.testing.assert_array_equal(table["valve"], truth[rid]["valve"])
        np.testing.assert_allclose(table["p"], truth[rid]["p"], atol=1e-6)
        np.testing.assert_allclose(table["t"], truth[rid]["t"], atol=1e-12)


def test_a_session_mixing_valve_only_logs_and_modulated_runs(tmp_path: Path, capsys) -> None:
    """Identification logs ``time,u,pressure`` (u the 0/1 command) beside a staircase log
    ``time,u,valve,pressure`` (u the input fraction): per-run columns, each valid."""
    folder = tmp_path / "mixed"
    _bench_session(folder)
    (spec,) = modulated_runs(
        [{"type": "pwm", "f_w": 20.0}], DT, {"staircase": EXPERIMENTS["staircase"]}
    )
    run = simulate_run(spec, LAB_VALVE, DT, SENSOR, np.random.default_rng(5))
    run[["t", "u", "valve", "p"]].set_axis(["time", "u", "valve", "pressure"], axis=1).to_csv(
        folder / "stair.csv", index=False
    )
    assert main(["init", str(folder)]) == 0
    assert "4 run(s), 0 TODO(s)" in capsys.readouterr().out
    draft = yaml.load((folder / "dataset.yaml").read_text(), Loader=_UniqueKeyLoader)
    by_id = {r["id"]: r for r in draft["runs"]}
    assert by_id["charge"]["columns"]["valve"] == "u" and by_id["charge"]["columns"]["u"] is None
    assert by_id["stair"]["kind"] == "staircase"
    assert by_id["stair"]["modulator"] == {"type": "pwm", "f_w": 20.0}
    assert main(["validate", str(folder)]) == 0
    tables = _ingested(folder, tmp_path / "runs")
    assert list(tables["stair"].columns) == ["t", "p", "valve", "u"]
    assert list(tables["pulse"].columns) == ["t", "p", "valve"]


@pytest.mark.parametrize(
    ("k2", "unit", "factor"),
    [
        (0.6, "kPa", 100.0),  # 60: 4.1 bar if psi
        (0.8, "kPa", 100.0),  # 80: 5.5 bar if psi (the case reported)
        (0.3, "kPa", 100.0),  # 30: 2.1 bar if psi; ambiguous, psi kept but named
        (0.6, "bar", 1.0),
        (4.0, "bar", 1.0),
        (2.0, "psi", 1 / PSI),
        (0.5, "mbar", 1000.0),
    ],
)
def test_pressure_unit_from_the_supply(k2: float, unit: str, factor: float) -> None:
    """The plateau of a charge run is the supply, typically 0.2-6 bar and most often near
    1 bar: a reading far above it in one unit gives way to one near it in another."""
    params = ValveParams(c1=0.3, k2=k2, tau2=0.3, t_on=0.008, t_off=0.020)
    spec = identification_runs(params, DT, repeats=1)[0]
    p = simulate_run(spec, params, DT, SENSOR, np.random.default_rng(2))["p"] * factor
    g = guess_pressure_unit(p)
    if k2 == 0.3:  # 30: 2.07 bar in psi or 0.3 bar in kPa, neither much likelier
        assert g.value == "psi" and "or 0.3" in g.reason and "in kPa" in g.reason
    else:
        assert g.value == unit, g.reason
    assert "the supply" in g.reason


def test_a_recording_in_kpa_is_not_taken_for_psi(tmp_path: Path, capsys) -> None:
    """0-75 kPa, once guessed psi (5.2 bar): init takes kPa and names psi in its comment;
    the same files declared psi are valid but warned about, naming the file, the column,
    the plateau and kPa; identification's k2 gets the same warning."""
    from spa.datasets.checks import k2_warning

    folder = tmp_path / "kpa"
    params = ValveParams(c1=0.3, k2=0.75, tau2=0.3, t_on=0.008, t_off=0.020)
    _bench_session(folder, params, scale=100.0, names=("time", "valve", "pressure"))
    assert main(["init", str(folder)]) == 0
    text = (folder / "dataset.yaml").read_text()
    line = next(x for x in text.splitlines() if x.strip().startswith("pressure:"))
    assert line.startswith("  pressure: kPa  #") and "in psi" in line, line
    assert "likely kPa read as psi" in line
    capsys.readouterr()
    assert main(["validate", str(folder)]) == 0
    assert "OK, 3 run(s), 0 warning(s)" in capsys.readouterr().out
    p_max = _ingested(folder, tmp_path / "runs")["charge"]["p"].max()
    assert p_max == pytest.approx(0.75, abs=0.02)

    (folder / "dataset.yaml").write_text(text.replace("pressure: kPa", "pressure: psi"))
    assert main(["validate", str(folder)]) == 0
    out = capsys.readouterr().out
    warning = next(x for x in out.splitlines() if x.startswith("warning:"))
    assert "charge.csv [run 'charge', column 'pressure']" in warning
    assert "plateau" in warning and "declared psi?" in warning and "logged in kPa" in warning
    assert f"({p_max * 100:.4g} psi)" in warning  # the plateau as logged
    assert "OK, 3 run(s), 1 warning(s)" in out
    metas = {"charge": {"kind": "charge", "units": {"pressure": "psi"}}}
    k2_psi = 75.0 * PSI  # what identification returns from the psi reading
    assert "logged in kPa but declared psi?" in k2_warning(k2_psi, metas)
    assert k2_warning(0.75, {"charge": {"kind": "charge", "units": {"pressure": "kPa"}}}) is None
    simulated = {"charge": {"kind": "charge", "origin": "synthetic"}}  # in bar, known
    assert k2_warning(5.9, simulated) is None and "psi" in k2_warning(5.9, {"c": {"kind": "x"}})
