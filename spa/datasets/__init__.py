"""Dataset contract, validation and ingest of bench recordings (see ``raw/README.md``).

A dataset is a folder ``raw/<name>/`` holding ``dataset.yaml`` and the run files it names.
:func:`validate_dataset` checks the folder against the contract and returns every problem at
once; :func:`ingest_dataset` turns each run into one canonical Parquet run table, written by
:func:`write_run_table` and read back by :func:`read_run_table`.

The canonical run table has the columns ``t`` (s, float64), ``p`` (bar gauge, float64),
``valve`` (int8 in {0, 1}, when recorded) and ``u`` (input fraction in [0, 1], float64, when
recorded), in that order, and the run's description as JSON under the Parquet key-value
metadata key ``b"spa"``.

Recordings are read in chunks (CSV in line-aligned blocks parsed by ``pyarrow.csv``, Parquet
by record batches), checked chunk by chunk (carrying the last time stamp across chunks) and
written batch by batch, so the memory needed does not grow with the length of a recording.
MATLAB files are loaded whole by ``scipy.io.loadmat``.
"""

from __future__ import annotations

import csv
import datetime as _dt
import difflib
import hashlib
import json
import math
import os
import re
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path, PurePosixPath, PureWindowsPath
from typing import Any

import numpy as np
import numpy.typing as npt
import pandas as pd
import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.csv as pacsv
import pyarrow.parquet as pq
import yaml

from spa.model.modulators import MODULATORS, check_settings

__all__ = [
    "CANONICAL_COLUMNS",
    "KINDS",
    "META_KEY",
    "ORIGINS",
    "PRESSURE_UNITS",
    "P_MAX_BAR",
    "P_MIN_BAR",
    "REQUIRED_COLUMNS",
    "RUN_TABLE_FORMAT",
    "SPEC_FILE",
    "TIME_UNITS",
    "DatasetError",
    "DatasetSpec",
    "Problem",
    "RunEntry",
    "RunSummary",
    "check_dataset",
    "find_datasets",
    "ingest_dataset",
    "load_spec",
    "read_run_meta",
    "read_run_table",
    "validate_dataset",
    "write_run_table",
]

#: Name of the description file inside a dataset folder.
SPEC_FILE = "dataset.yaml"
#: Kinds of run.
KINDS: tuple[str, ...] = ("charge", "discharge", "pulse", "staircase", "sine", "chirp")
#: Kinds of run driven through a pulse modulator: they need ``modulator`` and ``u``.
MODULATED_KINDS: tuple[str, ...] = ("staircase", "sine", "chirp")
#: Where the data come from.
ORIGINS: tuple[str, ...] = ("bench", "synthetic")
#: Canonical column names, in the order of a run table.
CANONICAL_COLUMNS: tuple[str, ...] = ("t", "p", "valve", "u")
#: Columns each kind of run must have.
REQUIRED_COLUMNS: Mapping[str, tuple[str, ...]] = {
    "charge": ("t", "p"),
    "discharge": ("t", "p"),
    "pulse": ("t", "p", "valve"),
    "staircase": ("t", "p", "u"),
    "sine": ("t", "p", "u"),
    "chirp": ("t", "p", "u"),
}
#: Columns whose absence is a warning, not an error.
RECOMMENDED_COLUMNS: Mapping[str, tuple[str, ...]] = {k: ("valve",) for k in MODULATED_KINDS}
#: Seconds per unit of time.
TIME_UNITS: Mapping[str, float] = {"s": 1.0, "ms": 1e-3}
#: Bar per unit of (gauge) pressure.
PRESSURE_UNITS: Mapping[str, float] = {"bar": 1.0, "mbar": 1e-3, "kPa": 1e-2, "psi": 0.0689475729}
#: Plausible range of gauge pressure for a soft actuator, in bar: a little below full vacuum
#: (-1.013 bar, with room for sensor offset) up to well above any supply used with one.
P_MIN_BAR = -1.1
P_MAX_BAR = 20.0
#: Parquet key-value metadata key holding the run's description as JSON.
META_KEY = b"spa"
#: Value of ``meta["format"]`` in every run table.
RUN_TABLE_FORMAT = "spa.run/1"

# Units whose factor is the inverse of an integer: divide by it, which rounds correctly.
_DIVISORS = {"ms": 1000.0, "mbar": 1000.0, "kPa": 100.0}
_FORMATS = {".csv": "csv", ".parquet": "parquet", ".mat": "mat"}
_TOP_KEYS = ("name", "description", "origin", "rig", "units", "columns", "runs")
_REQUIRED_TOP = ("name", "description", "origin", "rig", "runs")
_RUN_KEYS = ("id", "kind", "file", "modulator", "notes")
_UNIT_KEYS = ("time", "pressure")
_NAME_RE = re.compile(r"[A-Za-z0-9._-]+")
_ID_RE = re.compile(r"[A-Za-z0-9_-][A-Za-z0-9._-]{0,99}")
_ARROW_TYPES = {"t": pa.float64(), "p": pa.float64(), "valve": pa.int8(), "u": pa.float64()}
_QUANTITY = {"t": "time", "p": "pressure", "valve": "valve command", "u": "input fraction u"}
_NA_TOKENS = frozenset(
    ["", "#N/A", "#N/A N/A", "#NA", "-1.#IND", "-1.#QNAN", "-NaN", "-nan", "1.#IND",
     "1.#QNAN", "N/A", "NA", "NULL", "NaN", "n/a", "nan", "null"]
)
_CSV_BLOCK = 16 << 20  # bytes per CSV block read
_BATCH_ROWS = 1 << 19  # rows per Parquet / MATLAB chunk
_ROW_GROUP = 1 << 20  # rows per row group of a run table
_MAX_ROWS_LISTED = 5
_WRITER_OPTIONS: dict[str, Any] = {
    "version": "2.6",
    "compression": "zstd",
    "compression_level": 3,
    "use_dictionary": ["valve"],
    "write_statistics": True,
}


# --------------------------------------------------------------------------- problems


@dataclass(frozen=True, slots=True)
class Problem:
    """One thing wrong with a dataset, located as precisely as possible.

    Parameters
    ----------
    file : str or None
        File the problem is in, relative to the dataset folder (``"dataset.yaml"`` for the
        description), or None for the folder itself.
    run : str or None
        Run id, when the problem belongs to one run.
    column : str or None
        Column (or MATLAB variable) name as written in the file.
    row : int or None
        Data row, counted from 1 at the first row after the header: the first row where the
        problem shows (the message counts the others).
    message : str
        What is wrong and what was expected.
    key : str or None
        Location inside ``dataset.yaml``, such as ``runs[2].kind``.
    line : int or None
        Line of a CSV file (the header is line 1), when known.
    level : {"error", "warning"}
        Warnings are reported but do not make a dataset invalid.
    """

    file: str | None
    run: str | None
    column: str | None
    row: int | None
    message: str
    key: str | None = None
    line: int | None = None
    level: str = "error"

    def __str__(self) -> str:
        where = self.file or "dataset folder"
        if self.key:
            where += f": {self.key}"
        details = []
        if self.run is not None:
            details.append(f"run {self.run!r}")
        if self.column is not None:
            details.append(f"column {self.column!r}")
        if self.row is not None:
            details.append(f"row {self.row}" + (f" (line {self.line})" if self.line else ""))
        elif self.line is not None:
            details.append(f"line {self.line}")
        if details:
            where += f" [{', '.join(details)}]"
        return f"{self.level}: {where}: {self.message}"

    @property
    def is_error(self) -> bool:
        """True for an error, False for a warning."""
        return self.level == "error"


class DatasetError(ValueError):
    """Raised when a dataset breaks the contract; ``problems`` lists every problem found."""

    def __init__(self, folder: str | Path, problems: list[Problem]) -> None:
        self.folder = Path(folder)
        self.problems = list(problems)
        n = sum(p.is_error for p in self.problems)
        lines = "\n  ".join(str(p) for p in self.problems)
        super().__init__(f"{folder}: {n} error(s) in dataset (see raw/README.md):\n  {lines}")


def _suggest(word: Any, choices: Any) -> str:
    """Return ``" (did you mean 'x'?)"`` for the closest of ``choices``, or ``""``."""
    options = [str(c) for c in choices]
    text = str(word)
    for c in options:
        if c.lower() == text.lower():
            return f" (did you mean {c!r}?)"
    close = difflib.get_close_matches(text, options, n=1, cutoff=0.6)
    return f" (did you mean {close[0]!r}?)" if close else ""


