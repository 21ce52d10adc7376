"""The log's clock in dataset.yaml (``sample_step``, ``valve_edges``) and the files a serial
logger writes: ``.log`` endings, headerless numeric columns, ``csv: {delimiter: ...}`` and a
serial monitor's time-stamp prefix."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pytest
import yaml

from spa.cli import main
from spa.datasets import (
    DatasetError,
    check_dataset,
    ingest_dataset,
    load_spec,
    read_run_table,
    read_runs,
    write_run_table,
)
from spa.datasets.clock import MAX_SAMPLE_STEP
from spa.datasets.draft_yaml import draft_report
from spa.datasets.options import check_csv

HEAD = {"description": "x", "origin": "bench", "rig": {}}
STEP = 0.02
ROWS = 40


def _charge(n: int = ROWS) -> np.ndarray:
    return np.round(0.8 * (1.0 - np.exp(-np.arange(n) * STEP / 0.1)), 4)


def _dataset(root: Path, spec: dict[str, Any], files: dict[str, str], name: str = "d") -> Path:
    folder = root / "raw" / name
    folder.mkdir(parents=True)
    runs = spec.pop("runs", [{"id": "r", "kind": "charge", "file": "r.csv"}])
    doc = {"name": name, **HEAD, **spec, "runs": runs}
    (folder / "dataset.yaml").write_text(yaml.safe_dump(doc, sort_keys=False))
    for rel, text in files.items():
        (folder / rel).write_text(text)
    return folder


def _pressure_only(n: int = ROWS, header: str | None = "p") -> str:
    lines = [f"{x:.4f}" for x in _charge(n)]
    return "\n".join(([header] if header else []) + lines) + "\n"


def _errors(folder: Path) -> list[str]:
    return [str(p) for p in check_dataset(folder)[0] if p.is_error]


def _ingested(folder: Path, tmp_path: Path) -> tuple[pd.DataFrame, dict[str, Any]]:
    (path,) = ingest_dataset(folder, tmp_path / "results" / "runs")
    return read_run_table(path)


# --------------------------------------------------------------------------- sample_step


def test_an_unmapped_time_absent_from_the_file_comes_from_sample_step(tmp_path: Path) -> None:
    folder = _dataset(tmp_path, {"sample_step": STEP}, {"r.csv": _pressure_only()})
    table, meta = _ingested(folder, tmp_path)
    assert table["t"].tolist() == (np.arange(ROWS) * STEP).tolist()
    assert table["p"].tolist() == _charge().tolist()
    assert meta["sample_step"] == STEP
    assert meta["source"]["columns"] == {"p": "p"}  # t was not read from the file


def test_a_runs_sample_step_overrides_the_datasets(tmp_path: Path) -> None:
    runs = [
        {"id": "a", "kind": "charge", "file": "a.csv"},
        {"id": "b", "kind": "charge", "file": "b.csv", "sample_step": 0.005},
    ]
    files = {"a.csv": _pressure_only(), "b.csv": _pressure_only()}
    spec = {"columns": {"t": None}, "sample_step": STEP, "runs": runs}
    folder = _dataset(tmp_path, spec, files)
    assert [r.sample_step for r in load_spec(folder).runs] == [STEP, 0.005]
    assert load_spec(folder).sample_step == STEP
    ingest_dataset(folder, tmp_path / "results" / "runs")
    tables, metas = read_runs(tmp_path / "results" / "runs")
    assert tables["b"]["t"].iloc[-1] == pytest.approx((ROWS - 1) * 0.005, rel=1e-12)
    assert metas["a"]["sample_step"] == STEP and metas["b"]["sample_step"] == 0.005


@pytest.mark.parametrize("value", ["TODO", 0, -0.02, MAX_SAMPLE_STEP * 1.5, True, float("nan")])
def test_a_bad_sample_step_is_refused_with_what_was_expected(tmp_path: Path, value: Any) -> None:
    folder = _dataset(tmp_path, {"sample_step": value}, {"r.csv": _pressure_only()})
    (message,) = _errors(folder)
    assert "dataset.yaml: sample_step:" in message
    assert "the logging step in s" in message and f"at most {MAX_SAMPLE_STEP:g}" in message


def test_a_run_without_time_nor_sample_step_is_told_to_add_one(tmp_path: Path) -> None:
    folder = _dataset(tmp_path, {}, {"r.csv": _pressure_only()})
    (message,) = _errors(folder)
    assert "run 'r'" in message and "missing column 't'" in message
    assert "columns: {t: null} and sample_step: <s>" in message


def test_sample_step_is_in_s_whatever_the_time_unit(tmp_path: Path) -> None:
    spec = {"units": {"time": "ms"}, "sample_step": STEP}
    folder = _dataset(tmp_path, spec, {"r.csv": _pressure_only()})
    table, _ = _ingested(folder, tmp_path)
    assert table["t"].iloc[1] == STEP
    assert check_dataset(folder)[1][0].rate_hz == pytest.approx(1 / STEP)


# --------------------------------------------------------------------------- valve_edges


def _valve_log(n: int = ROWS) -> str:
    valve = (np.arange(n) // 5) % 2
    pairs = enumerate(zip(_charge(n), valve, strict=True))
    rows = [f"{k * STEP:.2f},{p:.4f},{v}" for k, (p, v) in pairs]
    return "t,p,valve\n" + "\n".join(rows) + "\n"


def test_valve_edges_reaches_the_run_tables_metadata(tmp_path: Path) -> None:
    runs = [
        {"id": "a", "kind": "pulse", "file": "a.csv"},
        {"id": "b", "kind": "pulse", "file": "b.csv", "valve_edges": "sampled"},
        {"id": "c", "kind": "pulse", "file": "c.csv"},
    ]
    files = {f"{k}.csv": _valve_log() for k in "abc"}
    folder = _dataset(tmp_path, {"valve_edges": "on_tick", "runs": runs}, files)
    ingest_dataset(folder, tmp_path / "results" / "runs")
    _, metas = read_runs(tmp_path / "results" / "runs")
    assert {k: m["valve_edges"] for k, m in metas.items()} == {
        "a": "on_tick",
        "b": "sampled",
        "c": "on_tick",
    }
    bare = _dataset(tmp_path, {}, {"r.csv": _valve_log()}, name="bare")
    _, meta = _ingested(bare, tmp_path / "bare")
    assert meta.get("valve_edges") is None  # undeclared: the data decide


@pytest.mark.parametrize("where", ["dataset", "run"])
def test_an_unknown_valve_edges_gets_the_closest_value(tmp_path: Path, where: str) -> None:
    run = {"id": "r", "kind": "pulse", "file": "r.csv"}
    spec: dict[str, Any] = {"runs": [run]}
    if where == "run":
        run["valve_edges"] = "ontick"
    else:
        spec["valve_edges"] = "ontick"
    (message,) = _errors(_dataset(tmp_path, spec, {"r.csv": _valve_log()}))
    key = "runs[0].valve_edges" if where == "run" else "valve_edges"
    assert f"dataset.yaml: {key}" in message
    assert "'ontick' is not one of on_tick, sampled (did you mean 'on_tick'?)" in message


def test_the_run_table_writer_checks_valve_edges(tmp_path: Path) -> None:
    table = pd.DataFrame({"t": [0.0, 0.001], "p": [0.0, 0.1], "valve": [1, 1]})
    meta = {"dataset": "d", "run": "r", "kind": "charge", "origin": "synthetic"}
    write_run_table(tmp_path / "ok.parquet", table, {**meta, "valve_edges": "sampled"})
    assert read_run_table(tmp_path / "ok.parquet")[1]["valve_edges"] == "sampled"
    with pytest.raises(ValueError, match=r"meta\['valve_edges'\].*did you mean 'sampled'"):
        write_run_table(tmp_path / "bad.parquet", table, {**meta, "valve_edges": "sample"})
    with pytest.raises(ValueError, match=r"meta\['sample_step'\]"):
        write_run_table(tmp_path / "bad.parquet", table, {**meta, "sample_step": -1})


# --------------------------------------------------------------------------- csv: delimiter


def test_delimiter_is_another_name_for_sep(tmp_path: Path) -> None:
    text = "t;p\n" + "".join(f"{k * STEP:.2f};{p:.4f}\n" for k, p in enumerate(_charge()))
    folder = _dataset(tmp_path, {"csv": {"delimiter": ";"}}, {"r.csv": text})
    assert load_spec(folder).runs[0].csv["sep"] == ";"
    table, _ = _ingested(folder, tmp_path)
    assert table["p"].tolist() == _charge().tolist()


def test_delimiter_and_sep_that_differ_are_refused_naming_both() -> None:
    _, found = check_csv({"delimiter": ";", "sep": ","}, {}, "runs[1].csv")
    (key, message), *_ = found
    assert key == "runs[1].csv.delimiter" and "delimiter ';' and sep ','" in message
    assert check_csv({"delimiter": ";", "sep": ";"}, {}, "csv") == ({"sep": ";"}, [])
    (_, typo), *_ = check_csv({"delimeter": ";"}, {}, "csv")[1]
    assert "did you mean 'delimiter'?" in typo


# --------------------------------------------------------------------------- .log, headerless


@pytest.mark.parametrize("header", [None, False])
def test_a_headerless_log_is_read_with_columns_named_by_position(
    tmp_path: Path, header: bool | None
) -> None:
    rows = "".join(f"{k * 20},{p:.4f}\n" for k, p in enumerate(_charge()))
    spec: dict[str, Any] = {
        "units": {"time": "ms"},
        "columns": {"t": "col1", "p": "col2"},
        "runs": [{"id": "r", "kind": "charge", "file": "r.log"}],
    }
    if header is not None:
        spec["csv"] = {"header": header}
    folder = _dataset(tmp_path, spec, {"r.log": rows})
    table, _ = _ingested(folder, tmp_path)
    assert len(table) == ROWS  # the first line is data
    np.testing.assert_allclose(table["t"], np.arange(ROWS) * STEP, atol=1e-12)


def test_header_true_reads_a_numeric_first_line_as_names(tmp_path: Path) -> None:
    text = "1,2\n" + "".join(f"{k * STEP:.2f},{p:.4f}\n" for k, p in enumerate(_charge()))
    spec = {"csv": {"header": True}, "columns": {"t": "1", "p": "2"}}
    table, _ = _ingested(_dataset(tmp_path, spec, {"r.csv": text}), tmp_path)
    assert len(table) == ROWS


def test_init_drafts_a_headerless_log_file(tmp_path: Path, capsys) -> None:
    folder = tmp_path / "raw" / "serial"
    folder.mkdir(parents=True)
    (folder / "charge.log").write_text(_pressure_only(header=None))
    assert main(["init", str(folder)]) == 0
    text = (folder / "dataset.yaml").read_text()
    doc = yaml.safe_load(text.replace("sample_step: TODO", f"sample_step: {STEP}"))
    assert doc["columns"] == {"t": None, "p": "col1"}
    assert doc["runs"] == [{"id": "charge", "kind": "charge", "file": "charge.log"}]
    (folder / "dataset.yaml").write_text(text.replace("sample_step: TODO", f"sample_step: {STEP}"))
    assert main(["validate", str(folder)]) == 0


def test_init_drafts_valve_edges_as_a_comment_when_a_valve_is_logged(
    tmp_path: Path, capsys
) -> None:
    folder = tmp_path / "raw" / "pulses"
    folder.mkdir(parents=True)
    (folder / "pulses.csv").write_text(_valve_log(200))
    assert main(["init", str(folder)]) == 0
    text = (folder / "dataset.yaml").read_text()
    assert "# valve_edges: on_tick  # or sampled" in text and "valve_edges:" not in yaml.safe_load(
        text
    )
    assert main(["validate", str(folder)]) == 0


# --------------------------------------------------------------------------- what init says


#: A serial monitor's log with "Show timestamp" on: 12:00:00.000 -> 0.00, every 20 ms.
SERIAL = "".join(
    f"12:00:{k // 50:02d}.{k % 50 * 20:03d} -> {p:.2f}\n" for k, p in enumerate(_charge())
)


def test_init_says_per_file_what_it_could_not_read(tmp_path: Path, capsys) -> None:
    folder = tmp_path / "raw" / "mixed"
    folder.mkdir(parents=True)
    (folder / "charge.txt").write_text(_pressure_only())
    (folder / "monitor.txt").write_text(SERIAL)
    (folder / "photo.jpg").write_bytes(b"\xff\xd8")
    assert main(["init", str(folder)]) == 0
    said = capsys.readouterr().out
    (monitor,) = [x for x in said.splitlines() if "monitor.txt" in x]
    assert monitor.startswith("not read: monitor.txt: ")
    assert "a time of day and an arrow, `12:00:00.000 -> `" in monitor and "sed -E" in monitor
    (photo,) = [x for x in said.splitlines() if "photo.jpg" in x]
    assert "ending '.jpg' is not one spa reads" in photo


def test_init_never_calls_a_folder_of_unreadable_files_empty(tmp_path: Path) -> None:
    folder = tmp_path / "raw" / "monitor"
    folder.mkdir(parents=True)
    (folder / "inflate_1.txt").write_text(SERIAL)
    with pytest.raises(ValueError, match="no data file spa can read") as caught:
        draft_report(folder)
    assert "inflate_1.txt: " in str(caught.value) and "serial monitor" in str(caught.value)
    (tmp_path / "empty").mkdir()
    with pytest.raises(ValueError, match="holds no files"):
        draft_report(tmp_path / "empty")


def test_validate_names_the_serial_prefix_too(tmp_path: Path) -> None:
    spec = {"sample_step": STEP, "columns": {"t": None, "p": "p"}}
    spec["runs"] = [{"id": "r", "kind": "charge", "file": "r.txt"}]
    folder = _dataset(tmp_path, spec, {"r.txt": "p\n" + SERIAL})
    errors = _errors(folder)
    assert errors and "a serial monitor's time stamps" in errors[0]
    with pytest.raises(DatasetError):
        ingest_dataset(folder, tmp_path / "results" / "runs")


def test_init_drafts_one_step_for_unstamped_files_of_different_columns(
    tmp_path: Path, capsys
) -> None:
    folder = tmp_path / "raw" / "mixed"
    folder.mkdir(parents=True)
    (folder / "inflate.txt").write_text(_pressure_only(header="pressure_psi"))
    (folder / "deflate.log").write_text("".join(f"{p:.4f}\n" for p in _charge()[::-1]))
    assert main(["init", str(folder)]) == 0
    assert "drafted 2 run(s), 1 TODO(s)" in capsys.readouterr().out
    text = (folder / "dataset.yaml").read_text()
    doc = yaml.safe_load(text.replace("sample_step: TODO", f"sample_step: {STEP}"))
    assert doc["sample_step"] == STEP
    assert {r["id"]: r["columns"] for r in doc["runs"]} == {
        "deflate": {"t": None, "p": "col1"},
        "inflate": {"t": None, "p": "pressure_psi"},
    }


def test_a_missing_name_in_a_headerless_file_says_how_its_columns_are_named(
    tmp_path: Path,
) -> None:
    spec = {"sample_step": STEP, "columns": {"t": None, "p": "pressure"}}
    (message,) = _errors(_dataset(tmp_path, spec, {"r.csv": _pressure_only(header=None)}))
    assert "missing column 'pressure'" in message and "the file has 'col1'" in message
    assert "no header line" in message and "csv: {header: true}" in message


@pytest.mark.parametrize(
    "name, unit",
    [
        ("time_ms", "ms"),
        ("t_s", "s"),
        ("Time [ms]", "ms"),
        ("time (s)", "s"),
        ("t[s]", "s"),
        ("Zeit(ms)", "ms"),
        ("millis", "ms"),
        ("timestamp", None),  # no unit in the name: the median step decides
    ],
)
def test_init_reads_the_time_unit_from_the_time_columns_name(name: str, unit: str | None) -> None:
    from spa.datasets.draft import guess_time_unit

    steps = np.arange(50) * 2.0  # 2: ms by the median-step rule (500 Hz), 0.5 Hz in s
    guess = guess_time_unit(steps, name)
    assert guess.value == (unit or "ms")
    assert (f"named {name!r}" in guess.reason) == (unit is not None)


def test_init_takes_a_coarse_unnamed_time_column_for_s(tmp_path: Path, capsys) -> None:
    """A step of 0.02 is 50 Hz in s or 50 kHz in ms; files of 50 samples would last 1 ms in
    ms, too short for a valve's response: s."""
    folder = tmp_path / "raw" / "coarse"
    folder.mkdir(parents=True)
    rows = "".join(f"{k * STEP:.2f},{p:.4f}\n" for k, p in enumerate(_charge(50)))
    (folder / "charge.csv").write_text("t,p\n" + rows)
    assert main(["init", str(folder)]) == 0
    doc = yaml.safe_load((folder / "dataset.yaml").read_text())
    assert doc["units"]["time"] == "s"
    assert main(["validate", str(folder)]) == 0
    assert "at 50 Hz" in capsys.readouterr().out
