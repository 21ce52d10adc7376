"""Validate a dataset folder and ingest it into canonical run tables (one streaming pass
per run)."""

from __future__ import annotations

import os
from dataclasses import replace
from pathlib import Path, PurePosixPath
from typing import Any

from spa._docs import fill_doc
from spa._progress import progress
from spa.datasets.checks import RunSummary, _RunCheck, supply_warning
from spa.datasets.clock import INDEX_TIME, SAMPLE_STEP_EXAMPLE, index_time, step_problem
from spa.datasets.contract import (
    _FORMATS,
    _MAX_ROWS_LISTED,
    _QUANTITY,
    CANONICAL_COLUMNS,
    RECOMMENDED_COLUMNS,
    REQUIRED_COLUMNS,
    RUN_TABLE_FORMAT,
    SPEC_FILE,
    unit_in_name,
)
from spa.datasets.options import csv_options
from spa.datasets.problems import DatasetError, Problem
from spa.datasets.readers import READERS
from spa.datasets.readers.base import _ReadError, _Retry
from spa.datasets.readers.sniff import csv_hint
from spa.datasets.runtable import _meta_bytes, _RunWriter, _sha256
from spa.datasets.spec import RunEntry, _parse_spec, _Parsed
from spa.errors import ENVIRONMENT_ERRNOS

# --------------------------------------------------------------------------- scanning


class _Hint:
    """The sniffed layout of a delimited file where it differs from its options, told once
    per run (computed on first use): ``""`` for other formats or when nothing differs."""

    def __init__(self, path: Path, options: dict[str, Any] | None) -> None:
        self.path = path
        self.options = options
        self.given = False

    def __call__(self) -> str:
        if self.options is None or self.given:
            return ""
        self.given = True
        return csv_hint(self.path, self.options)


def _reading(problem: Problem) -> bool:
    """True for the errors that reading with wrong ``csv:`` options gives."""
    return problem.is_error and problem.message.startswith(
        ("non-numeric value", "malformed line", "cannot parse", "line ")
    )