def _unknown_key(key: Any, allowed: Any) -> str:
    return f"unknown key {key!r}{_suggest(key, allowed)}; allowed keys: {_one_of(allowed)}"


def _is_one_of(value: Any, choices: Any) -> bool:
    """``value in choices`` for string choices, False for any other (even unhashable) value."""
    return isinstance(value, str) and value in choices


def _one_of(choices: Any) -> str:
    return ", ".join(str(c) for c in choices)


# --------------------------------------------------------------------------- specification


@dataclass(frozen=True, slots=True)
class RunEntry:
    """One entry of ``runs:`` in ``dataset.yaml``, checked.

    Attributes
    ----------
    id : str
        Run id, unique within the dataset and safe as a file name.
    kind : str
        One of :data:`KINDS`.
    file : str
        Path of the run's file, relative to the dataset folder.
    modulator : dict or None
        ``{"type": kind, **settings}`` with every setting filled in (see
        :func:`spa.model.modulators.check_settings`), or None.
    notes : str or None
        Free text.
    """

    id: str
    kind: str
    file: str
    modulator: dict[str, Any] | None = None
    notes: str | None = None


@dataclass(frozen=True, slots=True)
class DatasetSpec:
    """The content of a valid ``dataset.yaml``.

    Attributes
    ----------
    folder : pathlib.Path
        The dataset folder.
    name, description, origin : str
        As in the file; ``origin`` is one of :data:`ORIGINS`.
    rig : dict
        Free description of the bench (dates turned into ISO strings).
    time_unit, pressure_unit : str
        Units of the files (keys of :data:`TIME_UNITS` and :data:`PRESSURE_UNITS`).
    columns : dict
        Column name in the files for each canonical name in :data:`CANONICAL_COLUMNS`.
    runs : tuple of RunEntry
        The runs, in file order.
    """

    folder: Path
    name: str
    description: str
    origin: str
    rig: dict[str, Any]
    time_unit: str
    pressure_unit: str
    columns: dict[str, str]
    runs: tuple[RunEntry, ...]

    def run_path(self, run: RunEntry | str) -> Path:
        """Absolute path of a run's file."""
        spec = run if isinstance(run, RunEntry) else self.run(run)
        return self.folder / spec.file

    def run(self, run_id: str) -> RunEntry:
        """The run with id ``run_id``; ``KeyError`` naming the known ids if absent."""
        for r in self.runs:
            if r.id == run_id:
                return r
        raise KeyError(f"no run {run_id!r} in dataset {self.name!r}; runs: {self.run_ids}")

    @property
    def run_ids(self) -> list[str]:
        """Run ids in file order."""
        return [r.id for r in self.runs]


@dataclass
class _Parsed:
    """Whatever could be checked of ``dataset.yaml``; runs with problems are left out."""

    folder: Path
    problems: list[Problem] = field(default_factory=list)
    name: str = ""
    description: str = ""
    origin: str = ""
    rig: dict[str, Any] = field(default_factory=dict)
    time_unit: str = "s"
    pressure_unit: str = "bar"
    columns: dict[str, str] = field(default_factory=lambda: {c: c for c in CANONICAL_COLUMNS})
    runs: list[RunEntry] = field(default_factory=list)
    data_ok: bool = True  # units and columns are usable for checking the data

    def error(self, message: str, *, key: str | None = None, run: str | None = None,
              file: str | None = SPEC_FILE, level: str = "error") -> None:
        self.problems.append(Problem(file, run, None, None, message, key=key, level=level))

    @property
    def has_errors(self) -> bool:
        return any(p.is_error for p in self.problems)


class _UniqueKeyLoader(yaml.SafeLoader):
    """Safe YAML loader that rejects a key given twice in one mapping.

    Floats are read as YAML 1.2 reads them, so ``20e-3`` is a number (YAML 1.1, PyYAML's
    default, needs ``20.0e-3`` and would give the string ``'20e-3'``).
    """


_UniqueKeyLoader.yaml_implicit_resolvers = {
    k: [r for r in v if r[0] != "tag:yaml.org,2002:float"]
    for k, v in yaml.SafeLoader.yaml_implicit_resolvers.items()
}
_UniqueKeyLoader.add_implicit_resolver(
    "tag:yaml.org,2002:float",
    re.compile(
        r"""^(?:[-+]?(?:[0-9][0-9_]*)\.[0-9_]*(?:[eE][-+]?[0-9]+)?
        |[-+]?(?:[0-9][0-9_]*)(?:[eE][-+]?[0-9]+)
        |\.[0-9_]+(?:[eE][-+]?[0-9]+)?
        |[-+]?\.(?:inf|Inf|INF)
        |\.(?:nan|NaN|NAN))$""",
        re.X,
    ),
    list("-+0123456789."),
)


def _construct_mapping(loader: yaml.SafeLoader, node: yaml.MappingNode, deep: bool = False) -> Any:
    seen: set[Any] = set()
    for key_node, _ in node.value:
        key = loader.construct_object(key_node, deep=deep)
        try:
            duplicate = key in seen
        except TypeError:
            continue
        if duplicate:
            raise yaml.constructor.ConstructorError(
                "while constructing a mapping", node.start_mark,
                f"found duplicate key {key!r}", key_node.start_mark,
            )
        seen.add(key)
    return loader.construct_mapping(node, deep=deep)


_UniqueKeyLoader.add_constructor(
    yaml.resolver.BaseResolver.DEFAULT_MAPPING_TAG, _construct_mapping
)


def _plain(value: Any) -> Any:
    """Turn YAML values into JSON-compatible ones (dates become ISO strings)."""
    if isinstance(value, Mapping):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_plain(v) for v in value]
    if isinstance(value, _dt.date | _dt.datetime | _dt.time):
        return value.isoformat()
    if value is None or isinstance(value, bool | int | float | str):
        if isinstance(value, float) and not math.isfinite(value):
            return str(value)
        return value
    return str(value)


def _check_modulator(value: Any) -> tuple[dict[str, Any] | None, list[str]]:
    """Check a ``modulator:`` mapping; return the completed settings and the problems."""
    example = "e.g. {type: pwm, f_w: 20}"
    if not isinstance(value, Mapping):
        return None, [f"modulator must be a mapping, {example}; got {value!r}"]
    kind = value.get("type")
    if kind is None:
        return None, [f"modulator has no 'type'; expected one of {_one_of(MODULATORS)}, {example}"]
    if not _is_one_of(kind, MODULATORS):
        return None, [
            f"unknown modulator type {kind!r}; expected one of {_one_of(MODULATORS)}"
            f"{_suggest(kind, MODULATORS)}"
        ]
    allowed = ["type", *MODULATORS[kind]]
    problems = [
        f"unknown {kind} setting {k!r}{_suggest(k, allowed)}; {kind} takes {_one_of(allowed)}"
        for k in value
        if k not in allowed
    ]
    if problems:
        return None, problems
    settings = {k: v for k, v in value.items() if k != "type"}
    try:
        full = check_settings(str(kind), **settings)
    except ValueError as exc:
        return None, [f"bad modulator settings: {exc}"]
    return {"type": kind, **full}, []


def _check_run_file(folder: Path, value: Any) -> tuple[str | None, str | None]:
    """Check a run's ``file``: return (relative path, None) or (None, problem)."""
    if not isinstance(value, str) or not value.strip():
        return None, f"file must be a path relative to the dataset folder, got {value!r}"
    if "\\" in value:
        return None, f"file path {value!r} contains '\\'; use '/' between folders"
    if PurePosixPath(value).is_absolute() or PureWindowsPath(value).drive:
        return None, (
            f"file path {value!r} is absolute; paths must be relative to the dataset folder "
            "and stay inside it"
        )
    if ".." in PurePosixPath(value).parts:
        return None, (
            f"file path {value!r} leaves the dataset folder through '..'; "
            "data files must live inside the folder"
        )
    full = folder / value
    resolved = full.resolve()
    if not resolved.is_relative_to(folder.resolve()):
        return None, (
            f"file path {value!r} resolves to {resolved}, outside the dataset folder "
            "(a symlink pointing out?); data files must live inside the folder"
        )
    suffix = PurePosixPath(value).suffix.lower()
    if suffix not in _FORMATS:
        return None, (
            f"unsupported file type {suffix or '(none)'!r} for {value!r}; expected one of "
            f"{_one_of(_FORMATS)}"
        )
    if not full.exists():
        return None, f"file {value!r} not found (looked for {full})"
    if not full.is_file():
        return None, f"{value!r} is not a regular file"
    return value, None


