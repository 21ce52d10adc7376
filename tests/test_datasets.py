"""Dataset contract: validation (corpus of malformed datasets), ingest, run tables, CLI."""

from __future__ import annotations

import hashlib
import json
import shutil
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq
import pytest
import scipy.io
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import spa.datasets as ds
import spa.datasets.readers.delimited as delimited
import spa.datasets.runtable as runtable
from spa.cli import main
from spa.datasets import (
    DatasetError,
    Problem,
    check_dataset,
    ingest_dataset,
    load_spec,
    read_run_meta,
    read_run_table,
    validate_dataset,
    write_run_table,
)

CORPUS = Path(__file__).parent / "corpus"
BAD = sorted(p for p in (CORPUS / "bad").iterdir() if p.is_dir())
GOOD = CORPUS / "good" / "spa_good"
REPO = Path(__file__).resolve().parents[1]


# ---------------------------------------------------------------------------- helpers


def make_dataset(
    root: Path,
    runs: list[dict[str, Any]],
    files: dict[str, pd.DataFrame | dict[str, Any] | bytes],
    name: str = "bench1",
    **extra: Any,
) -> Path:
    """Write ``root/raw/<name>/`` with ``dataset.yaml`` and ``files`` (by extension)."""
    folder = root / "raw" / name
    folder.mkdir(parents=True)
    doc = {
        "name": name,
        "description": "test bench",
        "origin": "bench",
        "rig": {"valve": "v", "actuator": "a", "sensors": "s", "controller": "c"},
    }
    doc.update(extra)
    doc["runs"] = runs
    (folder / "dataset.yaml").write_text(yaml.safe_dump(doc, sort_keys=False))
    for rel, content in files.items():
        path = folder / rel
        path.parent.mkdir(parents=True, exist_ok=True)
        if isinstance(content, bytes):
            path.write_bytes(content)
        elif rel.endswith(".csv"):
            content.to_csv(path, index=False)
        elif rel.endswith(".parquet"):
            pq.write_table(pa.Table.from_pandas(content, preserve_index=False), path)
        elif rel.endswith(".mat"):
            scipy.io.savemat(path, content)
    return folder


