"""The canonical run table: write (Parquet with JSON metadata under ``b"spa"``) and read back."""

from __future__ import annotations

import hashlib
import json
import os
import re
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq

from spa.datasets.checks import _RunCheck
from spa.datasets.clock import check_sample_step, check_valve_edges
from spa.datasets.contract import (
    _ARROW_TYPES,
    _ID_RE,
    _NAME_RE,
    CANONICAL_COLUMNS,
    KINDS,
    META_KEY,
    MODULATED_KINDS,
    ORIGINS,
    PRESSURE_UNITS,
    REQUIRED_COLUMNS,
    RUN_TABLE_FORMAT,
    TIME_UNITS,
)
from spa.datasets.fields import _check_modulator
from spa.datasets.problems import _one_of

_ROW_GROUP = 1 << 20  # rows per row group of a run table


_WRITER_OPTIONS: dict[str, Any] = {
    "version": "2.6",
    "compression": "zstd",
    "compression_level": 3,
    "use_dictionary": ["valve"],
    "write_statistics": True,
}


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
        raise ValueError(
            f"meta['dataset'] = {out['dataset']!r} must use letters, digits, '.', '_' and '-'"
        )
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
    if out["kind"] == "closed_loop" and not isinstance(out.get("controller"), Mapping):
        raise ValueError("meta['controller'] is required for a closed_loop run (kp, ki, dt)")
    for key, check in (("sample_step", check_sample_step), ("valve_edges", check_valve_edges)):
        if out.get(key) is not None and check(out[key])[1] is not None:
            raise ValueError(f"meta[{key!r}]: {check(out[key])[1]}")
    units = out.setdefault("units", {"time": "s", "pressure": "bar"})
    if (
        not isinstance(units, Mapping)
        or units.get("time") not in TIME_UNITS
        or units.get("pressure") not in PRESSURE_UNITS
        or len(units) != 2
    ):
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
        ``format =`` :data:`RUN_TABLE_FORMAT`. Optional, checked when given: ``sample_step``
        (s: the run's ``t`` was made as row index times it) and ``valve_edges``
        (``on_tick`` or ``sampled``: :mod:`spa.datasets.clock`). Other keys are kept as they
        are.

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
        raise ValueError(
            f"unknown column(s) {unknown}; a run table holds only {_one_of(CANONICAL_COLUMNS)}"
        )
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
        lines = "\n  ".join(
            p.message if p.column is None else f"column {p.column!r}, row {p.row}: {p.message}"
            for p in problems
        )
        raise ValueError(f"cannot write run table {path}:\n  {lines}")
    path = Path(path)
    tmp = path.with_name(f".{path.name}.tmp")
    writer = _RunWriter(tmp, columns, _meta_bytes(full_meta))
    try:
        for start in range(0, len(canonical["t"]), _ROW_GROUP):
            writer.add({c: v[start : start + _ROW_GROUP] for c, v in canonical.items()})
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


def read_runs(run_dir: str | Path) -> tuple[dict[str, pd.DataFrame], dict[str, dict[str, Any]]]:
    """Read every run table of a dataset's ``runs/`` folder, in run-id order.

    Returns
    -------
    runs : dict
        Run id → canonical table (``t``, ``p``, ``valve``, ``u``).
    metas : dict
        Run id → the run's metadata (``kind``, ``modulator``, ...); ``modulator`` is a
        :class:`~spa.model.modulators.Modulator` (parsed here, once) or None.
    """
    from spa.model.modulators import Modulator

    runs: dict[str, pd.DataFrame] = {}
    metas: dict[str, dict[str, Any]] = {}
    for path in sorted(Path(run_dir).glob("*.parquet")):
        table, meta = read_run_table(path)
        if meta.get("modulator") is not None:
            meta["modulator"] = Modulator.from_mapping(meta["modulator"])
        runs[meta["run"]] = table
        metas[meta["run"]] = meta
    if not runs:
        raise ValueError(f"{run_dir}: no run tables (*.parquet) found")
    return runs, metas