def _parse_spec(folder: Path) -> _Parsed:
    parsed = _Parsed(folder=folder)
    if not folder.exists():
        parsed.error(f"dataset folder {folder} does not exist", file=None)
        parsed.data_ok = False
        return parsed
    if not folder.is_dir():
        parsed.error(f"{folder} is not a folder; a dataset is a folder holding {SPEC_FILE}",
                     file=None)
        parsed.data_ok = False
        return parsed
    spec_path = folder / SPEC_FILE
    if not spec_path.is_file():
        parsed.error(f"missing {SPEC_FILE}: every dataset folder needs one (see raw/README.md)")
        parsed.data_ok = False
        return parsed
    try:
        doc = yaml.load(spec_path.read_text(encoding="utf-8"), Loader=_UniqueKeyLoader)
    except UnicodeDecodeError as exc:
        parsed.error(f"cannot read {SPEC_FILE} as UTF-8 text: {exc}")
        parsed.data_ok = False
        return parsed
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f" at line {mark.line + 1}, column {mark.column + 1}" if mark else ""
        what = getattr(exc, "problem", None) or str(exc)
        parsed.error(f"cannot parse YAML{where}: {what}")
        parsed.data_ok = False
        return parsed
    if not isinstance(doc, Mapping):
        kind = "an empty file" if doc is None else f"a {type(doc).__name__}"
        parsed.error(f"expected a mapping with keys {_one_of(_TOP_KEYS)}; got {kind}")
        parsed.data_ok = False
        return parsed

    for key in doc:
        if key not in _TOP_KEYS:
            parsed.error(
                _unknown_key(key, _TOP_KEYS),
                key=str(key),
            )
    for key in _REQUIRED_TOP:
        if key not in doc:
            parsed.error(f"missing required key {key!r}")

    name = doc.get("name")
    if "name" in doc:
        if not isinstance(name, str) or not _NAME_RE.fullmatch(name) or name in (".", ".."):
            parsed.error(
                f"name {name!r} must be a string of letters, digits, '.', '_' and '-'",
                key="name",
            )
        elif name != folder.name:
            parsed.error(
                f"name {name!r} differs from the folder name {folder.name!r}; they must be equal",
                key="name",
            )
        else:
            parsed.name = name
    if "description" in doc:
        desc = doc["description"]
        if not isinstance(desc, str) or not desc.strip():
            parsed.error(f"description must be non-empty text, got {desc!r}", key="description")
        else:
            parsed.description = desc.strip()
    if "origin" in doc:
        origin = doc["origin"]
        if not _is_one_of(origin, ORIGINS):
            parsed.error(
                f"origin {origin!r} is not one of {_one_of(ORIGINS)}{_suggest(origin, ORIGINS)}",
                key="origin",
            )
        else:
            parsed.origin = origin
    if "rig" in doc:
        rig = doc["rig"]
        if not isinstance(rig, Mapping):
            parsed.error(
                "rig must be a mapping describing the bench, e.g. "
                f"{{valve: ..., actuator: ..., sensors: ..., controller: ...}}; got {rig!r}",
                key="rig",
            )
        else:
            parsed.rig = _plain(rig)

    _parse_units(parsed, doc.get("units"))
    _parse_columns(parsed, doc.get("columns"))
    if "runs" in doc:
        _parse_runs(parsed, doc["runs"])
    return parsed


def _parse_units(parsed: _Parsed, units: Any) -> None:
    if units is None:
        return
    if not isinstance(units, Mapping):
        parsed.error(f"units must be a mapping like {{time: ms, pressure: kPa}}, got {units!r}",
                     key="units")
        parsed.data_ok = False
        return
    for key in units:
        if key not in _UNIT_KEYS:
            parsed.error(
                _unknown_key(key, _UNIT_KEYS),
                key=f"units.{key}",
            )
            parsed.data_ok = False
    for key, table in (("time", TIME_UNITS), ("pressure", PRESSURE_UNITS)):
        if key not in units:
            continue
        value = units[key]
        if not _is_one_of(value, table):
            parsed.error(
                f"{key} unit {value!r} is not one of {_one_of(table)}{_suggest(value, table)}",
                key=f"units.{key}",
            )
            parsed.data_ok = False
        elif key == "time":
            parsed.time_unit = value
        else:
            parsed.pressure_unit = value


def _parse_columns(parsed: _Parsed, columns: Any) -> None:
    if columns is None:
        return
    if not isinstance(columns, Mapping):
        parsed.error(
            f"columns must map canonical names ({_one_of(CANONICAL_COLUMNS)}) to the names in "
            f"the files, e.g. {{t: time_ms, p: P_kPa}}; got {columns!r}",
            key="columns",
        )
        parsed.data_ok = False
        return
    for key, value in columns.items():
        if key not in CANONICAL_COLUMNS:
            parsed.error(
                f"unknown canonical column {key!r}{_suggest(key, CANONICAL_COLUMNS)}; "
                f"allowed: {_one_of(CANONICAL_COLUMNS)}",
                key=f"columns.{key}",
            )
            parsed.data_ok = False
        elif not isinstance(value, str) or not value:
            parsed.error(f"column name for {key!r} must be a non-empty string, got {value!r}",
                         key=f"columns.{key}")
            parsed.data_ok = False
        else:
            parsed.columns[key] = value
    names = list(parsed.columns.values())
    for dup in sorted({n for n in names if names.count(n) > 1}):
        which = [c for c, n in parsed.columns.items() if n == dup]
        parsed.error(
            f"file column {dup!r} is used for several canonical columns {which} (a canonical "
            "name not mapped under columns: stands for itself)",
            key="columns",
        )
        parsed.data_ok = False


def _parse_runs(parsed: _Parsed, runs: Any) -> None:
    if not isinstance(runs, list):
        parsed.error(f"runs must be a list of {{id, kind, file, ...}} entries, got {runs!r}",
                     key="runs")
        return
    if not runs:
        parsed.error("runs is empty; list at least one run", key="runs")
        return
    seen: dict[str, str] = {}
    for i, entry in enumerate(runs):
        key = f"runs[{i}]"
        if not isinstance(entry, Mapping):
            parsed.error(
                f"each run must be a mapping with keys {_one_of(_RUN_KEYS)}, got {entry!r}", key=key
            )
            continue
        before = len(parsed.problems)
        rid = entry.get("id")
        label = rid if isinstance(rid, str) else None

        def err(message: str, sub: str | None = None, _label: str | None = label,
                _key: str = key) -> None:
            parsed.error(message, key=f"{_key}.{sub}" if sub else _key, run=_label)

        for k in entry:
            if k not in _RUN_KEYS:
                err(_unknown_key(k, _RUN_KEYS), str(k))
        for k in ("id", "kind", "file"):
            if k not in entry:
                err(f"missing required key {k!r}")
        if "id" in entry:
            if not isinstance(rid, str):
                err(f"id must be a string (quote it in YAML: id: '{rid}'), got {rid!r}", "id")
            elif not _ID_RE.fullmatch(rid):
                err(
                    f"id {rid!r} is not filename-safe: use up to 100 letters, digits, '.', '_' "
                    "and '-', not starting with '.'",
                    "id",
                )
            elif rid.casefold() in seen:
                other = seen[rid.casefold()]
                same = "" if other == rid else f" ({other!r} differs only in case)"
                err(f"duplicate run id {rid!r}{same}; run ids must be unique", "id")
            else:
                seen[rid.casefold()] = rid
        kind = entry.get("kind")
        if "kind" in entry and not _is_one_of(kind, KINDS):
            err(f"unknown kind {kind!r}; expected one of {_one_of(KINDS)}{_suggest(kind, KINDS)}",
                "kind")
        modulator = None
        if entry.get("modulator") is not None:
            modulator, problems = _check_modulator(entry["modulator"])
            for message in problems:
                err(message, "modulator")
        elif _is_one_of(kind, MODULATED_KINDS):
            err(
                f"a {kind} run needs a modulator, one of {{type: pwm, f_w: <Hz>}}, "
                "{type: ipfm, t_h: <s>, gain: <G>}, {type: iipfm, t_l: <s>, gain: <G>}, "
                "{type: dsm, period: <s>}",
                "modulator",
            )
        notes = entry.get("notes")
        if notes is not None and not isinstance(notes, str):
            err(f"notes must be text, got {notes!r}", "notes")
        rel = None
        if "file" in entry:
            rel, message = _check_run_file(parsed.folder, entry["file"])
            if message:
                err(message, "file")
        if len(parsed.problems) == before and rel is not None:
            parsed.runs.append(RunEntry(rid, kind, rel, modulator, notes))


