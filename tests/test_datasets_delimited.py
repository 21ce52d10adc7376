"""Delimited text options (``csv:``), per-run columns and units, and the sniffer that names
the options a file needs."""

from __future__ import annotations

import codecs
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml

import spa.datasets.readers.delimited as delimited
from spa.datasets import check_dataset, ingest_dataset, load_spec, read_run_meta, read_run_table
from spa.datasets.options import check_csv
from spa.datasets.readers import READERS
from spa.datasets.readers.sniff import sniff_delimited

CORPUS = Path(__file__).parent / "corpus"
GOOD = sorted(p for p in (CORPUS / "good").iterdir() if p.is_dir())


#: The options of the European corpus file (good/european_csv/pulse_eu.csv), all six resolved.
EU_OPTIONS = {
    "sep": ";",
    "decimal": ",",
    "encoding": "cp1252",
    "skip_rows": 3,
    "comment": None,
    "units_row": True,
}


def _dataset(root: Path, run: dict, content: bytes, name: str = "d", **extra) -> Path:
    folder = root / name
    folder.mkdir(parents=True)
    doc = {"name": name, "description": "x", "origin": "bench", "rig": {}, **extra, "runs": [run]}
    (folder / "dataset.yaml").write_text(yaml.safe_dump(doc, sort_keys=False))
    (folder / run["file"]).write_bytes(content)
    return folder


