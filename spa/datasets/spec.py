"""``dataset.yaml``: its safe YAML loader, its parser (every problem at once) and the
parsed :class:`DatasetSpec`."""

from __future__ import annotations

import os
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path, PurePosixPath
from typing import Any

import yaml

from spa._docs import fill_doc
from spa.datasets.clock import SAMPLE_STEP_EXAMPLE, check_sample_step, check_valve_edges
from spa.datasets.contract import (
    _FORMATS,
    _ID_RE,
    _REQUIRED_TOP,
    _RUN_KEYS,
    _TOP_KEYS,
    CANONICAL_COLUMNS,
    KINDS,
    MODULATED_KINDS,
    PLAN_FILE,
    PLAN_WRITTEN,
    SPEC_FILE,
)
from spa.datasets.fields import (
    _check_controller,
    _check_modulator,
    _check_run_file,
    _description_problem,
    _name_problem,
    _origin_problem,
    _recorded_problem,
    _rig_problem,
    recorded_stamp,
)

# The dataset folders of raw/, importable from here as before.
from spa.datasets.folders import find_datasets as find_datasets
from spa.datasets.folders import undecodable_datasets as undecodable_datasets
from spa.datasets.options import check_columns, check_csv, check_units, csv_options
from spa.datasets.problems import DatasetError, Problem, _is_one_of, _one_of, _suggest, _unknown_key
from spa.datasets.yaml_loader import (
    MAX_SPEC_BYTES,
    _plain,
    _SpecTooComplex,
    _UniqueKeyLoader,
)
from spa.model.modulators import get_kind, kinds

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
    columns : dict
        Column name in the run's file for each canonical name: the dataset's ``columns:``
        overridden key by key by the run's; None for a column left out (``null``).
    units : dict
        ``{"time": unit, "pressure": unit}`` of the run's file: the dataset's ``units:``
        overridden key by key by the run's.
    csv : dict
        How to read the run's file when it is delimited text: every key of
        :data:`spa.datasets.options.CSV_DEFAULTS`, from the defaults (of its file ending),
        the dataset's ``csv:`` and the run's; empty for other formats.
    controller : dict or None
        A ``closed_loop`` run's PI: ``dt`` (its step, s) and the mapping of
        :meth:`spa.closedloop.controller.PIController.to_mapping` (``kp``, ``ki``, optional
        ``schedule`` and ``feedforward``); None for other kinds.
    sample_step : float or None
        The logging step in s (the run's ``sample_step:``, else the dataset's), or None: a
        run without a time column gets ``t = row index * sample_step``
        (:mod:`spa.datasets.clock`).
    valve_edges : str or None
        How the logged valve command relates to the log's clock, ``on_tick`` or
        ``sampled`` (the run's ``valve_edges:``, else the dataset's), or None (undeclared:
        the data decide).
    """

    id: str
    kind: str
    file: str
    modulator: dict[str, Any] | None = None
    notes: str | None = None
    columns: dict[str, str | None] = field(
        default_factory=lambda: {c: c for c in CANONICAL_COLUMNS}
    )
    units: dict[str, str] = field(default_factory=lambda: {"time": "s", "pressure": "bar"})
    csv: dict[str, Any] = field(default_factory=dict)
    controller: dict[str, Any] | None = None
    sample_step: float | None = None
    valve_edges: str | None = None

    @property
    def time_unit(self) -> str:
        """Unit of time in the run's file."""
        return self.units["time"]

    @property
    def pressure_unit(self) -> str:
        """Unit of pressure in the run's file."""
        return self.units["pressure"]


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
        Column name in the files for each canonical name in :data:`CANONICAL_COLUMNS`, None
        for one left out (a run may override it: see :attr:`RunEntry.columns`).
    csv : dict
        The dataset's ``csv:`` options, as written (runs hold the resolved ones).
    runs : tuple of RunEntry
        The runs, in file order.
    recorded : str or None
        When the session was recorded (``recorded:``): its day, ISO 8601 ``YYYY-MM-DD``,
        with the time ``THH:MM`` (UTC) when ``recorded:`` gives one; or None.
    sample_step, valve_edges : float or str or None
        The dataset's ``sample_step:`` (s) and ``valve_edges:``, or None (runs hold the
        resolved ones: :class:`RunEntry`).
    """

    folder: Path
    name: str
    description: str
    origin: str
    rig: dict[str, Any]
    time_unit: str
    pressure_unit: str
    columns: dict[str, str | None]
    runs: tuple[RunEntry, ...]
    csv: dict[str, Any] = field(default_factory=dict)
    recorded: str | None = None
    sample_step: float | None = None
    valve_edges: str | None = None

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
    columns: dict[str, str | None] = field(
        default_factory=lambda: {c: c for c in CANONICAL_COLUMNS}
    )
    csv: dict[str, Any] = field(default_factory=dict)
    runs: list[RunEntry] = field(default_factory=list)
    recorded: str | None = None
    sample_step: float | None = None
    valve_edges: str | None = None
    data_ok: bool = True  # units and columns are usable for checking the data

    def error(
        self,
        message: str,
        *,
        key: str | None = None,
        run: str | None = None,
        file: str | None = SPEC_FILE,
        level: str = "error",
    ) -> None:
        self.problems.append(Problem(file, run, None, None, message, key=key, level=level))

    @property
    def has_errors(self) -> bool:
        return any(p.is_error for p in self.problems)


def _parse_spec(folder: Path) -> _Parsed:
    parsed = _Parsed(folder=folder)
    if not folder.exists():
        parsed.error(f"dataset folder {folder} does not exist", file=None)
        parsed.data_ok = False
        return parsed
    if not folder.is_dir():
        parsed.error(
            f"{folder} is not a folder; a dataset is a folder holding {SPEC_FILE}", file=None
        )
        parsed.data_ok = False
        return parsed
    spec_path = folder / SPEC_FILE
    if not spec_path.is_file():
        parsed.error(f"missing {SPEC_FILE}: every dataset folder needs one (see raw/README.md)")
        parsed.data_ok = False
        return parsed
    size = spec_path.stat().st_size
    if size > MAX_SPEC_BYTES:
        parsed.error(
            f"{SPEC_FILE} is {size} bytes; a description is at most {MAX_SPEC_BYTES} bytes "
            "(the data go in the run files)"
        )
        parsed.data_ok = False
        return parsed
    try:
        doc = yaml.load(spec_path.read_text(encoding="utf-8"), Loader=_UniqueKeyLoader)
    except _SpecTooComplex as exc:
        parsed.error(f"{SPEC_FILE} is too complex to be a dataset description: {exc}")
        parsed.data_ok = False
        return parsed
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

    here = Path(os.path.abspath(folder)).name  # "spa validate ." names the folder too
    _top_value(parsed, doc, "name", lambda name: _name_problem(name, here))
    _top_value(parsed, doc, "description", _description_problem, str.strip)
    _top_value(parsed, doc, "origin", _origin_problem)
    _top_value(parsed, doc, "rig", _rig_problem, _plain)
    _top_value(parsed, doc, "recorded", _recorded_problem, recorded_stamp)
    _top_value(parsed, doc, "sample_step", lambda v: check_sample_step(v)[1], float)
    _top_value(parsed, doc, "valve_edges", lambda v: check_valve_edges(v)[1], str)
    if any(p.key == "sample_step" for p in parsed.problems):
        parsed.data_ok = False  # the runs' time is unknown

    _parse_options(parsed, doc)
    if "runs" in doc:
        _parse_runs(parsed, doc["runs"])
        _warn_unnamed(parsed, doc["runs"])
    return parsed


#: Files a file manager or an office program leaves behind: never worth a warning.
_JUNK = ("Thumbs.db", "desktop.ini", "Icon\r")


def _warn_unnamed(parsed: _Parsed, runs: Any) -> None:
    """One warning listing the files of the folder that ``dataset.yaml`` does not name.

    They are ignored (not read, not digested: :func:`spa.pipeline.provenance.file_digests`); hidden
    files, the droppings of file managers and office programs, and in a planned session's
    folder the files spa wrote there (:data:`spa.datasets.contract.PLAN_WRITTEN`) are not
    listed.
    """
    named = {SPEC_FILE}
    if isinstance(runs, list):
        named |= {str(r.get("file")) for r in runs if isinstance(r, Mapping)}
    spa_wrote: tuple[str, ...] = ()
    if (Path(parsed.folder) / PLAN_FILE).is_file():  # a planned session: spa's own files
        spa_wrote = PLAN_WRITTEN
    spa_folders = tuple(w for w in spa_wrote if w.endswith("/"))
    stray = []
    for dirpath, dirnames, filenames in os.walk(parsed.folder):
        dirnames[:] = sorted(d for d in dirnames if not d.startswith("."))
        for name in sorted(filenames):
            if name.startswith((".", "~$")) or name in _JUNK:
                continue
            rel = (Path(dirpath) / name).relative_to(parsed.folder).as_posix()
            if rel in spa_wrote or rel.startswith(spa_folders):
                continue
            if rel not in named:
                stray.append(os.fsencode(rel).decode("utf-8", "backslashreplace"))
    if stray:
        more = f" and {len(stray) - 5} more" if len(stray) > 5 else ""
        parsed.error(
            f"{len(stray)} file(s) of the folder that no run names are ignored: "
            f"{', '.join(stray[:5])}{more}",
            level="warning",
        )


def _top_value(
    parsed: _Parsed,
    doc: Mapping[str, Any],
    key: str,
    problem: Callable[[Any], str | None],
    value: Callable[[Any], Any] = lambda v: v,
) -> None:
    """Set ``parsed.<key>`` to ``value(doc[key])``, or record its problem under ``key``.

    Parameters
    ----------
    parsed : _Parsed
        What is parsed so far.
    doc : mapping
        The top level of ``dataset.yaml``; nothing happens when it lacks ``key``.
    key : str
        The optional top-level key, also the attribute of ``parsed``.
    problem : callable
        The given value to the message of its problem, or None when it is valid.
    value : callable, optional
        The valid given value to what ``parsed`` keeps; the value itself by default.
    """
    if key not in doc:
        return
    given = doc[key]
    message = problem(given)
    if message is None:
        setattr(parsed, key, value(given))
    else:
        parsed.error(message, key=key)


def _parse_options(parsed: _Parsed, doc: Mapping[str, Any]) -> None:
    """The dataset-level ``units:``, ``columns:`` and ``csv:``, which runs inherit."""
    units, found = check_units(
        doc.get("units"), {"time": parsed.time_unit, "pressure": parsed.pressure_unit}, "units"
    )
    parsed.time_unit, parsed.pressure_unit = units["time"], units["pressure"]
    columns, more = check_columns(doc.get("columns"), parsed.columns, "columns")
    parsed.columns = columns
    parsed.csv, csv_found = check_csv(doc.get("csv"), {}, "csv")
    for key, message in found + more + csv_found:
        parsed.error(message, key=key)
    if found or more or csv_found:
        parsed.data_ok = False


def _sub_entry(
    entry: Mapping[str, Any],
    name: str,
    check: Callable[[Any], tuple[Any, list[str]]],
    err: Callable[[str, str], None],
    needed: bool,
    missing: str,
) -> Any:
    """A run's optional sub-mapping ``entry[name]`` checked by ``check`` (its problems given
    to ``err`` under ``name``), or None; when absent and ``needed``, ``missing`` is the error."""
    if entry.get(name) is not None:
        value, problems = check(entry[name])
        for message in problems:
            err(message, name)
        return value
    if needed:
        err(missing, name)
    return None


def _parse_runs(parsed: _Parsed, runs: Any) -> None:
    if not isinstance(runs, list):
        parsed.error(
            f"runs must be a list of {{id, kind, file, ...}} entries, got {runs!r}", key="runs"
        )
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

        def err(
            message: str, sub: str | None = None, _label: str | None = label, _key: str = key
        ) -> None:
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
            err(
                f"unknown kind {kind!r}; expected one of {_one_of(KINDS)}{_suggest(kind, KINDS)}",
                "kind",
            )
        modulator = _sub_entry(
            entry,
            "modulator",
            _check_modulator,
            err,
            _is_one_of(kind, MODULATED_KINDS),
            f"a {kind} run needs a modulator, one of "
            + ", ".join(get_kind(k).example() for k in kinds()),
        )
        controller = _sub_entry(
            entry,
            "controller",
            _check_controller,
            err,
            kind == "closed_loop",
            "a closed_loop run needs its controller, e.g. {kp: 4.0, ki: 4.5, dt: 0.001} "
            "(gains in 1/bar and 1/(bar*s), step in s)",
        )
        notes = entry.get("notes")
        if notes is not None and not isinstance(notes, str):
            err(f"notes must be text, got {notes!r}", "notes")
        rel = None
        if "file" in entry:
            rel, message = _check_run_file(parsed.folder, entry["file"])
            if message:
                err(message, "file")
        columns, found = check_columns(entry.get("columns"), parsed.columns, f"{key}.columns")
        units, more = check_units(
            entry.get("units"),
            {"time": parsed.time_unit, "pressure": parsed.pressure_unit},
            f"{key}.units",
        )
        options, csv_found = check_csv(entry.get("csv"), parsed.csv, f"{key}.csv")
        for where, message in found + more + csv_found:
            parsed.error(message, key=where, run=label)
        sample_step, valve_edges = _clock(entry, parsed, columns, err)
        if len(parsed.problems) == before and rel is not None:
            suffix = PurePosixPath(rel).suffix.lower()
            delimited = _FORMATS[suffix] == "csv"
            options = csv_options(options, suffix) if delimited else {}
            parsed.runs.append(
                RunEntry(
                    rid,
                    kind,
                    rel,
                    modulator,
                    notes,
                    columns,
                    units,
                    options,
                    controller=controller,
                    sample_step=sample_step,
                    valve_edges=valve_edges,
                )
            )


def _clock(
    entry: Mapping[str, Any],
    parsed: _Parsed,
    columns: Mapping[str, str | None],
    err: Callable[[str, str], None],
) -> tuple[float | None, str | None]:
    """A run's ``sample_step`` and ``valve_edges``: its own, else the dataset's; a time
    column left out (``t: null``) without a step is a problem."""
    step, edges = parsed.sample_step, parsed.valve_edges
    if entry.get("sample_step") is not None:
        step, message = check_sample_step(entry["sample_step"])
        if message:
            err(message, "sample_step")
    if entry.get("valve_edges") is not None:
        edges, message = check_valve_edges(entry["valve_edges"])
        if message:
            err(message, "valve_edges")
    if columns["t"] is None and step is None and "sample_step" not in entry:
        if not any(p.key == "sample_step" for p in parsed.problems):
            err(
                "columns: leaves out t (null), so the run has no time stamps: add its logging "
                f"step, {SAMPLE_STEP_EXAMPLE}, to the run or the dataset",
                "sample_step",
            )
    return step, edges


@fill_doc
def load_spec(folder: str | Path) -> DatasetSpec:
    """Read and check ``dataset.yaml`` of a dataset folder, ``raw/<name>`` (only that file:
    the data are checked by :func:`spa.datasets.check_dataset`).

    Parameters
    ----------
    %(dataset_folder)s

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
        csv=dict(parsed.csv),
        recorded=parsed.recorded,
        sample_step=parsed.sample_step,
        valve_edges=parsed.valve_edges,
    )