def find_datasets(raw_dir: str | Path) -> list[str]:
    """Names of the dataset folders in ``raw_dir``: its sub-folders holding a ``dataset.yaml``.

    Parameters
    ----------
    raw_dir : str or path-like
        The folder of datasets, usually ``raw``. A missing folder holds no datasets.

    Returns
    -------
    list of str
        Sorted folder names (hidden folders, starting with ``.``, are skipped).
    """
    root = Path(raw_dir)
    if not root.is_dir():
        return []
    return sorted(
        p.name for p in root.iterdir()
        if p.is_dir() and not p.name.startswith(".") and (p / SPEC_FILE).is_file()
    )


def load_spec(folder: str | Path) -> DatasetSpec:
    """Read and check ``dataset.yaml`` of a dataset folder (not the data themselves).

    Parameters
    ----------
    folder : str or path-like
        The dataset folder, ``raw/<name>``.

    Returns
    -------
    DatasetSpec
        The description with defaults filled in.

    Raises
    ------
    DatasetError
        Listing every problem of ``dataset.yaml``: unknown keys (with the closest valid key),
        bad values, run files that are missing, of an unsupported type or outside the folder.
    """
    parsed = _parse_spec(Path(folder))
    if parsed.has_errors:
        raise DatasetError(folder, parsed.problems)
    return _spec_from(parsed)


def _spec_from(parsed: _Parsed) -> DatasetSpec:
    return DatasetSpec(
        folder=parsed.folder,
        name=parsed.name,
        description=parsed.description,
        origin=parsed.origin,
        rig=parsed.rig,
        time_unit=parsed.time_unit,
        pressure_unit=parsed.pressure_unit,
        columns=dict(parsed.columns),
        runs=tuple(parsed.runs),
    )


# --------------------------------------------------------------------------- units


def _to_seconds(t: npt.NDArray[np.float64], unit: str) -> npt.NDArray[np.float64]:
    return t / _DIVISORS[unit] if unit in _DIVISORS else t * TIME_UNITS[unit]


def _to_bar(p: Any, unit: str) -> Any:
    return p / _DIVISORS[unit] if unit in _DIVISORS else p * PRESSURE_UNITS[unit]


# --------------------------------------------------------------------------- readers


class _ReadError(Exception):
    """A file (or one of its columns) cannot be read; becomes a Problem."""

    def __init__(self, message: str, column: str | None = None, row: int | None = None):
        super().__init__(message)
        self.column = column
        self.row = row


class _Retry(Exception):
    """The fast CSV path met a value it cannot parse as a number: re-read as text."""


# A chunk: (rows before it, values by file column, non-numeric mask by file column or None).
_Chunk = tuple[int, dict[str, npt.NDArray[np.float64]], dict[str, npt.NDArray[np.bool_]]]


def _text_to_float(
    values: pa.Array | pa.ChunkedArray,
) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.bool_]]:
    """Parse text as numbers; return the values (NaN where missing) and a non-numeric mask."""
    obj = pd.Series(values.to_numpy(zero_copy_only=False), dtype=object)
    numbers = pd.to_numeric(obj, errors="coerce").to_numpy(dtype=np.float64, na_value=np.nan)
    stripped = obj.map(lambda s: s.strip() if isinstance(s, str) else "")
    bad = np.isnan(numbers) & ~stripped.isin(_NA_TOKENS).to_numpy()
    return numbers, bad


class _CsvSource:
    """Comma-separated text with one header line, parsed by ``pyarrow.csv`` block by block.

    The file is cut at line ends into blocks of about ``_CSV_BLOCK`` bytes, read one at a time
    (``pyarrow.csv.open_csv`` reads ahead without bound on a fast disk), so memory stays flat
    whatever the length of the file. Quoted fields must not hold line breaks.
    """

    def __init__(self, path: Path) -> None:
        self.path = path
        self.invalid: list[tuple[int | None, str, int, int]] = []
        # (first data row, first line, rows map one-to-one onto lines) of each block read
        self.blocks: list[tuple[int, int, bool]] = []
        with path.open("rb") as fh:
            first = fh.readline(1 << 20)
        self.header_size = len(first)
        try:
            text = first.decode("utf-8-sig")
        except UnicodeDecodeError:
            raise _ReadError(
                "the header line is not UTF-8 text; is this really a CSV file?"
            ) from None
        names = next(csv.reader([text.rstrip("\r\n")]), [])
        if not any(n.strip() for n in names):
            raise _ReadError("the first line is empty; expected a header line naming the columns")
        self.columns = names

    def _blocks(self) -> Iterator[bytes]:
        with self.path.open("rb") as fh:
            fh.seek(self.header_size)
            carry = b""
            while True:
                data = fh.read(_CSV_BLOCK)
                if not data:
                    if carry:
                        yield carry
                    return
                data = carry + data
                cut = data.rfind(b"\n") + 1
                carry = data[cut:]
                if cut:
                    yield data[:cut]

    def _parse(self, block: bytes, names: list[str], kind: pa.DataType, threads: bool,
               invalid: list[Any]) -> pa.Table:
        def handler(row: Any) -> str:
            invalid.append(row)
            return "skip"

        keys = [f"c{i}" for i in range(len(self.columns))]  # names in files may repeat
        include = [keys[self.columns.index(n)] for n in names]
        table = pacsv.read_csv(
            pa.py_buffer(block),
            read_options=pacsv.ReadOptions(column_names=keys, use_threads=threads),
            parse_options=pacsv.ParseOptions(invalid_row_handler=handler),
            convert_options=pacsv.ConvertOptions(
                include_columns=include,
                column_types=dict.fromkeys(include, kind),
                strings_can_be_null=False,
            ),
        )
        return table.rename_columns(names)

    def chunks(self, names: list[str], as_text: bool = False) -> Iterator[_Chunk]:
        self.invalid = []
        self.blocks = []
        kind = pa.string() if as_text else pa.float64()
        offset, line = 0, 2
        try:
            for block in self._blocks():
                invalid: list[Any] = []
                table = self._parse(block, names, kind, True, invalid)
                if invalid:  # parse again on one thread, which numbers the bad lines
                    invalid = []
                    table = self._parse(block, names, kind, False, invalid)
                lines = block.count(b"\n") + (not block.endswith(b"\n"))
                for row in invalid:
                    number = None if row.number is None else line + row.number - 1
                    self.invalid.append(
                        (number, row.text, row.expected_columns, row.actual_columns)
                    )
                self.blocks.append((offset + 1, line, table.num_rows == lines))
                values: dict[str, npt.NDArray[np.float64]] = {}
                bad: dict[str, npt.NDArray[np.bool_]] = {}
                for name in names:
                    col = table.column(name)
                    if as_text:
                        values[name], bad[name] = _text_to_float(col)
                    else:
                        values[name] = col.to_numpy().astype(np.float64, copy=False)
                yield offset, values, bad
                offset += table.num_rows
                line += lines
        except pa.ArrowInvalid as exc:
            if not as_text and "conversion error" in str(exc):
                raise _Retry from exc
            raise _ReadError(f"cannot parse the CSV file: {exc}") from exc

    def line_of(self, row: int | None) -> int | None:
        """Line of data row ``row`` (1-based), when blank or malformed lines do not blur it."""
        if row is None:
            return None
        for first_row, first_line, exact in reversed(self.blocks):
            if row >= first_row:
                return first_line + row - first_row if exact else None
        return None


def _numeric_type(kind: pa.DataType) -> bool:
    return (
        pa.types.is_integer(kind)
        or pa.types.is_floating(kind)
        or pa.types.is_boolean(kind)
        or pa.types.is_decimal(kind)
        or pa.types.is_null(kind)
    )


def _text_type(kind: pa.DataType) -> bool:
    return pa.types.is_string(kind) or pa.types.is_large_string(kind)