def _scan_run(
    parsed: _Parsed, run: RunEntry, out: Path | None
) -> tuple[list[Problem], RunSummary | None]:
    """Check one run's file; with ``out``, also write its run table there (if clean)."""
    path = parsed.folder / run.file
    fmt = _FORMATS[PurePosixPath(run.file).suffix.lower()]
    hint = _Hint(path, run.csv if fmt == "csv" else None)

    def problem(
        message: str,
        column: str | None = None,
        row: int | None = None,
        level: str = "error",
        line: int | None = None,
    ) -> Problem:
        return Problem(run.file, run.id, column, row, message, line=line, level=level)

    if path.stat().st_size == 0:
        return [problem("file is empty (0 bytes)")], None
    try:
        source = READERS[fmt](path, run.csv)
    except _ReadError as exc:
        return [problem(f"{exc}{hint()}", exc.column, exc.row)], None

    what = source.what  # a MATLAB file may hold a dSpace recording
    problems: list[Problem] = []
    present: dict[str, str] = {}
    index_t = False  # t is made from sample_step: the log has no time stamps
    for canon in CANONICAL_COLUMNS:
        name = run.columns[canon]
        if name is None and canon == "t" and run.sample_step is not None:
            index_t = True
            continue
        if name is None:  # left out under columns: (null)
            if canon in REQUIRED_COLUMNS[run.kind]:
                problems.append(problem(_left_out(run.kind, canon)))
            continue
        try:
            found = source.resolve(name) is not None  # more names than columns: MATLAB
        except _ReadError as exc:
            problems.append(problem(str(exc), name))
            continue
        if found:
            if source.columns.count(name) > 1:
                problems.append(problem(f"{what} {name!r} appears more than once", name))
            present[canon] = name
            continue
        if canon == "t" and name == canon and run.sample_step is not None:
            index_t = True  # t not mapped and not in the file: a log without time stamps
            continue
        mapped = "" if name == canon else f" (mapped from {canon!r} under columns:)"
        hint_names = f"{source.describe(name)}; map names under columns: in {SPEC_FILE}"
        if canon == "t":
            hint_names += (
                "; a log without time stamps declares its logging step instead: "
                f"columns: {{t: null}} and {SAMPLE_STEP_EXAMPLE}"
            )
        if canon in REQUIRED_COLUMNS[run.kind]:
            problems.append(
                problem(
                    f"missing {what} {name!r}{mapped}: a {run.kind} run needs "
                    f"{_QUANTITY[canon]} ({canon}){hint_names}{hint()}",
                    name,
                )
            )
        elif canon in RECOMMENDED_COLUMNS.get(run.kind, ()):
            problems.append(
                problem(
                    f"no {what} {name!r}{mapped}: the valve command is recommended for "
                    f"{run.kind} runs; ingesting without it",
                    name,
                    level="warning",
                )
            )
    if any(p.is_error for p in problems):
        return problems, None
    names = list(present.values())
    type_errors = source.check_types(names)
    if type_errors:
        return problems + [problem(str(e), e.column, e.row) for e in type_errors], None

    meta = None
    if out is not None:
        info = {
            "format": RUN_TABLE_FORMAT,
            "dataset": parsed.name,
            "description": parsed.description,
            "origin": parsed.origin,
            "rig": parsed.rig,
            "run": run.id,
            "kind": run.kind,
            "modulator": run.modulator,
            **({"controller": run.controller} if run.controller is not None else {}),
            "notes": run.notes,
            "source": {
                "file": run.file,
                "sha256": _sha256(path),
                "format": fmt,
                "columns": {  # as found in the file (a dSpace short name resolved)
                    k: source.resolve(v) for k, v in present.items()
                },
            },
            "units": dict(run.units),
            **({"sample_step": run.sample_step} if index_t else {}),
            **({"valve_edges": run.valve_edges} if run.valve_edges is not None else {}),
        }
        if fmt == "csv" and run.csv != csv_options({}, path.suffix):
            info["source"]["csv"] = run.csv  # how the text was read, when not the default
        meta = _meta_bytes(info)
    rename = {v: k for k, v in present.items()}
    columns = {"t": INDEX_TIME, **present} if index_t else present
    time_unit = "s" if index_t else run.time_unit  # sample_step is in s
    check = _RunCheck(columns, time_unit, run.pressure_unit)

    def scan(as_text: bool) -> _RunCheck:
        nonlocal check
        check = _RunCheck(columns, time_unit, run.pressure_unit)
        writer = None
        if out is not None:
            writer = _RunWriter(out, tuple(columns), meta or b"")
        try:
            blocks = progress(source.chunks(names, as_text), f"reading {run.file}", unit="block")
            for offset, values, bad in blocks:
                named = {rename[k]: v for k, v in values.items()}
                if index_t and run.sample_step is not None:
                    named["t"] = index_time(offset, len(named["p"]), run.sample_step)
                clean = check.feed(offset, named, {rename[k]: v for k, v in bad.items()})
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
        if isinstance(exc, OSError) and exc.errno in ENVIRONMENT_ERRNOS:
            raise  # a full disk is not the recording's fault
        problems.append(problem(f"cannot read the file: {type(exc).__name__}: {exc}"))

    invalid = source.invalid
    sep = {",": "comma", "\t": "tab", " ": "blank", ";": "semicolon"}
    sep_name = sep.get(source.sep, repr(source.sep))  # type: ignore[call-overload]
    for line, text, expected, actual in invalid[:_MAX_ROWS_LISTED]:
        more = f" ({len(invalid)} such lines in all)" if len(invalid) > 1 else ""
        problems.append(
            problem(
                f"malformed line: expected {expected} {sep_name}-separated fields, got {actual}: "
                f"{text[:80]!r} (truncated file? other separators or decimal commas?){more}",
                line=line,
            )
        )
    found = check.problems(run.file, run.id) + check.kind_problems(run.file, run.id, run.kind)
    found += _step_problems(run, check, index_t)
    found += check.warnings(run.file, run.id, run.kind)
    found = [replace(p, line=source.line_of(p.row)) if p.line is None else p for p in found]
    problems += found
    first = next((i for i, p in enumerate(problems) if _reading(p)), None)
    if first is not None and not hint.given:
        problems[first] = replace(problems[first], message=problems[first].message + hint())
    if any(p.is_error for p in problems):
        if out is not None:
            out.unlink(missing_ok=True)
        return problems, None
    return problems, check.summary(run)


def _step_problems(run: RunEntry, check: _RunCheck, index_t: bool) -> list[Problem]:
    """An error when a run has both a time column and ``sample_step``, and the column's
    median step disagrees with it (:func:`spa.datasets.clock.step_problem`)."""
    if index_t or run.sample_step is None or check.failed or check.rows < 2:
        return []
    column = check.columns["t"]
    message = step_problem(check.median_step(), run.sample_step, column)
    if message is None:
        return []
    return [Problem(run.file, run.id, column, None, message)]


def _left_out(kind: str, canon: str) -> str:
    """The error for a column a run's kind needs that ``columns:`` leaves out (null)."""
    message = (
        f"columns: leaves out {canon} (null), but a {kind} run needs {_QUANTITY[canon]} "
        f"({canon}); name its column"
    )
    if canon == "u":  # a log of the valve command alone
        message += (
            "; a log of the 0/1 valve command alone serves as a pulse run (kind: pulse), "
            "which identifies the delays"
        )
    return message