def _rows(n: int = 30) -> list[tuple[float, float, int]]:
    return [(k * 0.001, round(0.5 * (1 - np.exp(-k / 10)), 6), k // 5 % 2) for k in range(n)]


@pytest.mark.parametrize("folder", GOOD, ids=[p.name for p in GOOD])
def test_every_good_dataset_passes_without_warnings(folder: Path, tmp_path: Path) -> None:
    problems, summaries = check_dataset(folder)
    assert problems == []
    assert [s.run for s in summaries] == load_spec(folder).run_ids
    assert len(ingest_dataset(folder, tmp_path / "out")) == len(summaries)


def test_european_csv_holds_exactly_the_values_of_its_plain_twin(tmp_path: Path) -> None:
    folder = CORPUS / "good" / "european_csv"
    eu, plain = ingest_dataset(folder, tmp_path / "out")
    df, _ = read_run_table(eu)
    twin, _ = read_run_table(plain)
    pd.testing.assert_frame_equal(df, twin, check_exact=True)
    # the values the file holds, read by hand: t in s, p in bar, decimal commas
    lines = (folder / "pulse_eu.csv").read_bytes().decode("cp1252").splitlines()
    assert lines[3] == "Zeit;Druck;Ventil;Öltemperatur" and lines[4] == "s;bar;-;°C"
    cells = [line.replace(",", ".").split(";") for line in lines[5:]]
    assert df["t"].tolist() == [float(c[0]) for c in cells]
    assert df["p"].tolist() == [float(c[1]) for c in cells]
    assert df["valve"].tolist() == [int(c[2]) for c in cells]
    assert list(df.columns) == ["t", "p", "valve"] and len(df) == 400
    meta = read_run_meta(eu)
    assert meta["source"]["csv"] == EU_OPTIONS


def test_per_run_columns_and_units_give_the_same_table(tmp_path: Path) -> None:
    folder = CORPUS / "good" / "per_run_units"
    spec = load_spec(folder)
    ms, s = spec.runs
    assert (ms.time_unit, ms.pressure_unit, s.time_unit, s.pressure_unit) == (
        "ms",
        "kPa",
        "s",
        "bar",
    )
    assert ms.columns == {"t": "t_ms", "p": "p_kPa", "valve": "valve", "u": "u", "r": "r"}
    assert s.columns == {"t": "time", "p": "pressure", "valve": "valve", "u": "duty", "r": "r"}
    paths = ingest_dataset(folder, tmp_path / "out")
    assert "csv" not in read_run_meta(paths[0])["source"]  # the defaults are not recorded
    assert read_run_meta(paths[1])["units"] == {"time": "s", "pressure": "bar"}
    a, b = (read_run_table(p)[0] for p in paths)
    np.testing.assert_allclose(a["t"], b["t"], rtol=0, atol=1e-15)
    np.testing.assert_allclose(a["p"], b["p"], rtol=1e-15, atol=1e-15)
    assert a["valve"].equals(b["valve"]) and a["u"].equals(b["u"])


def test_tsv_comments_are_dropped_and_lines_stay_numbered(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(delimited, "_CSV_BLOCK", 128)
    body = [f"{t}\t{p}\t{v}" for t, p, v in _rows(60)]
    body[40] = body[40].replace("\t", "\tx", 1)  # row 41: text in p
    body.insert(20, "# note")
    text = "# a\n# b\nt\tp\tvalve\n" + "\n".join(body) + "\n"
    folder = _dataset(
        tmp_path,
        {"id": "c", "kind": "charge", "file": "c.tsv"},
        text.encode(),
        csv={"comment": "#"},
    )
    (problem,) = check_dataset(folder)[0]
    # 2 comments + header above, the note between rows 20 and 21: row 41 is on line 45
    assert (problem.column, problem.row, problem.line) == ("p", 41, 45), str(problem)


def test_whitespace_separated_text(tmp_path: Path) -> None:
    rows = "".join(f"  {t:>8}\t {p:<9}   {v}  \n" for t, p, v in _rows())
    folder = _dataset(
        tmp_path,
        {"id": "c", "kind": "charge", "file": "c.txt"},
        ("  t   p\tvalve \n" + rows).encode(),
        csv={"sep": "whitespace"},
    )
    assert check_dataset(folder)[0] == []
    df, _ = read_run_table(ingest_dataset(folder, tmp_path / "out")[0])
    assert df["p"].tolist() == [p for _, p, _ in _rows()]


@pytest.mark.parametrize("encoding", ["utf-16", "utf-16-le", "utf-32", "cp1252", "latin-1"])
def test_encodings_are_read(tmp_path: Path, encoding: str) -> None:
    text = "t;p;valve;Bemerkung\n" + "".join(f"{t};{p};{v};Größe\n" for t, p, v in _rows()).replace(
        ".", ","
    )
    folder = _dataset(
        tmp_path,
        {"id": "c", "kind": "charge", "file": "c.csv"},
        text.encode(encoding),
        csv={"sep": ";", "decimal": ",", "encoding": encoding},
    )
    assert check_dataset(folder)[0] == []
    df, _ = read_run_table(ingest_dataset(folder, tmp_path / "out")[0])
    assert df["t"].tolist() == [t for t, _, _ in _rows()]


def test_run_options_override_the_dataset_key_by_key(tmp_path: Path) -> None:
    run = {"id": "c", "kind": "charge", "file": "c.csv", "csv": {"skip_rows": 1}}
    text = "meta\nt;p;valve\n" + "".join(f"{t};{p};{v}\n" for t, p, v in _rows())
    folder = _dataset(
        tmp_path,
        run,
        text.replace(".", ",").encode(),
        csv={"sep": ";", "decimal": ",", "skip_rows": 5},
    )
    assert load_spec(folder).runs[0].csv["skip_rows"] == 1
    assert load_spec(folder).runs[0].csv["sep"] == ";"
    assert check_dataset(folder)[0] == []


def test_a_tsv_defaults_to_tabs_and_a_csv_to_commas() -> None:
    for suffix, sep in ((".tsv", "\t"), (".csv", ","), (".txt", ","), (".dat", ",")):
        source = READERS["csv"]
        assert source.__init__.__code__.co_varnames[:3] == ("self", "path", "options")
        from spa.datasets.options import csv_options

        assert csv_options({}, suffix)["sep"] == sep


@pytest.mark.parametrize(
    ("value", "key", "fragment"),
    [
        ({"sep": "ab"}, "csv.sep", "is not one character"),
        ({"decimal": ";"}, "csv.decimal", "is not '.' or ','"),
        ({"encoding": "nope"}, "csv.encoding", "unknown encoding 'nope'"),
        ({"skip_rows": True}, "csv.skip_rows", "is not an integer >= 0"),
        ({"comment": 3}, "csv.comment", "is not a non-empty prefix"),
        ({"units_row": 1}, "csv.units_row", "is not true or false"),
        ({"decmal": ","}, "csv.decmal", "unknown key 'decmal' (did you mean 'decimal'?)"),
        ({"sep": ","}, "csv.decimal", "needs a sep other than ','"),
        ("tab", "csv", "csv must be a mapping"),
    ],
)
def test_bad_csv_options_are_named(value, key: str, fragment: str) -> None:
    base = {"decimal": ","} if value == {"sep": ","} else {}
    _, found = check_csv(value, base, "csv")
    assert [k for k, _ in found] == [key] and fragment in found[0][1], found


def test_check_csv_accepts_every_allowed_value() -> None:
    options = {
        "sep": "whitespace",
        "decimal": ",",
        "encoding": "cp1252",
        "skip_rows": 2,
        "comment": "//",
        "units_row": True,
    }
    assert check_csv(options, {"sep": ";"}, "runs[0].csv") == (options, [])
    assert check_csv({"sep": "\t"}, {}, "csv") == ({"sep": "\t"}, [])


# ---------------------------------------------------------------------------- sniffing


@pytest.mark.parametrize(
    ("text", "encoding", "expected"),
    [
        (
            "t,p,valve\n0.0,0.1,1\n0.001,0.2,0\n",
            "utf-8",
            {
                "sep": ",",
                "decimal": ".",
                "encoding": "utf-8",
                "skip_rows": 0,
                "comment": None,
                "units_row": False,
            },
        ),
        (
            "Prüfung\nDatum: heute\nZeit;Druck\ns;bar\n0,0;1,5\n0,1;1,25\n0,2;1,0\n",
            "cp1252",
            {
                "sep": ";",
                "decimal": ",",
                "encoding": "cp1252",
                "skip_rows": 2,
                "comment": None,
                "units_row": True,
            },
        ),
        (
            "# logger\n# x\nt\tp\n0\t1.5\n1\t1.5\n2\t1.5\n",
            "utf-8",
            {
                "sep": "\t",
                "decimal": ".",
                "encoding": "utf-8",
                "skip_rows": 0,
                "comment": "#",
                "units_row": False,
            },
        ),
        (
            "   t     p\n  0.0   1.5\n  0.1   2.5\n  0.2   3.5\n",
            "utf-16",
            {
                "sep": "whitespace",
                "decimal": ".",
                "encoding": "utf-16",
                "skip_rows": 0,
                "comment": None,
                "units_row": False,
            },
        ),
        (
            "t,p\n0,1\n1,2\n",
            "utf-16-le",
            {
                "sep": ",",
                "decimal": ".",
                "encoding": "utf-16-le",
                "skip_rows": 0,
                "comment": None,
                "units_row": False,
            },
        ),
    ],
)
def test_sniff_delimited(tmp_path: Path, text: str, encoding: str, expected: dict) -> None:
    path = tmp_path / "f.csv"
    path.write_bytes(text.encode(encoding))
    assert sniff_delimited(path) == expected


def test_sniffed_options_read_the_file(tmp_path: Path) -> None:
    """What the sniffer finds in the European corpus file reads it."""
    path = CORPUS / "good" / "european_csv" / "pulse_eu.csv"
    found = sniff_delimited(path)
    assert found == EU_OPTIONS
    source = READERS["csv"](path, found)
    assert source.columns == ["Zeit", "Druck", "Ventil", "Öltemperatur"]
    ((offset, values, _),) = source.chunks(["Zeit", "Druck"])
    assert offset == 0 and values["Zeit"][:3].tolist() == [0.0, 0.001, 0.002]


def test_a_utf8_bom_is_skipped_whatever_the_options(tmp_path: Path) -> None:
    text = codecs.BOM_UTF8 + b"t;p\n0;1\n1;2\n"
    path = tmp_path / "f.csv"
    path.write_bytes(text)
    for encoding in (None, "utf-8", "utf-8-sig"):
        source = READERS["csv"](path, {"sep": ";", "encoding": encoding})
        assert source.columns == ["t", "p"]


def test_utf16_without_bom_names_the_encoding_that_reads_it(tmp_path: Path) -> None:
    text = "t,p,valve\n" + "".join(f"{t},{p},{v}\n" for t, p, v in _rows())
    run = {"id": "c", "kind": "charge", "file": "c.csv"}
    folder = _dataset(tmp_path / "a", run, text.encode("utf-16-le"))
    (problem,) = check_dataset(folder)[0]
    assert "UTF-16 text without a byte-order mark" in problem.message
    assert "add `csv: {encoding: utf-16-le}` to the run or the dataset" in problem.message
    fixed = _dataset(tmp_path / "b", run, text.encode("utf-16-le"), csv={"encoding": "utf-16-le"})
    assert check_dataset(fixed)[0] == []


def test_a_hint_appears_only_where_the_options_disagree_with_the_file(tmp_path: Path) -> None:
    text = "t;p;valve\n" + "".join(f"{t};{p};{v}\n" for t, p, v in _rows())
    run = {"id": "c", "kind": "charge", "file": "c.csv"}
    wrong = _dataset(tmp_path / "a", run, text.replace("0.1", "0.x").encode(), csv={"sep": ";"})
    messages = [p.message for p in check_dataset(wrong)[0]]
    assert messages and not any("judging by its content" in m for m in messages), messages