class _ParquetSource:
    """A Parquet file, read by record batches."""

    def __init__(self, path: Path) -> None:
        self.path = path
        try:
            self.file = pq.ParquetFile(path)
        except Exception as exc:  # pyarrow raises several types for a damaged file
            raise _ReadError(f"unreadable Parquet file (truncated or damaged?): {exc}") from exc
        self.schema = self.file.schema_arrow
        self.columns = list(self.schema.names)

    def check_types(self, names: list[str]) -> list[_ReadError]:
        errors = []
        for name in names:
            kind = self.schema.field(name).type
            if not (_numeric_type(kind) or _text_type(kind)):
                errors.append(_ReadError(f"column has Parquet type {kind}; expected numbers",
                                         column=name))
        return errors

    def chunks(self, names: list[str], as_text: bool = False) -> Iterator[_Chunk]:
        offset = 0
        try:
            for batch in self.file.iter_batches(batch_size=_BATCH_ROWS, columns=names):
                values: dict[str, npt.NDArray[np.float64]] = {}
                bad: dict[str, npt.NDArray[np.bool_]] = {}
                for name in names:
                    col = batch.column(name)
                    if _text_type(col.type):
                        values[name], bad[name] = _text_to_float(col)
                    else:
                        values[name] = pc.cast(col, pa.float64()).to_numpy(zero_copy_only=False)
                yield offset, values, bad
                offset += batch.num_rows
        except (pa.ArrowException, OSError) as exc:
            raise _ReadError(
                f"unreadable Parquet data after row {offset} (truncated or damaged?): {exc}",
                row=offset + 1,
            ) from exc


class _MatSource:
    """A MATLAB v4/v5/v7 ``.mat`` file holding one vector variable per column."""

    def __init__(self, path: Path) -> None:
        import scipy.io

        self.path = path
        try:
            self.data = scipy.io.loadmat(path, squeeze_me=False, mat_dtype=False)
        except NotImplementedError as exc:
            raise _ReadError(
                "MATLAB v7.3 (HDF5) files are not supported; save with "
                "save(..., '-v7') or export CSV/Parquet"
            ) from exc
        except Exception as exc:  # scipy raises several types for a damaged file
            raise _ReadError(
                f"unreadable MATLAB file (truncated, damaged or not a .mat file?): "
                f"{type(exc).__name__}: {exc}"
            ) from exc
        self.columns = [k for k in self.data if not k.startswith("__")]

    def check_types(self, names: list[str]) -> list[_ReadError]:
        errors = []
        lengths: dict[str, int] = {}
        for name in names:
            value = self.data[name]
            if not isinstance(value, np.ndarray) or value.dtype.kind not in "biuf":
                kind = getattr(value, "dtype", type(value).__name__)
                errors.append(_ReadError(
                    f"MATLAB variable holds {kind}, not real numbers; expected a numeric vector",
                    column=name,
                ))
            elif value.ndim > 2 or (value.ndim == 2 and min(value.shape) > 1):
                errors.append(_ReadError(
                    f"MATLAB variable has shape {value.shape}; expected a vector (n×1 or 1×n)",
                    column=name,
                ))
            else:
                lengths[name] = value.size
        if len(set(lengths.values())) > 1:
            sizes = ", ".join(f"{k}: {v}" for k, v in lengths.items())
            errors.append(_ReadError(
                f"MATLAB variables have different lengths ({sizes}); expected one length"
            ))
        return errors

    def chunks(self, names: list[str], as_text: bool = False) -> Iterator[_Chunk]:
        arrays = {n: np.asarray(self.data[n], dtype=np.float64).ravel() for n in names}
        n = len(next(iter(arrays.values()))) if arrays else 0
        for start in range(0, n, _BATCH_ROWS):
            yield start, {k: v[start:start + _BATCH_ROWS] for k, v in arrays.items()}, {}


_SOURCES = {"csv": _CsvSource, "parquet": _ParquetSource, "mat": _MatSource}


# --------------------------------------------------------------------------- checks


class _Tally:
    __slots__ = ("count", "detail", "rows")

    def __init__(self) -> None:
        self.count = 0
        self.rows: list[int] = []
        self.detail = ""


@dataclass(frozen=True, slots=True)
class RunSummary:
    """What a run holds, for the one-line report of ``spa validate``.

    Attributes
    ----------
    run, kind, file : str
        Run id, kind and file (relative to the dataset folder).
    modulator : dict or None
        Completed modulator settings.
    columns : tuple of str
        Canonical columns present.
    rows : int
        Number of samples.
    t_start, t_end : float
        First and last time stamp in s.
    rate_hz : float
        Mean sample rate ``(rows - 1) / (t_end - t_start)`` in Hz.
    p_min, p_max : float
        Pressure range in bar gauge.
    """

    run: str
    kind: str
    file: str
    modulator: dict[str, Any] | None
    columns: tuple[str, ...]
    rows: int
    t_start: float
    t_end: float
    rate_hz: float
    p_min: float
    p_max: float

    @property
    def duration(self) -> float:
        """``t_end - t_start`` in s."""
        return self.t_end - self.t_start

    def __str__(self) -> str:
        return (
            f"{self.run}: {self.kind}, {_modulator_text(self.modulator)}, "
            f"{self.duration:.6g} s at {self.rate_hz:.6g} Hz, "
            f"p {self.p_min:.4g} to {self.p_max:.4g} bar "
            f"({self.file}, {self.rows} rows, columns {' '.join(self.columns)})"
        )


def _modulator_text(modulator: Mapping[str, Any] | None) -> str:
    if not modulator:
        return "no modulator"
    units = {"f_w": " Hz", "t_h": " s", "t_l": " s", "period": " s", "gain": ""}
    settings = " ".join(
        f"{k}={v:g}{units.get(k, '')}" for k, v in modulator.items() if k != "type"
    )
    return f"{modulator['type']} {settings}"