def frame(n: int = 50, u: bool = False) -> pd.DataFrame:
    t = np.arange(n) * 0.002
    df = pd.DataFrame(
        {"t": t, "p": 0.5 * (1 - np.exp(-t / 0.03)), "valve": (np.arange(n) // 7 % 2).astype(int)}
    )
    if u:
        df["u"] = np.linspace(0.0, 1.0, n)
    return df


def tree_digest(folder: Path) -> dict[str, str]:
    return {
        str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest()
        for p in sorted(folder.rglob("*"))
        if p.is_file()
    }


CHARGE = {"id": "c1", "kind": "charge", "file": "c1.csv"}


# ---------------------------------------------------------------------------- corpus


@pytest.mark.parametrize("case", BAD, ids=[p.name for p in BAD])
def test_bad_corpus_reports_expected_problem(case: Path, tmp_path: Path, capsys) -> None:
    expected = [line for line in (case / "expected.txt").read_text().splitlines() if line]
    assert expected, f"{case.name}/expected.txt is empty"
    problems = validate_dataset(case)
    text = "\n".join(str(p) for p in problems)
    assert any(p.is_error for p in problems), text
    for fragment in expected:
        assert fragment in text, f"{fragment!r} not in:\n{text}"
    # Ingest refuses, lists the same problems and writes nothing.
    out = tmp_path / "out"
    with pytest.raises(DatasetError) as info:
        ingest_dataset(case, out)
    assert [str(p) for p in info.value.problems] == [str(p) for p in problems]
    assert not out.exists() or not any(out.iterdir())
    # The CLI prints them and exits 1, without a traceback.
    assert main(["validate", str(case)]) == 1
    printed = capsys.readouterr().out
    assert "Traceback" not in printed
    for fragment in expected:
        assert fragment in printed


def test_corpus_covers_the_contract() -> None:
    names = {p.name for p in BAD}
    for required in [
        "missing_yaml",
        "unparsable_yaml",
        "unknown_key_typo",
        "unknown_kind",
        "unknown_modulator_type",
        "bad_modulator_settings",
        "path_absolute",
        "path_dotdot",
        "path_symlink",
        "missing_file",
        "empty_file",
        "truncated_csv",
        "truncated_parquet",
        "unreadable_mat",
        "missing_column",
        "missing_mat_variable",
        "non_numeric",
        "nan_inf",
        "time_backwards",
        "time_duplicated",
        "valve_not_binary",
        "u_out_of_range",
        "pressure_looks_kpa",
        "many_problems",
    ]:
        assert required in names
    assert (CORPUS / "bad" / "path_symlink" / "charge1.csv").is_symlink()


def test_corpus_matches_its_generator(tmp_path: Path) -> None:
    sys.path.insert(0, str(CORPUS))
    try:
        import make_corpus
    finally:
        sys.path.remove(str(CORPUS))
    make_corpus.build(tmp_path)
    for sub in ("good", "bad"):
        fresh = sorted(p.name for p in (tmp_path / sub).iterdir())
        assert fresh == sorted(p.name for p in (CORPUS / sub).iterdir())
    for case in BAD:
        for name in ("expected.txt", "dataset.yaml"):
            fresh = tmp_path / "bad" / case.name / name
            if (case / name).exists():
                assert (case / name).read_text() == fresh.read_text()


def test_good_corpus_passes_without_warnings() -> None:
    problems, summaries = check_dataset(GOOD)
    assert problems == []
    assert [s.run for s in summaries] == load_spec(GOOD).run_ids
    assert {s.kind for s in summaries} == set(ds.KINDS)
    assert {s.modulator["type"] for s in summaries if s.modulator} == {
        "pwm",
        "ipfm",
        "iipfm",
        "dsm",
    }
    for s in summaries:
        assert s.rows == 400
        assert s.rate_hz == pytest.approx(1000.0)
        assert s.duration == pytest.approx(0.399)
        assert s.p_min == pytest.approx(0.0)
        assert 0.59 < s.p_max < 0.6  # 60 kPa asymptote, converted to bar


# ---------------------------------------------------------------------------- spec


def test_load_spec_fills_defaults(tmp_path: Path) -> None:
    folder = make_dataset(tmp_path, [dict(CHARGE, notes="first")], {"c1.csv": frame()})
    spec = load_spec(folder)
    assert spec.name == "bench1" and spec.origin == "bench"
    assert (spec.time_unit, spec.pressure_unit) == ("s", "bar")
    assert spec.columns == {"t": "t", "p": "p", "valve": "valve", "u": "u", "r": "r"}
    (run,) = spec.runs
    assert run == ds.RunEntry("c1", "charge", "c1.csv", None, "first", csv=run.csv)
    assert run.csv == {
        "sep": ",",
        "decimal": ".",
        "encoding": None,
        "skip_rows": 0,
        "comment": None,
        "units_row": False,
    }
    assert (run.time_unit, run.pressure_unit, run.columns) == ("s", "bar", spec.columns)
    assert spec.run_path("c1") == folder / "c1.csv"


def test_find_datasets_lists_folders_with_a_description(tmp_path: Path) -> None:
    make_dataset(tmp_path, [CHARGE], {"c1.csv": frame()}, name="b_bench")
    make_dataset(tmp_path, [CHARGE], {"c1.csv": frame()}, name="a_bench")
    (tmp_path / "raw" / "notes").mkdir()
    (tmp_path / "raw" / "README.md").write_text("x")
    assert ds.find_datasets(tmp_path / "raw") == ["a_bench", "b_bench"]
    assert ds.find_datasets(tmp_path / "nowhere") == []


def test_load_spec_completes_modulator_settings(tmp_path: Path) -> None:
    runs = [
        {"id": "s", "kind": "sine", "file": "s.csv", "modulator": {"type": "ipfm", "t_h": "20e-3"}}
    ]
    spec = load_spec(make_dataset(tmp_path, runs, {"s.csv": frame(u=True)}))
    assert spec.runs[0].modulator == {"type": "ipfm", "t_h": 0.02, "gain": 1.0}


def test_load_spec_raises_listing_every_problem(tmp_path: Path) -> None:
    runs = [
        {"id": "a", "kind": "stair", "file": "a.csv"},
        {"id": "b", "kind": "sine", "file": "b.csv", "modulator": {"type": "pwm"}},
    ]
    folder = make_dataset(tmp_path, runs, {"a.csv": frame(), "b.csv": frame(u=True)}, origin="lab")
    with pytest.raises(DatasetError) as info:
        load_spec(folder)
    assert isinstance(info.value, ValueError)
    text = str(info.value)
    assert "origin 'lab' is not one of bench, synthetic" in text
    assert "runs[0].kind [run 'a']: unknown kind 'stair'" in text
    assert "runs[1].modulator [run 'b']: bad modulator settings: pwm: missing setting 'f_w'" in text
    assert len(info.value.problems) == 3


def test_run_ids_differing_in_case_collide(tmp_path: Path) -> None:
    runs = [dict(CHARGE, id="Run1"), dict(CHARGE, id="run1")]
    problems = validate_dataset(make_dataset(tmp_path, runs, {"c1.csv": frame()}))
    assert "duplicate run id 'run1' ('Run1' differs only in case)" in str(problems[0])


_KEYS = st.sampled_from(
    [
        "name",
        "description",
        "origin",
        "rig",
        "units",
        "columns",
        "runs",
        "id",
        "kind",
        "file",
        "modulator",
        "notes",
        "type",
        "f_w",
        "gain",
        "time",
        "pressure",
        "t",
        "p",
        "valve",
        "u",
        "x",
    ]
)
_LEAVES = st.one_of(
    st.none(),
    st.booleans(),
    st.integers(-3, 3),
    st.floats(),
    st.text(max_size=5),
    st.sampled_from(["charge", "pwm", "kPa", "bench", "c1.csv", "../c1.csv"]),
)
_YAML = st.dictionaries(
    _KEYS,
    st.recursive(
        _LEAVES,
        lambda c: st.one_of(st.lists(c, max_size=3), st.dictionaries(_KEYS, c, max_size=4)),
        max_leaves=10,
    ),
    max_size=7,
)


@settings(
    max_examples=150, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(doc=_YAML)
def test_any_yaml_gives_problems_not_exceptions(tmp_path: Path, doc: dict[str, Any]) -> None:
    folder = tmp_path / "ds"
    folder.mkdir(exist_ok=True)
    (folder / "c1.csv").write_text("t,p\n0,0\n0.001,0.1\n")
    (folder / "dataset.yaml").write_text(yaml.safe_dump(doc))
    for problem in validate_dataset(folder):  # never an exception
        assert problem.level in ("error", "warning")
        assert problem.file in ("dataset.yaml", "c1.csv")
        assert str(problem).startswith(f"{problem.level}: {problem.file}")


def test_problem_str_names_every_location() -> None:
    p = Problem("data/a.csv", "a", "P_kPa", 12, "bad value", line=13)
    assert str(p) == "error: data/a.csv [run 'a', column 'P_kPa', row 12 (line 13)]: bad value"
    q = Problem("a.parquet", "a", "p", 3, "x", level="warning")
    assert str(q) == "warning: a.parquet [run 'a', column 'p', row 3]: x"
    k = Problem("dataset.yaml", None, None, None, "unknown key", key="runs[0].kid")
    assert str(k) == "error: dataset.yaml: runs[0].kid: unknown key"
    assert not q.is_error and k.is_error


# ---------------------------------------------------------------------------- data checks


def test_warning_for_modulated_run_without_valve(tmp_path: Path) -> None:
    runs = [
        {
            "id": "s",
            "kind": "staircase",
            "file": "s.csv",
            "modulator": {"type": "dsm", "period": 0.02},
        }
    ]
    folder = make_dataset(tmp_path, runs, {"s.csv": frame(u=True).drop(columns="valve")})
    problems = validate_dataset(folder)
    assert [p.level for p in problems] == ["warning"]
    assert "the valve command is recommended for staircase runs" in problems[0].message
    (path,) = ingest_dataset(folder, tmp_path / "out")
    assert list(read_run_table(path)[0].columns) == ["t", "p", "u"]


def test_warning_when_time_looks_like_ms(tmp_path: Path) -> None:
    df = frame().assign(t=np.arange(50) * 2.0)  # ms, declared as s
    problems = validate_dataset(make_dataset(tmp_path, [CHARGE], {"c1.csv": df}))
    assert [p.level for p in problems] == ["warning"]
    assert "is time in ms? (set units: {time: ms})" in problems[0].message


@pytest.mark.parametrize(("kind", "warned"), [("charge", True), ("pulse", False)])
def test_warning_when_pressure_is_tiny(tmp_path: Path, kind: str, warned: bool) -> None:
    df = frame()  # in bar, up to 0.481, but declared as kPa
    runs = [dict(CHARGE, kind=kind)]
    problems = validate_dataset(
        make_dataset(tmp_path, runs, {"c1.csv": df}, units={"pressure": "kPa"})
    )
    assert [p.level for p in problems] == (["warning"] if warned else [])
    if warned:
        assert "pressure never exceeds 0.00481 bar in magnitude" in problems[0].message


def test_many_bad_rows_are_counted_once(tmp_path: Path) -> None:
    df = frame(200)
    df.loc[100:, "valve"] = 5
    (problem,) = validate_dataset(make_dataset(tmp_path, [CHARGE], {"c1.csv": df}))
    assert problem.row == 101 and problem.column == "valve"
    assert "(100 rows in all: 101, 102, 103, 104, 105, ...)" in problem.message


def test_text_values_parse_through_the_slow_path(tmp_path: Path) -> None:
    text = "t,p,valve\n0, 0.1 ,0\n0.001,abc,1\n0.002,NaN,1\n0.003,0.2,x\n0.004,0.3,1\n"
    folder = make_dataset(tmp_path, [CHARGE], {"c1.csv": text.encode()})
    messages = sorted(str(p) for p in validate_dataset(folder))
    assert messages == [
        "error: c1.csv [run 'c1', column 'p', row 2 (line 3)]: non-numeric value; expected a "
        "number",
        "error: c1.csv [run 'c1', column 'p', row 3 (line 4)]: missing value (empty cell or "
        "NaN); expected a finite number",
        "error: c1.csv [run 'c1', column 'valve', row 4 (line 5)]: non-numeric value; expected "
        "a number",
    ]


def test_spaces_and_bom_are_accepted(tmp_path: Path) -> None:
    text = "\ufefft,p\n0, 0.1\n0.001 ,0.2\n"
    folder = make_dataset(tmp_path, [CHARGE], {"c1.csv": text.encode()})
    assert validate_dataset(folder) == []
    df, _ = read_run_table(ingest_dataset(folder, tmp_path / "out")[0])
    assert df["p"].tolist() == [0.1, 0.2]


def test_checks_carry_across_chunks(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(delimited, "_CSV_BLOCK", 256)
    df = frame(400)
    df.loc[299, "t"] = df.loc[298, "t"]  # duplicate of the previous row: row 300
    folder = make_dataset(tmp_path, [CHARGE], {"c1.csv": df})
    (problem,) = validate_dataset(folder)
    assert (problem.column, problem.row) == ("t", 300)
    assert "duplicated time stamp" in problem.message


def test_malformed_line_is_numbered_across_blocks(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(delimited, "_CSV_BLOCK", 200)
    lines = frame(400).to_csv(index=False).splitlines()
    lines[149] = "0.5,0.1"  # line 150 of the file: two fields instead of three
    lines[301] = lines[301].replace(",", ",x", 1)  # line 302: text in p
    folder = make_dataset(tmp_path, [CHARGE], {"c1.csv": ("\n".join(lines) + "\n").encode()})
    messages = [str(p) for p in validate_dataset(folder)]
    assert any(
        "[run 'c1', line 150]: malformed line: expected 3 comma-separated fields, got 2" in m
        for m in messages
    ), messages
    # the malformed line blurs the row -> line mapping of its own block only
    assert any("column 'p', row 300 (line 302)]: non-numeric value" in m for m in messages)


def test_blank_lines_are_skipped(tmp_path: Path) -> None:
    text = "t,p\n0,0.1\n\n0.001,0.2\n0.002,0.2\n0.002,0.3\n\n"
    folder = make_dataset(tmp_path, [CHARGE], {"c1.csv": text.encode()})
    (problem,) = validate_dataset(folder)
    assert (problem.row, problem.line) == (4, None)  # the blank line makes the line uncertain
    assert str(problem).startswith("error: c1.csv [run 'c1', column 't', row 4]: duplicated")


def test_chunking_does_not_change_the_output(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    folder = make_dataset(tmp_path, [CHARGE], {"c1.csv": frame(3000)})
    monkeypatch.setattr(runtable, "_ROW_GROUP", 1000)
    whole = ingest_dataset(folder, tmp_path / "a")[0].read_bytes()
    monkeypatch.setattr(delimited, "_CSV_BLOCK", 512)
    chunked = ingest_dataset(folder, tmp_path / "b")[0]
    assert chunked.read_bytes() == whole
    assert pq.ParquetFile(chunked).metadata.num_row_groups == 3


# ---------------------------------------------------------------------------- ingest


@pytest.mark.parametrize(
    ("unit", "value", "bar"),
    [
        ("bar", 0.8, 0.8),
        ("mbar", 1500.0, 1.5),
        ("kPa", 250.0, 2.5),
        ("kPa", 80.0, 0.8),
        ("psi", 100.0, 6.89475729),
    ],
)
def test_pressure_units_convert_to_bar(tmp_path: Path, unit: str, value: float, bar: float) -> None:
    df = pd.DataFrame({"t": [0.0, 0.001, 0.002], "p": [0.0, value, value]})
    folder = make_dataset(tmp_path, [CHARGE], {"c1.csv": df}, units={"pressure": unit})
    out, meta = read_run_table(ingest_dataset(folder, tmp_path / "out")[0])
    assert out["p"].iloc[1] == pytest.approx(bar, rel=1e-15, abs=0)
    assert meta["units"] == {"time": "s", "pressure": unit}


def test_conversion_factors_are_the_documented_ones() -> None:
    assert ds.PRESSURE_UNITS == {"bar": 1.0, "mbar": 0.001, "kPa": 0.01, "psi": 0.0689475729}
    assert ds.TIME_UNITS == {"s": 1.0, "ms": 0.001}
    assert ds._to_bar(np.array([250.0]), "kPa")[0] == 2.5  # exact: divided by 100
    assert ds._to_seconds(np.array([3.0]), "ms")[0] == 0.003


def test_ms_and_renamed_columns(tmp_path: Path) -> None:
    t_ms = np.arange(0, 100, 0.5)
    df = pd.DataFrame(
        {
            "V": np.ones(t_ms.size, dtype=int),
            "time [ms]": t_ms,
            "P (kPa)": np.full(t_ms.size, 45.0),
            "extra": 1.0,
        }
    )
    folder = make_dataset(
        tmp_path,
        [CHARGE],
        {"c1.csv": df},
        units={"time": "ms", "pressure": "kPa"},
        columns={"t": "time [ms]", "p": "P (kPa)", "valve": "V"},
    )
    out, meta = read_run_table(ingest_dataset(folder, tmp_path / "out")[0])
    assert list(out.columns) == ["t", "p", "valve"]
    assert out.dtypes.astype(str).tolist() == ["float64", "float64", "int8"]
    np.testing.assert_array_equal(out["t"], t_ms / 1000)
    np.testing.assert_allclose(out["t"], t_ms * 1e-3, rtol=1e-15, atol=0)
    assert out["t"].iloc[3] == 0.0015 and (out["p"] == 0.45).all()
    assert meta["source"]["columns"] == {"t": "time [ms]", "p": "P (kPa)", "valve": "V"}


def test_csv_parquet_and_mat_give_the_same_table(tmp_path: Path) -> None:
    df = frame(60, u=True)
    mod = {"type": "iipfm", "t_l": 0.02, "gain": 1.15}
    runs = [
        {"id": f"r_{ext}", "kind": "chirp", "file": f"d/r.{ext}", "modulator": mod}
        for ext in ("csv", "parquet", "mat")
    ]
    pq_df = df.astype({"valve": "int8", "p": "float32"})
    mat = {k: df[k].to_numpy().reshape(-1, 1) for k in df}  # column vectors
    folder = make_dataset(tmp_path, runs, {"d/r.csv": df, "d/r.parquet": pq_df, "d/r.mat": mat})
    paths = ingest_dataset(folder, tmp_path / "out")
    assert [p.name for p in paths] == ["r_csv.parquet", "r_parquet.parquet", "r_mat.parquet"]
    tables = [read_run_table(p) for p in paths]
    expected = df.astype({"valve": "int8"})
    pd.testing.assert_frame_equal(tables[0][0], expected)
    pd.testing.assert_frame_equal(tables[2][0], expected)
    pd.testing.assert_frame_equal(
        tables[1][0], expected.assign(p=df["p"].astype("float32").astype(float))
    )
    assert [m["source"]["format"] for _, m in tables] == ["csv", "parquet", "mat"]


def test_metadata_round_trip_and_sha256(tmp_path: Path) -> None:
    runs = [
        {
            "id": "st",
            "kind": "staircase",
            "file": "st.csv",
            "notes": "5 s steps",
            "modulator": {"type": "pwm", "f_w": 20},
        }
    ]
    folder = make_dataset(
        tmp_path,
        runs,
        {"st.csv": frame(u=True)},
        origin="synthetic",
        units={"time": "s", "pressure": "bar"},
    )
    (path,) = ingest_dataset(folder, tmp_path / "out")
    meta = read_run_meta(path)
    raw = pq.ParquetFile(path).metadata.metadata[b"spa"]
    assert json.loads(raw) == meta
    assert meta == {
        "format": "spa.run/1",
        "dataset": "bench1",
        "description": "test bench",
        "origin": "synthetic",
        "rig": {"valve": "v", "actuator": "a", "sensors": "s", "controller": "c"},
        "run": "st",
        "kind": "staircase",
        "modulator": {"type": "pwm", "f_w": 20.0},
        "notes": "5 s steps",
        "source": {
            "file": "st.csv",
            "format": "csv",
            "sha256": hashlib.sha256((folder / "st.csv").read_bytes()).hexdigest(),
            "columns": {"t": "t", "p": "p", "valve": "valve", "u": "u"},
        },
        "units": {"time": "s", "pressure": "bar"},
    }
    assert str(tmp_path) not in raw.decode()  # no absolute paths


def test_ingest_is_deterministic_and_leaves_raw_untouched(tmp_path: Path) -> None:
    before = tree_digest(GOOD)
    first = ingest_dataset(GOOD, tmp_path / "a")
    second = ingest_dataset(GOOD, tmp_path / "b")
    again = ingest_dataset(GOOD, tmp_path / "a")
    assert len(first) == 8
    for x, y, z in zip(first, second, again, strict=True):
        assert x.read_bytes() == y.read_bytes() == z.read_bytes()
    assert tree_digest(GOOD) == before
    assert sorted(p.name for p in (tmp_path / "a").iterdir()) == sorted(p.name for p in first)


def test_ingest_refuses_to_write_into_raw(tmp_path: Path) -> None:
    folder = make_dataset(tmp_path, [CHARGE], {"c1.csv": frame()})
    for out in (folder, folder / "out", folder.parent):
        with pytest.raises(ValueError, match="ingest never writes into raw/"):
            ingest_dataset(folder, out)
    assert sorted(p.name for p in folder.iterdir()) == ["c1.csv", "dataset.yaml"]


def test_failed_ingest_keeps_earlier_outputs(tmp_path: Path) -> None:
    folder = make_dataset(tmp_path, [CHARGE], {"c1.csv": frame()})
    (good,) = ingest_dataset(folder, tmp_path / "out")
    content = good.read_bytes()
    frame().assign(valve=3).to_csv(folder / "c1.csv", index=False)
    with pytest.raises(DatasetError, match="valve = 3"):
        ingest_dataset(folder, tmp_path / "out")
    assert good.read_bytes() == content
    assert [p.name for p in (tmp_path / "out").iterdir()] == ["c1.parquet"]


# ---------------------------------------------------------------------------- run tables

META = {
    "dataset": "sim",
    "run": "stair_pwm-20Hz",
    "kind": "staircase",
    "origin": "synthetic",
    "modulator": {"type": "pwm", "f_w": 20},
}


def test_write_run_table_enforces_canonical_form(tmp_path: Path) -> None:
    df = frame(30, u=True)
    shuffled = df[["u", "valve", "p", "t"]].astype({"valve": float, "t": "float32"})
    write_run_table(tmp_path / "r.parquet", shuffled, {**META, "seed": 7})
    out, meta = read_run_table(tmp_path / "r.parquet")
    assert list(out.columns) == ["t", "p", "valve", "u"]
    assert out.dtypes.astype(str).tolist() == ["float64", "float64", "int8", "float64"]
    assert meta["modulator"] == {"type": "pwm", "f_w": 20.0}
    assert meta["seed"] == 7 and meta["source"] is None and meta["format"] == "spa.run/1"
    assert meta["units"] == {"time": "s", "pressure": "bar"}
    schema = pq.read_schema(tmp_path / "r.parquet")
    assert [f.nullable for f in schema] == [False] * 4


def test_write_run_table_is_deterministic(tmp_path: Path) -> None:
    df = frame(30, u=True)
    write_run_table(tmp_path / "a.parquet", df, META)
    write_run_table(tmp_path / "b.parquet", df.copy(), dict(reversed(list(META.items()))))
    assert (tmp_path / "a.parquet").read_bytes() == (tmp_path / "b.parquet").read_bytes()
    assert not list(tmp_path.glob(".*"))  # no temporary file left


def test_bench_and_written_tables_are_identical(tmp_path: Path) -> None:
    runs = [{"id": "c1", "kind": "charge", "file": "c1.csv"}]
    folder = make_dataset(tmp_path, runs, {"c1.csv": frame()})
    (path,) = ingest_dataset(folder, tmp_path / "out")
    table, meta = read_run_table(path)
    write_run_table(tmp_path / "copy.parquet", table, meta)
    assert (tmp_path / "copy.parquet").read_bytes() == path.read_bytes()


@pytest.mark.parametrize(
    ("change", "message"),
    [
        (lambda df, m: (df.assign(extra=1.0), m), r"unknown column\(s\) \['extra'\]"),
        (lambda df, m: (df.drop(columns="p"), m), "needs column 'p'"),
        (lambda df, m: (df.assign(p=np.nan), m), "column 'p', row 1: missing value"),
        (lambda df, m: (df.assign(t=df["t"][::-1].to_numpy()), m), "time goes backwards"),
        (lambda df, m: (df.assign(valve=2), m), "valve = 2"),
        (lambda df, m: (df.assign(u=-0.5), m), r"u = -0.5 is outside \[0, 1\]"),
        (lambda df, m: (df.assign(p="x"), m), "column 'p' must hold numbers"),
        (lambda df, m: (df.drop(columns="u"), m), r"needs column\(s\) \['u'\]"),
        (lambda df, m: (df, {**m, "modulator": None}), "modulator'] is required"),
        (lambda df, m: (df, {**m, "kind": "ramp"}), "'ramp' is not one of"),
        (lambda df, m: (df, {**m, "run": "a/b"}), "not a filename-safe run id"),
        (lambda df, m: (df, {k: v for k, v in m.items() if k != "origin"}), "'origin'"),
        (lambda df, m: (df, {**m, "units": {"time": "h"}}), r"meta\['units'\]"),
        (lambda df, m: (df, {**m, "source": {"file": "x"}}), r"meta\['source'\]"),
        (lambda df, m: (df, {**m, "gain": float("nan")}), "JSON-serialisable"),
    ],
)
def test_write_run_table_rejects(tmp_path: Path, change, message: str) -> None:
    df, meta = change(frame(10, u=True), dict(META))
    with pytest.raises(ValueError, match=message):
        write_run_table(tmp_path / "r.parquet", df, meta)
    assert not list(tmp_path.iterdir())


def test_read_run_table_rejects_foreign_parquet(tmp_path: Path) -> None:
    pq.write_table(pa.table({"t": [0.0]}), tmp_path / "x.parquet")
    with pytest.raises(ValueError, match="not a spa run table"):
        read_run_table(tmp_path / "x.parquet")


# ---------------------------------------------------------------------------- CLI


def test_cli_validate_good_prints_one_line_per_run(capsys) -> None:
    assert main(["validate", str(GOOD)]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert len(lines) == 9 and lines[-1] == f"{GOOD}: OK, 8 run(s), 0 warning(s)"
    assert lines[5] == (
        "chirp_iipfm: chirp, iipfm t_l=0.02 s gain=1.15, 0.399 s at 1000 Hz, "
        "p 0 to 0.5959 bar (chirp_iipfm.csv, 400 rows, columns t p valve u)"
    )


def test_cli_exit_codes_in_a_subprocess() -> None:
    def run(*args: str) -> subprocess.CompletedProcess[str]:
        return subprocess.run(
            [sys.executable, "-m", "spa", *args],
            capture_output=True,
            text=True,
            cwd=REPO,
            check=False,
        )

    good = str(GOOD.relative_to(REPO))
    ok = run("validate", good)
    assert ok.returncode == 0, ok.stdout + ok.stderr
    assert "stair_pwm: staircase, pwm f_w=20 Hz, 0.399 s at 1000 Hz" in ok.stdout
    bad = run("validate", good, str(CORPUS / "bad" / "many_problems"))
    assert bad.returncode == 1
    assert f"{good}: OK, 8 run(s)" in bad.stdout  # every folder is reported
    assert "many_problems: INVALID, 6 error(s)" in bad.stdout
    assert "Traceback" not in bad.stdout + bad.stderr


def test_cli_usage_errors_and_ingest(tmp_path: Path, capsys) -> None:
    assert main([]) == 2
    assert main(["validate"]) == 2
    assert main(["frobnicate"]) == 2
    assert main(["ingest", str(GOOD), str(tmp_path / "out")]) == 0
    printed = capsys.readouterr().out.splitlines()
    assert printed == [str(tmp_path / "out" / f"{r}.parquet") for r in load_spec(GOOD).run_ids]
    assert main(["ingest", str(GOOD), str(GOOD / "out")]) == 1
    assert "ingest never writes into raw/" in capsys.readouterr().out


def test_cli_ingest_reports_problems(tmp_path: Path, capsys) -> None:
    assert main(["ingest", str(CORPUS / "bad" / "non_numeric"), str(tmp_path / "o")]) == 1
    out = capsys.readouterr().out
    assert "non-numeric value" in out and "not ingested, 1 error(s)" in out


def test_a_huge_dataset_yaml_is_refused_before_it_is_parsed(tmp_path: Path) -> None:
    folder = tmp_path / "big"
    folder.mkdir()
    (folder / "dataset.yaml").write_text("name: big\ndescription: " + "x" * (2 << 20) + "\n")
    problems = validate_dataset(folder)
    assert any("a description is at most 1048576 bytes" in str(p) for p in problems), problems


def _one_csv_run(tmp_path: Path, content: bytes) -> list[str]:
    folder = tmp_path / "d"
    folder.mkdir(parents=True)
    (folder / "dataset.yaml").write_text(
        "name: d\ndescription: x\norigin: bench\nrig: {}\n"
        "runs:\n- {id: c, kind: charge, file: run.csv}\n"
    )
    (folder / "run.csv").write_bytes(content)
    return [str(p) for p in validate_dataset(folder)]


ROWS = "".join(f"{k * 0.001:.3f},{min(k, 500) * 0.001:.4f},1\n" for k in range(1000))


def test_hostile_csv_gets_a_message_naming_the_cause(tmp_path: Path, monkeypatch) -> None:
    cr = _one_csv_run(tmp_path / "cr", ("t,p,valve\n" + ROWS).replace("\n", "\r").encode())
    assert any("lines end in CR alone" in m for m in cr), cr
    utf16 = _one_csv_run(tmp_path / "u16", ("t,p,valve\n" + ROWS).encode("utf-16-le"))
    assert any("UTF-16 text without a byte-order mark" in m for m in utf16), utf16
    bom = _one_csv_run(tmp_path / "bom", ("t,p,valve\n" + ROWS).encode("utf-16"))
    assert bom == []  # UTF-16 with its byte-order mark is read
    monkeypatch.setattr(delimited, "_MAX_LINE", 4096)
    monkeypatch.setattr(delimited, "_CSV_BLOCK", 1024)
    long = _one_csv_run(tmp_path / "long", b"t,p,valve\n0,0,1\n" + b"1" * 10_000 + b"\n")
    assert any("line 3 is longer than 4096 bytes" in m for m in long), long
    ulp = repr(float(np.nextafter(1.0, 2.0)))
    rows = "".join(f"{k}e-3,0.1,1,{ulp}\n" for k in range(9))
    over = _one_csv_run(tmp_path / "ulp", ("t,p,valve,u\n" + rows).encode())
    assert any(f"u = {ulp} is outside [0, 1]" in m for m in over), over


def test_time_in_seconds_declared_as_ms_is_flagged(tmp_path: Path) -> None:
    folder = tmp_path / "d"
    folder.mkdir()
    (folder / "dataset.yaml").write_text(
        "name: d\ndescription: x\norigin: bench\nrig: {}\nunits: {time: ms}\n"
        "runs:\n- {id: c, kind: charge, file: run.csv}\n"
    )
    (folder / "run.csv").write_text("t,p,valve\n" + ROWS)  # 1 kHz in s, said to be ms
    problems = [str(p) for p in validate_dataset(folder)]
    assert any("implausibly high; is time really in ms?" in m for m in problems), problems


_CSV_LINES = st.lists(
    st.one_of(
        st.just("t,p,valve"),
        st.builds(
            lambda t, p, v: f"{t},{p},{v}",
            st.one_of(st.floats(allow_nan=True), st.integers(-(2**70), 2**70), st.text(max_size=4)),
            st.one_of(st.floats(-50, 2500), st.text(max_size=3)),
            st.sampled_from(["0", "1", "2", "", "x", "1.0"]),
        ),
        st.text(max_size=30),
    ),
    max_size=25,
)


@settings(
    max_examples=120, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(
    lines=_CSV_LINES,
    ending=st.sampled_from(["\n", "\r\n", "\r"]),
    encoding=st.sampled_from(["utf-8", "utf-8-sig", "utf-16", "latin-1"]),
)
def test_any_csv_gives_a_valid_run_or_a_clean_dataset_error(
    tmp_path: Path, lines: list[str], ending: str, encoding: str
) -> None:
    """Fuzz: whatever a run's file holds, validation returns problems and ingest either writes
    the run tables or raises DatasetError; nothing is ever written into the dataset folder or
    outside the output folder."""
    folder = tmp_path / "raw" / "ds"
    out = tmp_path / "results" / "runs"
    shutil.rmtree(tmp_path / "raw", ignore_errors=True)
    shutil.rmtree(tmp_path / "results", ignore_errors=True)
    folder.mkdir(parents=True)
    (folder / "dataset.yaml").write_text(
        "name: ds\ndescription: x\norigin: bench\nrig: {}\n"
        "runs:\n- {id: c, kind: charge, file: c1.csv}\n"
    )
    (folder / "c1.csv").write_bytes(ending.join(["t,p,valve", *lines]).encode(encoding, "replace"))
    before = {p: p.read_bytes() for p in folder.iterdir()}
    problems = validate_dataset(folder)
    assert all(p.level in ("error", "warning") for p in problems)
    try:
        paths = ingest_dataset(folder, out)
    except DatasetError as exc:
        assert any(p.is_error for p in exc.problems)
    else:
        assert not any(p.is_error for p in problems)
        assert [p.name for p in paths] == ["c.parquet"]
    assert {p: p.read_bytes() for p in folder.iterdir()} == before
    written = {p.relative_to(tmp_path) for p in tmp_path.rglob("*") if p.is_file()}
    assert all(p.parts[0] in ("raw", "results") for p in written)
    assert {p for p in written if p.parts[0] == "raw"} == {
        Path("raw/ds/dataset.yaml"),
        Path("raw/ds/c1.csv"),
    }


def test_ns_time_stamps_beyond_2_53_are_named(tmp_path: Path) -> None:
    rows = "".join(f"{1_700_000_000_000_000_000 + k * 1_000_000},0.1,1\n" for k in range(20))
    problems = _one_csv_run(tmp_path, ("t,p,valve\n" + rows).encode())
    assert any("is beyond 2^53" in m and "[run 'c', column 't', row 1" in m for m in problems)


def test_pressure_logged_in_bar_but_declared_kpa_is_a_warning_naming_the_mistake(
    tmp_path: Path,
) -> None:
    """A charge run topping at 0.0106 "bar" (bar values declared kPa) is valid data but no
    plausible supply: a warning says which unit mistake would explain it; the identified k2
    gets the same warning (spa identify, the identify stage's status)."""
    import pandas as pd

    from spa.datasets.checks import k2_warning

    src = REPO / "raw" / "example"
    spec = yaml.safe_load((src / "dataset.yaml").read_text())
    spec["runs"] = [r for r in spec["runs"] if r["kind"] == "charge"]
    spec["name"] = "barkpa"
    folder = tmp_path / "barkpa"
    folder.mkdir()
    for r in spec["runs"]:
        df = pd.read_csv(src / r["file"])
        df["P_act_kPa"] = (df["P_act_kPa"] / 100).round(6)
        df.to_csv(folder / r["file"], index=False)
    (folder / "dataset.yaml").write_text(yaml.safe_dump(spec, sort_keys=False))
    problems = validate_dataset(folder)
    assert [p.level for p in problems] == ["warning"], problems
    assert "= 0.0106 bar is outside the plausible supply range 0.05-20 bar: pressure logged in " \
           "bar but declared kPa?" in str(problems[0])  # fmt: skip
    metas = {"charge": {"kind": "charge", "units": {"pressure": "kPa"}}}
    assert k2_warning(0.8, metas) is None
    assert k2_warning(0.8, metas, (1.0, 5.0)).startswith("k2 = 0.8 bar is outside")
    assert k2_warning(83.7, {"c": {"kind": "charge", "units": {"pressure": "bar"}}}).endswith(
        "pressure logged in kPa but declared bar?"
    )