def _scan_dataset(
    folder: Path, out_dir: Path | None, supply: tuple[float, float] | None = None
) -> tuple[_Parsed, list[Problem], list[RunSummary], dict[str, Path]]:
    parsed = _parse_spec(folder)
    problems = list(parsed.problems)
    summaries: list[RunSummary] = []
    temps: dict[str, Path] = {}
    if not parsed.data_ok:
        return parsed, problems, summaries, temps
    writing = out_dir is not None and not parsed.has_errors
    for run in progress(parsed.runs, f"ingesting {parsed.name or folder.name}"):
        tmp = out_dir / f".{run.id}.parquet.tmp" if writing and out_dir else None
        run_problems, summary = _scan_run(parsed, run, tmp)
        problems += run_problems
        if summary is not None:
            summaries.append(summary)
            if tmp is not None:
                temps[run.id] = tmp
    problems += _supply_problems(parsed, summaries, supply, problems)
    return parsed, problems, summaries, temps


def _supply_problems(
    parsed: _Parsed,
    summaries: list[RunSummary],
    supply: tuple[float, float] | None,
    found: list[Problem],
) -> list[Problem]:
    """A warning when the charge runs' highest pressure, their plateau, is no plausible
    supply pressure, or is much likelier in another unit than the one declared (unless the
    column's name states that unit: :func:`supply_warning`; and unless its run already has
    a warning about its pressure, from the data checks)."""
    charges = [s for s in summaries if s.kind == "charge"]
    if not charges:
        return []
    top = max(charges, key=lambda s: s.p_max)
    if any(p.run == top.run and not p.is_error and "pressure" in p.message for p in found):
        return []
    run = parsed.runs[[r.id for r in parsed.runs].index(top.run)]
    what = f"the charge runs' plateau (highest pressure, run {top.run!r})"
    named = unit_in_name(run.columns["p"]) == run.pressure_unit  # "P_kPa" declared kPa
    message = supply_warning(top.p_max, what, run.pressure_unit, supply, likelier=not named)
    if message is None:
        return []
    return [Problem(top.file, top.run, run.columns["p"], None, message, level="warning")]


@fill_doc
def check_dataset(folder: str | Path) -> tuple[list[Problem], list[RunSummary]]:
    """Check a dataset folder against the contract and summarise its runs.

    Parameters
    ----------
    %(dataset_folder)s

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
    chunks, so any length of recording can be checked. ``folder`` is as for
    :func:`check_dataset`, which also summarises the runs.

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


def ingest_dataset(
    folder: str | Path,
    out_dir: str | Path,
    warnings: list[Problem] | None = None,
    supply: tuple[float, float] | None = None,
) -> list[Path]:
    """Validate a dataset and write one canonical run table per run.

    Parameters
    ----------
    folder : str or path-like
        The dataset folder, ``raw/<name>``; never written to.
    out_dir : str or path-like
        Where to write ``<run id>.parquet``; created if needed. Must not be the dataset
        folder, inside it, or the folder holding it (``raw/``).
    warnings : list, optional
        When given, the warnings found (problems that do not stop the ingest, e.g. an
        implausible sample rate) are appended to it, for the caller to log.
    supply : (float, float), optional
        Plausible supply pressure in bar (config ``datasets.plausible_supply_bar``; default
        :data:`~spa.datasets.contract.PLAUSIBLE_SUPPLY_BAR`): a charge run whose highest
        pressure is outside it is a warning naming the likely unit mistake.

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
    _check_writable(out)
    parsed, problems, _, temps = _scan_dataset(folder, out, supply)
    if any(p.is_error for p in problems):
        for tmp in temps.values():
            tmp.unlink(missing_ok=True)
        raise DatasetError(folder, problems)
    if warnings is not None:
        warnings.extend(p for p in problems if not p.is_error)
    paths = []
    for run in parsed.runs:
        final = out / f"{run.id}.parquet"
        os.replace(temps[run.id], final)
        paths.append(final)
    return paths


def _check_writable(out: Path) -> None:
    """Refuse an output folder that cannot be written, before any recording is read.

    Raises
    ------
    OSError
        Naming the folder (with the system's reason), so that a read-only or full results
        folder is never taken for unreadable recordings.
    """
    try:
        out.mkdir(parents=True, exist_ok=True)
        probe = out / f".spa-write-check.{os.getpid()}"
        probe.write_bytes(b"")
        probe.unlink()
    except OSError as exc:
        raise type(exc)(
            exc.errno,
            f"the output folder is not writable ({exc.strerror}); the recordings were not read",
            str(out),
        ) from None