class _RunCheck:
    """Checks of one run's samples, fed chunk by chunk, in the file's own units."""

    def __init__(self, columns: Mapping[str, str], time_unit: str, pressure_unit: str) -> None:
        self.columns = dict(columns)  # canonical -> file column, present ones only
        self.time_unit = time_unit
        self.pressure_unit = pressure_unit
        self.tallies: dict[tuple[str, str], _Tally] = {}
        self.rows = 0
        self.t_first = math.nan
        self.t_prev: float | None = None
        self.p_lo = math.inf
        self.p_hi = -math.inf

    @property
    def failed(self) -> bool:
        return bool(self.tallies)

    def _note(self, canon: str, check: str, mask: npt.NDArray[np.bool_], offset: int,
              detail: Any) -> None:
        """Record rows where ``mask`` holds; ``detail(i)`` describes index ``i``."""
        hits = np.flatnonzero(mask)
        if hits.size == 0:
            return
        tally = self.tallies.setdefault((canon, check), _Tally())
        if tally.count == 0:
            tally.detail = detail(int(hits[0]))
        tally.count += int(hits.size)
        room = _MAX_ROWS_LISTED - len(tally.rows)
        if room > 0:
            tally.rows.extend(int(i) + offset + 1 for i in hits[:room])

    def feed(self, offset: int, values: Mapping[str, npt.NDArray[np.float64]],
             bad: Mapping[str, npt.NDArray[np.bool_]]) -> dict[str, npt.NDArray[Any]] | None:
        """Check one chunk (canonical names) and return it in canonical units when clean."""
        tu, pu = self.time_unit, self.pressure_unit
        with np.errstate(invalid="ignore", over="ignore"):
            for canon, x in values.items():
                non_numeric = bad.get(canon)
                if non_numeric is not None and non_numeric.any():
                    self._note(canon, "text", non_numeric, offset,
                               lambda i: "non-numeric value; expected a number")
                    missing = np.isnan(x) & ~non_numeric
                else:
                    missing = np.isnan(x)
                self._note(canon, "nan", missing, offset,
                           lambda i: "missing value (empty cell or NaN); expected a finite number")
                self._note(canon, "inf", np.isinf(x), offset,
                           lambda i, x=x: f"infinite value ({x[i]}); expected a finite number")

            t = values["t"]
            if t.size:
                if self.rows == 0:
                    self.t_first = float(t[0])
                before = np.nan if self.t_prev is None else self.t_prev
                prev = np.concatenate(([before], t[:-1]))
                step = np.where(np.isfinite(t) & np.isfinite(prev), t - prev, np.nan)
                self._note("t", "dup", step == 0, offset,
                           lambda i: f"duplicated time stamp t = {t[i]:.10g} {tu}, the same as "
                           "the previous row; expected strictly increasing time")
                self._note("t", "back", step < 0, offset,
                           lambda i: f"time goes backwards: t = {t[i]:.10g} {tu} after "
                           f"{prev[i]:.10g} {tu} on the previous row; expected strictly "
                           "increasing time")
                self.t_prev = float(t[-1])

            p = values["p"]
            p_bar = _to_bar(p, pu)
            finite = np.isfinite(p)
            if finite.any():
                self.p_lo = min(self.p_lo, float(p[finite].min()))
                self.p_hi = max(self.p_hi, float(p[finite].max()))
            self._note("p", "range", finite & ((p_bar < P_MIN_BAR) | (p_bar > P_MAX_BAR)), offset,
                       lambda i: f"pressure {p[i]:.6g} {pu}"
                       + ("" if pu == "bar" else f" (= {p_bar[i]:.6g} bar)")
                       + f" is outside the plausible gauge range {P_MIN_BAR:g} to "
                       f"{P_MAX_BAR:g} bar")

            if "valve" in values:
                v = values["valve"]
                self._note("valve", "range", np.isfinite(v) & (v != 0) & (v != 1), offset,
                           lambda i: f"valve = {v[i]:.6g}; expected the command 0 or 1")
            if "u" in values:
                u = values["u"]
                self._note("u", "range", np.isfinite(u) & ((u < 0) | (u > 1)), offset,
                           lambda i: f"u = {u[i]:.6g} is outside [0, 1]; expected the input "
                           "fraction in [0, 1]")
        self.rows += len(t)
        if self.failed:
            return None
        out: dict[str, npt.NDArray[Any]] = {"t": _to_seconds(t, tu), "p": p_bar}
        if "valve" in values:
            out["valve"] = values["valve"].astype(np.int8)
        if "u" in values:
            out["u"] = values["u"]
        return out

    def problems(self, file: str | None, run: str | None) -> list[Problem]:
        out = []
        for (canon, check), tally in self.tallies.items():
            message = tally.detail
            if tally.count > 1:
                listed = ", ".join(str(r) for r in tally.rows)
                more = ", ..." if tally.count > len(tally.rows) else ""
                message += f" ({tally.count} rows in all: {listed}{more})"
            if (canon, check) == ("p", "range"):
                pu = self.pressure_unit
                message += f"; the column spans {self.p_lo:.6g} to {self.p_hi:.6g} {pu}"
                message += _unit_hint(self.p_lo, self.p_hi, pu)
            out.append(Problem(file, run, self.columns[canon], tally.rows[0], message))
        if self.rows < 2 and not out:
            out.append(Problem(file, run, None, None,
                               f"{self.rows} data row(s); a run needs at least 2 samples"))
        return out

    def warnings(self, file: str | None, run: str | None, kind: str) -> list[Problem]:
        out = []
        if self.failed or self.rows < 2:
            return out
        duration = _to_seconds(np.float64(self.t_prev - self.t_first), self.time_unit)
        rate = (self.rows - 1) / duration
        tcol = self.columns["t"]
        if rate < 5.0:
            out.append(Problem(file, run, tcol, None,
                               f"mean sample rate {rate:.3g} Hz is implausibly low for a valve "
                               "with ms delays; is time in ms? (set units: {time: ms})",
                               level="warning"))
        elif rate > 1e6:
            out.append(Problem(file, run, tcol, None,
                               f"mean sample rate {rate:.3g} Hz is implausibly high; "
                               f"is time really in {self.time_unit}?", level="warning"))
        peak = max(abs(_to_bar(self.p_lo, self.pressure_unit)),
                   abs(_to_bar(self.p_hi, self.pressure_unit)))
        if peak < 0.01 and kind != "pulse":  # short pulses may stay below 0.01 bar
            out.append(Problem(file, run, self.columns["p"], None,
                               f"pressure never exceeds {peak:.3g} bar in magnitude; are the "
                               f"units right (declared {self.pressure_unit})?", level="warning"))
        return out

    def summary(self, run: RunEntry) -> RunSummary:
        t0 = float(_to_seconds(np.float64(self.t_first), self.time_unit))
        t1 = float(_to_seconds(np.float64(self.t_prev), self.time_unit))
        return RunSummary(
            run=run.id, kind=run.kind, file=run.file, modulator=run.modulator,
            columns=tuple(c for c in CANONICAL_COLUMNS if c in self.columns),
            rows=self.rows, t_start=t0, t_end=t1,
            rate_hz=(self.rows - 1) / (t1 - t0) if t1 > t0 else math.nan,
            p_min=float(_to_bar(self.p_lo, self.pressure_unit)),
            p_max=float(_to_bar(self.p_hi, self.pressure_unit)),
        )


def _unit_hint(lo: float, hi: float, declared: str) -> str:
    """Name the pressure units that would put ``[lo, hi]`` in the plausible range, if any.

    Units giving a peak between 0.05 and 12 bar (what soft actuators see) come first, then
    by how common they are on benches: kPa, bar, mbar, psi.
    """
    fits = []
    for rank, unit in enumerate(("kPa", "bar", "mbar", "psi")):
        if unit == declared:
            continue
        lo_b, hi_b = float(_to_bar(lo, unit)), float(_to_bar(hi, unit))
        if P_MIN_BAR <= lo_b and hi_b <= P_MAX_BAR:
            typical = 0.05 <= max(abs(lo_b), abs(hi_b)) <= 12.0
            fits.append((not typical, rank, unit, f"{unit} ({lo_b:.4g} to {hi_b:.4g} bar)"))
    if not fits:
        return "; is it absolute pressure, or in Pa? spa expects gauge pressure"
    fits.sort()
    others = "".join(f"; or {text}" for *_, text in fits[1:])
    unit, text = fits[0][2], fits[0][3]
    return (
        f"; the values look like {text}{others}: set units: {{pressure: {unit}}} "
        f"in {SPEC_FILE}"
    )


# --------------------------------------------------------------------------- writing


