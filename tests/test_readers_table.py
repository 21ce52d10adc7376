"""The readers' table: every format has a reader that is a Source; a new format is one class
and its lines in the tables, and then validates and ingests like the others."""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import yaml

from spa.datasets import check_dataset, ingest_dataset, read_run_table
from spa.datasets.contract import _FORMATS
from spa.datasets.readers import READERS, Source
from spa.datasets.readers.base import _ReadError


def test_every_format_has_a_reader_that_is_a_source() -> None:
    assert set(_FORMATS.values()) == set(READERS)
    for fmt, reader in READERS.items():
        assert Source in reader.__mro__, f"{fmt}: a reader subclasses Source"
        own = [vars(c) for c in reader.__mro__[: reader.__mro__.index(Source)]]
        for hook in ("__init__", "chunks"):  # a reader opens and reads its file itself
            assert any(hook in v for v in own), f"{fmt}: no {hook} of its own"


class ToyReader(Source):
    """A toy format: a line of names, then lines of numbers separated by '|'."""

    what = "toy field"

    def __init__(self, path: Path, options: Mapping[str, Any] | None = None) -> None:
        lines = path.read_text(encoding="utf-8").splitlines()
        if not lines:
            raise _ReadError("empty toy file")
        self.columns = lines[0].split("|")
        self.rows = [[float(v) for v in line.split("|")] for line in lines[1:]]

    def chunks(self, names: list[str], as_text: bool = False) -> Iterator[Any]:
        table = np.array(self.rows, dtype=np.float64).reshape(-1, len(self.columns))
        yield 0, {n: table[:, self.columns.index(n)] for n in names}, {}


def _toy_dataset(root: Path) -> Path:
    folder = root / "toy"
    folder.mkdir()
    t = np.arange(200) * 0.01
    p = 1.0 - np.exp(-t / 0.5)
    body = "\n".join(f"{a:.4f}|{b:.6f}|1" for a, b in zip(t, p, strict=True))
    (folder / "charge.toy").write_text(f"time|pressure|valve\n{body}\n", encoding="utf-8")
    spec = {
        "name": "toy",
        "description": "a charge recorded in a toy format",
        "origin": "bench",
        "rig": {"valve": "toy"},
        "units": {"time": "s", "pressure": "bar"},
        "columns": {"t": "time", "p": "pressure"},
        "runs": [{"id": "c1", "kind": "charge", "file": "charge.toy"}],
    }
    (folder / "dataset.yaml").write_text(yaml.safe_dump(spec, sort_keys=False), encoding="utf-8")
    return folder


def test_a_new_format_is_one_class_and_one_line_per_table(tmp_path, monkeypatch) -> None:
    monkeypatch.setitem(READERS, "toy", ToyReader)  # the reader
    monkeypatch.setitem(_FORMATS, ".toy", "toy")  # its file ending
    folder = _toy_dataset(tmp_path)
    problems, _ = check_dataset(folder)
    assert not [p for p in problems if p.is_error], problems
    ingest_dataset(folder, tmp_path / "runs")
    table, meta = read_run_table(tmp_path / "runs" / "c1.parquet")
    assert list(table.columns[:3]) == ["t", "p", "valve"] and len(table) == 200
    assert table["p"].iloc[-1] == pd.Series([1.0 - np.exp(-1.99 / 0.5)]).round(6).iloc[0]
    assert meta["kind"] == "charge"


def test_a_new_formats_missing_column_is_named_with_its_own_word(tmp_path, monkeypatch) -> None:
    monkeypatch.setitem(READERS, "toy", ToyReader)
    monkeypatch.setitem(_FORMATS, ".toy", "toy")
    folder = _toy_dataset(tmp_path)
    spec = yaml.safe_load((folder / "dataset.yaml").read_text())
    spec["columns"]["p"] = "presure"
    (folder / "dataset.yaml").write_text(yaml.safe_dump(spec, sort_keys=False))
    errors = [str(p) for p in check_dataset(folder)[0] if p.is_error]
    # the default describe() lists the file's names and suggests the closest
    assert any("missing toy field 'presure'" in e and "'pressure'" in e for e in errors), errors