def _sha256(path: Path) -> str:
    digest = hashlib.sha256()
    with path.open("rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


class _RunWriter:
    """Write a run table in fixed-size row groups, whatever the size of the chunks fed."""

    def __init__(self, path: Path, columns: tuple[str, ...], meta: bytes) -> None:
        self.path = path
        self.columns = columns
        self.schema = pa.schema(
            [pa.field(c, _ARROW_TYPES[c], nullable=False) for c in columns],
            metadata={META_KEY: meta},
        )
        path.parent.mkdir(parents=True, exist_ok=True)
        self.writer = pq.ParquetWriter(path, self.schema, **_WRITER_OPTIONS)
        self.pending: dict[str, list[npt.NDArray[Any]]] = {c: [] for c in columns}
        self.size = 0

    def add(self, arrays: Mapping[str, npt.NDArray[Any]]) -> None:
        for c in self.columns:
            self.pending[c].append(arrays[c])
        self.size += len(arrays["t"])
        if self.size >= _ROW_GROUP:
            self._flush(final=False)

    def _flush(self, final: bool) -> None:
        joined = {c: np.concatenate(v) if v else np.zeros(0) for c, v in self.pending.items()}
        start = 0
        while self.size - start >= _ROW_GROUP or (final and self.size > start):
            stop = min(start + _ROW_GROUP, self.size)
            table = pa.Table.from_arrays(
                [pa.array(joined[c][start:stop], type=_ARROW_TYPES[c]) for c in self.columns],
                schema=self.schema,
            )
            self.writer.write_table(table, row_group_size=_ROW_GROUP)
            start = stop
        self.pending = {c: [joined[c][start:]] for c in self.columns}
        self.size -= start

    def close(self) -> None:
        self._flush(final=True)
        self.writer.close()

    def abort(self) -> None:
        try:
            self.writer.close()
        finally:
            self.path.unlink(missing_ok=True)


def _meta_bytes(meta: Mapping[str, Any]) -> bytes:
    return json.dumps(
        meta, sort_keys=True, separators=(",", ":"), ensure_ascii=False, allow_nan=False
    ).encode("utf-8")


def _normalise_meta(meta: Mapping[str, Any], columns: tuple[str, ...]) -> dict[str, Any]:
    """Check a run table's metadata and fill in defaults; ``ValueError`` naming the key."""
    if not isinstance(meta, Mapping):
        raise ValueError(f"meta must be a mapping, got {type(meta).__name__}")
    try:
        out = json.loads(_meta_bytes(meta))  # a deep, JSON-only copy
    except (TypeError, ValueError) as exc:
        raise ValueError(f"meta must be JSON-serialisable with finite numbers: {exc}") from None
    out.setdefault("format", RUN_TABLE_FORMAT)
    if out["format"] != RUN_TABLE_FORMAT:
        raise ValueError(f"meta['format'] must be {RUN_TABLE_FORMAT!r}, got {out['format']!r}")
    for key in ("dataset", "run", "kind", "origin"):
        if not isinstance(out.get(key), str):
            raise ValueError(f"meta[{key!r}] is required and must be a string")
    if not _NAME_RE.fullmatch(out["dataset"]):
        raise ValueError(f"meta['dataset'] = {out['dataset']!r} must use letters, digits, '.', "
                         "'_' and '-'")
    if not _ID_RE.fullmatch(out["run"]):
        raise ValueError(f"meta['run'] = {out['run']!r} is not a filename-safe run id")
    if out["kind"] not in KINDS:
        raise ValueError(f"meta['kind'] = {out['kind']!r} is not one of {_one_of(KINDS)}")
    if out["origin"] not in ORIGINS:
        raise ValueError(f"meta['origin'] = {out['origin']!r} is not one of {_one_of(ORIGINS)}")
    modulator = out.get("modulator")
    if modulator is not None:
        full, problems = _check_modulator(modulator)
        if problems:
            raise ValueError(f"meta['modulator']: {'; '.join(problems)}")
        out["modulator"] = full
    elif out["kind"] in MODULATED_KINDS:
        raise ValueError(f"meta['modulator'] is required for a {out['kind']} run")
    else:
        out["modulator"] = None
    units = out.setdefault("units", {"time": "s", "pressure": "bar"})
    if (not isinstance(units, Mapping) or units.get("time") not in TIME_UNITS
            or units.get("pressure") not in PRESSURE_UNITS or len(units) != 2):
        raise ValueError(
            f"meta['units'] must be {{'time': one of {_one_of(TIME_UNITS)}, 'pressure': one of "
            f"{_one_of(PRESSURE_UNITS)}}} (the units converted from), got {units!r}"
        )
    source = out.setdefault("source", None)
    if source is not None and (
        not isinstance(source, Mapping)
        or not isinstance(source.get("file"), str)
        or not re.fullmatch(r"[0-9a-f]{64}", str(source.get("sha256", "")))
    ):
        raise ValueError(
            "meta['source'] must be None or {'file': <path relative to the dataset>, "
            f"'sha256': <64 hex digits>, ...}}, got {source!r}"
        )
    missing = [c for c in REQUIRED_COLUMNS[out["kind"]] if c not in columns]
    if missing:
        raise ValueError(f"a {out['kind']} run table needs column(s) {missing}")
    return out


def write_run_table(path: str | Path, table: pd.DataFrame, meta: Mapping[str, Any]) -> None:
    """Write one run in the canonical form (the only writer of run tables).

    Parameters
    ----------
    path : str or path-like
        Output ``.parquet`` file; written atomically (temporary file, then rename).
    table : pandas.DataFrame
        Columns ``t`` (s, strictly increasing), ``p`` (bar gauge), and optionally ``valve``
        (0/1) and ``u`` (in [0, 1]); no others. Any order and numeric dtype: they are written
        as float64, float64, int8 and float64 in the order ``t, p, valve, u``.
    meta : mapping
        JSON-serialisable description, stored under :data:`META_KEY`. Required: ``dataset``,
        ``run``, ``kind`` (one of :data:`KINDS`), ``origin`` (``bench`` or ``synthetic``),
        and ``modulator`` (``{"type": ..., settings}``) for staircase, sine and chirp runs.
        Defaults: ``units = {"time": "s", "pressure": "bar"}`` (the units converted from),
        ``source = None`` (else ``{"file", "sha256", ...}``), ``modulator = None``,
        ``format =`` :data:`RUN_TABLE_FORMAT`. Other keys are kept as they are.

    Raises
    ------
    ValueError
        For an unknown or missing column, values that break the contract (NaN, time not
        increasing, valve not 0/1, ...), or bad metadata; the message names the column or key.

    Notes
    -----
    The bytes depend only on the data and ``meta`` (sorted-key JSON, no time stamps, fixed
    row-group size), so equal inputs give identical files.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> df = pd.DataFrame({"t": [0.0, 0.001], "p": [0.0, 0.01], "valve": [1, 1]})
    >>> meta = {"dataset": "demo", "run": "c1", "kind": "charge", "origin": "synthetic"}
    >>> with tempfile.TemporaryDirectory() as tmp:
    ...     write_run_table(pathlib.Path(tmp) / "c1.parquet", df, meta)
    ...     back, info = read_run_table(pathlib.Path(tmp) / "c1.parquet")
    >>> back.dtypes.astype(str).tolist(), info["kind"]
    (['float64', 'float64', 'int8'], 'charge')
    """
    if not isinstance(table, pd.DataFrame):
        raise ValueError(f"table must be a pandas DataFrame, got {type(table).__name__}")
    names = [str(c) for c in table.columns]
    unknown = [c for c in names if c not in CANONICAL_COLUMNS]
    if unknown:
        raise ValueError(f"unknown column(s) {unknown}; a run table holds only "
                         f"{_one_of(CANONICAL_COLUMNS)}")
    if len(set(names)) != len(names):
        raise ValueError(f"duplicate column names in {names}")
    for c in ("t", "p"):
        if c not in names:
            raise ValueError(f"a run table needs column {c!r}")
    columns = tuple(c for c in CANONICAL_COLUMNS if c in names)
    values: dict[str, npt.NDArray[np.float64]] = {}
    for c in columns:
        try:
            values[c] = pd.to_numeric(table[c], errors="raise").to_numpy(
                dtype=np.float64, na_value=np.nan
            )
        except (TypeError, ValueError) as exc:
            raise ValueError(f"column {c!r} must hold numbers: {exc}") from None
    full_meta = _normalise_meta(meta, columns)
    check = _RunCheck({c: c for c in columns}, "s", "bar")
    canonical = check.feed(0, values, {})
    problems = check.problems(None, str(full_meta["run"]))
    if problems or canonical is None:
        lines = "\n  ".join(p.message if p.column is None else
                            f"column {p.column!r}, row {p.row}: {p.message}" for p in problems)
        raise ValueError(f"cannot write run table {path}:\n  {lines}")
    path = Path(path)
    tmp = path.with_name(f".{path.name}.tmp")
    writer = _RunWriter(tmp, columns, _meta_bytes(full_meta))
    try:
        for start in range(0, len(canonical["t"]), _ROW_GROUP):
            writer.add({c: v[start:start + _ROW_GROUP] for c, v in canonical.items()})
        writer.close()
    except BaseException:
        writer.abort()
        raise
    os.replace(tmp, path)


def read_run_meta(path: str | Path) -> dict[str, Any]:
    """Return the metadata of a run table without reading its data.

    Raises
    ------
    ValueError
        If the file is not a run table written by :func:`write_run_table`.
    """
    try:
        schema = pq.read_schema(path)
    except (pa.ArrowException, OSError) as exc:
        raise ValueError(f"{path}: not a readable Parquet file: {exc}") from None
    raw = (schema.metadata or {}).get(META_KEY)
    if raw is None:
        raise ValueError(f"{path}: not a spa run table (no {META_KEY!r} metadata)")
    return json.loads(raw)


def read_run_table(path: str | Path) -> tuple[pd.DataFrame, dict[str, Any]]:
    """Read a run table written by :func:`write_run_table` or :func:`ingest_dataset`.

    Returns
    -------
    table : pandas.DataFrame
        Columns ``t``, ``p`` and, when recorded, ``valve`` (int8) and ``u``.
    meta : dict
        The run's description (see :func:`write_run_table`).

    Raises
    ------
    ValueError
        If the file is not a run table.
    """
    meta = read_run_meta(path)
    table = pq.read_table(path)
    return table.to_pandas(), meta


# --------------------------------------------------------------------------- scanning


def _scan_run(parsed: _Parsed, run: RunEntry, out: Path | None) -> tuple[
        list[Problem], RunSummary | None]:
    """Check one run's file; with ``out``, also write its run table there (if clean)."""
    path = parsed.folder / run.file
    fmt = _FORMATS[PurePosixPath(run.file).suffix.lower()]
    what = {"csv": "column", "parquet": "column", "mat": "MATLAB variable"}[fmt]

    def problem(message: str, column: str | None = None, row: int | None = None,
                level: str = "error", line: int | None = None) -> Problem:
        return Problem(run.file, run.id, column, row, message, line=line, level=level)

    if path.stat().st_size == 0:
        return [problem("file is empty (0 bytes)")], None
    try:
        source = _SOURCES[fmt](path)
    except _ReadError as exc:
        return [problem(str(exc), exc.column, exc.row)], None

    problems: list[Problem] = []
    present: dict[str, str] = {}
    for canon in CANONICAL_COLUMNS:
        name = parsed.columns[canon]
        if name in source.columns:
            if source.columns.count(name) > 1:
                problems.append(problem(f"{what} {name!r} appears more than once", name))
            present[canon] = name
            continue
        mapped = "" if name == canon else f" (mapped from {canon!r} under columns:)"
        hint = (f"; the file has {_one_of(repr(c) for c in source.columns)}"
                f"{_suggest(name, source.columns)}; map names under columns: in {SPEC_FILE}")
        if canon in REQUIRED_COLUMNS[run.kind]:
            problems.append(problem(
                f"missing {what} {name!r}{mapped}: a {run.kind} run needs "
                f"{_QUANTITY[canon]} ({canon}){hint}", name))
        elif canon in RECOMMENDED_COLUMNS.get(run.kind, ()):
            problems.append(problem(
                f"no {what} {name!r}{mapped}: the valve command is recommended for "
                f"{run.kind} runs; ingesting without it", name, level="warning"))
    if any(p.is_error for p in problems):
        return problems, None
    names = list(present.values())
    check_types = getattr(source, "check_types", None)
    if check_types is not None:
        type_errors = check_types(names)
        if type_errors:
            return problems + [problem(str(e), e.column, e.row) for e in type_errors], None

    meta = None
    if out is not None:
        meta = _meta_bytes({
            "format": RUN_TABLE_FORMAT,
            "dataset": parsed.name,
            "description": parsed.description,
            "origin": parsed.origin,
            "rig": parsed.rig,
            "run": run.id,
            "kind": run.kind,
            "modulator": run.modulator,
            "notes": run.notes,
            "source": {"file": run.file, "sha256": _sha256(path), "format": fmt,
                       "columns": present},
            "units": {"time": parsed.time_unit, "pressure": parsed.pressure_unit},
        })
    rename = {v: k for k, v in present.items()}
    check = _RunCheck(present, parsed.time_unit, parsed.pressure_unit)

    def scan(as_text: bool) -> _RunCheck:
        nonlocal check
        check = _RunCheck(present, parsed.time_unit, parsed.pressure_unit)
        writer = None
        if out is not None:
            writer = _RunWriter(out, tuple(present), meta or b"")
        try:
            for offset, values, bad in source.chunks(names, as_text):
                clean = check.feed(offset, {rename[k]: v for k, v in values.items()},
                                   {rename[k]: v for k, v in bad.items()})
                if writer is not None:
                    if clean is None:
                        writer.abort()
                        writer = None
                    else:
                        writer.add(clean)
            if writer is not None:
                if check.rows >= 2:
                    writer.close()
                else:
                    writer.abort()
        except BaseException:
            if writer is not None:
                writer.abort()
            raise
        return check

    try:
        try:
            scan(as_text=False)
        except _Retry:
            scan(as_text=True)
    except _ReadError as exc:
        problems.append(problem(str(exc), exc.column, exc.row))
    except MemoryError:
        raise
    except Exception as exc:  # never a raw traceback for a bad file
        problems.append(problem(f"cannot read the file: {type(exc).__name__}: {exc}"))

    invalid = getattr(source, "invalid", [])
    for line, text, expected, actual in invalid[:_MAX_ROWS_LISTED]:
        more = f" ({len(invalid)} such lines in all)" if len(invalid) > 1 else ""
        problems.append(problem(
            f"malformed line: expected {expected} comma-separated fields, got {actual}: "
            f"{text[:80]!r} (truncated file? ';' separators or decimal commas?){more}",
            line=line,
        ))
    found = check.problems(run.file, run.id) + check.warnings(run.file, run.id, run.kind)
    line_of = getattr(source, "line_of", None)
    if line_of is not None:
        found = [replace(p, line=line_of(p.row)) for p in found]
    problems += found
    if any(p.is_error for p in problems):
        if out is not None:
            out.unlink(missing_ok=True)
        return problems, None
    return problems, check.summary(run)


def _scan_dataset(folder: Path, out_dir: Path | None) -> tuple[
        _Parsed, list[Problem], list[RunSummary], dict[str, Path]]:
    parsed = _parse_spec(folder)
    problems = list(parsed.problems)
    summaries: list[RunSummary] = []
    temps: dict[str, Path] = {}
    if not parsed.data_ok:
        return parsed, problems, summaries, temps
    writing = out_dir is not None and not parsed.has_errors
    for run in parsed.runs:
        tmp = out_dir / f".{run.id}.parquet.tmp" if writing and out_dir else None
        run_problems, summary = _scan_run(parsed, run, tmp)
        problems += run_problems
        if summary is not None:
            summaries.append(summary)
            if tmp is not None:
                temps[run.id] = tmp
    return parsed, problems, summaries, temps


def check_dataset(folder: str | Path) -> tuple[list[Problem], list[RunSummary]]:
    """Check a dataset folder against the contract and summarise its runs.

    Parameters
    ----------
    folder : str or path-like
        The dataset folder, ``raw/<name>``.

    Returns
    -------
    problems : list of Problem
        Every problem found (errors and warnings), description first, then run by run.
    summaries : list of RunSummary
        One per run whose data passed.
    """
    _, problems, summaries, _ = _scan_dataset(Path(folder), None)
    return problems, summaries


def validate_dataset(folder: str | Path) -> list[Problem]:
    """Check a dataset folder against the contract; return every problem found.

    Checks ``dataset.yaml`` (keys, with the closest valid key for a typo; kinds; modulator
    settings; units; column names; run ids; file paths, which must stay inside the folder)
    and every run's data (readable file; required columns; numbers only, no NaN or inf; time
    strictly increasing; valve in {0, 1}; u in [0, 1]; pressure within
    :data:`P_MIN_BAR` to :data:`P_MAX_BAR` bar gauge after unit conversion). Data are read in
    chunks, so any length of recording can be checked.

    Parameters
    ----------
    folder : str or path-like
        The dataset folder, ``raw/<name>``.

    Returns
    -------
    list of Problem
        Empty when the dataset is valid. Problems with ``level == "warning"`` (a staircase,
        sine or chirp run without a valve column; an implausible sample rate or tiny pressure
        range) do not make it invalid. A problem found on many rows is reported once, at its
        first row, with the number of rows and the first few row numbers.

    Examples
    --------
    >>> [str(p) for p in validate_dataset("/no/such/folder")]
    ['error: dataset folder: dataset folder /no/such/folder does not exist']
    """
    return check_dataset(folder)[0]


def ingest_dataset(folder: str | Path, out_dir: str | Path) -> list[Path]:
    """Validate a dataset and write one canonical run table per run.

    Parameters
    ----------
    folder : str or path-like
        The dataset folder, ``raw/<name>``; never written to.
    out_dir : str or path-like
        Where to write ``<run id>.parquet``; created if needed. Must not be the dataset
        folder, inside it, or the folder holding it (``raw/``).

    Returns
    -------
    list of pathlib.Path
        The run tables, in the order of ``runs:``.

    Raises
    ------
    DatasetError
        If the dataset has any error; nothing is written (earlier outputs are left alone).
    ValueError
        If ``out_dir`` is inside the dataset or its parent folder is ``raw/``.

    Notes
    -----
    Each run is checked and converted in one streaming pass: times to s, pressures to bar
    (factors in :data:`TIME_UNITS` and :data:`PRESSURE_UNITS`; units whose factor is the
    inverse of an integer are divided by it, so 250 kPa is exactly 2.5 bar). Each table is
    written to a hidden temporary file and renamed into place only once every run passed.
    The metadata hold the dataset name, description, origin and rig, the run id, kind,
    modulator and notes, the source file's relative path, format, column names and sha256,
    and the units converted from. Equal inputs give byte-identical outputs.
    """
    folder = Path(folder)
    out = Path(out_dir)
    root = folder.resolve()
    target = out.resolve()
    if target.is_relative_to(root) or target == root.parent:
        raise ValueError(
            f"out_dir {out} is inside the dataset folder {folder} or is its parent folder; "
            "ingest never writes into raw/"
        )
    parsed, problems, _, temps = _scan_dataset(folder, out)
    if any(p.is_error for p in problems):
        for tmp in temps.values():
            tmp.unlink(missing_ok=True)
        raise DatasetError(folder, problems)
    paths = []
    for run in parsed.runs:
        final = out / f"{run.id}.parquet"
        os.replace(temps[run.id], final)
        paths.append(final)
    return paths
