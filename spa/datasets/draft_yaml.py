"""``spa init``: read every data file of a dataset folder and draft its ``dataset.yaml``.

The guesses come from :mod:`spa.datasets.draft`; this module reads the files (through the
readers of :mod:`spa.datasets.readers`, so every format they know is drafted), pools what the
files share (units, column names, file options) at the dataset level, and writes YAML text
with the reason of every guess as a comment and ``TODO`` where a guess failed (a value the
parser rejects, so ``spa validate`` lists it).

Each file is read whole (its numeric columns as float64: 8 bytes per value), once: drafting
an hour at 10 kHz with four columns takes about 1.2 GB; ``spa validate`` and ``spa ingest``
then read in blocks.

Writing ``<folder>/dataset.yaml`` is the one write into ``raw/`` the project allows, and
only when that file does not exist (or with ``force``). Data files are only read.
"""

from __future__ import annotations

import re
import textwrap
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path, PurePosixPath
from typing import Any

import numpy as np
import numpy.typing as npt
import yaml

from spa._docs import fill_doc
from spa.datasets.contract import _FORMATS, _ID_RE, MODULATED_KINDS, SPEC_FILE
from spa.datasets.draft import (
    Guess,
    guess_kind,
    guess_modulator,
    guess_pressure_unit,
    guess_roles,
    guess_time_unit,
)
from spa.datasets.readers import READERS
from spa.datasets.readers.base import Source, _ReadError, _Retry
from spa.datasets.recorded import session_date
from spa.datasets.yaml_loader import _UniqueKeyLoader
from spa.io import dump_yaml

__all__ = ["FileDraft", "draft_dataset", "draft_files", "write_draft"]

#: Marker written where a guess failed; every place it goes, the parser rejects it.
TODO = "TODO"

_MAX_DEPTH = 2  # sub-folder levels searched for data files

_ROLES = ("t", "p", "valve", "u", "r")

#: The reason given for a time unit when the files have no time column.
NO_TIME = "no time column"

#: The line drafted for a log without time stamps (its value a ``TODO``).
_SAMPLE_STEP_TODO = (
    f"sample_step: {TODO}  # no time column: the logging step in s (e.g. 0.02 for 50 Hz)"
)

#: The comment drafted when the files log a valve command: what ``valve_edges`` declares.
_VALVE_EDGES_NOTE = (
    "# valve_edges: on_tick  # or sampled; how the logged valve command relates to the log's "
    "clock: on_tick, the controller issued every command on a logging tick (it logs itself: "
    "dSpace, an Arduino loop), so a logged edge is the true edge time; sampled, the command "
    "ran on its own faster clock and the log samples it, so a true edge lies within the step "
    "before the sample that shows it. Left out, the data decide"
)

#: The kind of a run with a set-point column, and what its draft asks for.
CLOSED_LOOP = "closed_loop"
_CONTROLLER_TODO = (
    "the PI that ran, not in the data: {kp: <1/bar>, ki: <1/(bar s)>, dt: <s>} "
    "(raw/README.md, controller)"
)


@dataclass
class FileDraft:
    """What was read and guessed of one data file.

    Attributes
    ----------
    file : str
        Path relative to the dataset folder, ``/`` as separator.
    id : str
        Run id (the file's stem, made filename-safe and unique).
    options : dict
        File options detected (e.g. a CSV separator); empty when none.
    roles : dict of str to Guess
        File column for ``t``, ``p``, ``valve`` and ``u``.
    error : str or None
        Why the file could not be read.
    data : dict of str to numpy.ndarray
        The numeric columns (dropped once the guesses are made).
    kind : Guess
        Kind of run.
    modulator : Guess or None
        Modulator, for a run whose input ``u`` moves.
    units : dict of str to Guess
        ``time`` and ``pressure`` units, pooled over the files sharing its columns.
    """

    file: str
    id: str = ""
    options: dict[str, Any] = field(default_factory=dict)
    roles: dict[str, Guess] = field(default_factory=dict)
    error: str | None = None
    data: dict[str, npt.NDArray[np.float64]] = field(default_factory=dict, repr=False)
    kind: Guess = field(default_factory=lambda: Guess(None, "not guessed"))
    modulator: Guess | None = None
    units: dict[str, Guess] = field(default_factory=dict)


# --------------------------------------------------------------------------- reading


def _detect_options(path: Path) -> dict[str, Any]:
    """The ``csv:`` options of a delimited text file that differ from its ending's defaults
    (separator, decimal mark, ...), as the delimited reader's sniffer finds them."""
    from spa.datasets.options import csv_options
    from spa.datasets.readers.sniff import sniff_delimited

    try:
        found = dict(sniff_delimited(path))
    except Exception:  # a sniffer that cannot decide leaves the defaults
        return {}
    if str(found.get("encoding", "")).lower().replace("_", "-") in ("utf-8", "utf-8-sig"):
        found["encoding"] = None  # the default: UTF-8, with or without a byte-order mark
    defaults = csv_options({}, path.suffix)
    return {k: v for k, v in found.items() if v is not None and v != defaults.get(k)}


def _open(path: Path, fmt: str, options: Mapping[str, Any]) -> Source:
    """The reader for ``fmt`` (:data:`spa.datasets.readers.READERS`), with ``options``."""
    return READERS[fmt](path, dict(options) if options else None)


def _numeric_names(source: Source) -> list[str]:
    """The file's columns whose type is numeric (:meth:`Source.check_types` finds no problem)."""
    return [str(name) for name in source.columns if not source.check_types([str(name)])]


def _read_columns(source: Any, names: list[str]) -> dict[str, npt.NDArray[np.float64]]:
    for as_text in (False, True):
        parts: dict[str, list[npt.NDArray[np.float64]]] = {n: [] for n in names}
        try:
            for _, values, _ in source.chunks(names, as_text=as_text):
                for n in names:
                    parts[n].append(np.asarray(values[n], dtype=np.float64))
        except _Retry:
            continue
        return {n: np.concatenate(p) if p else np.empty(0) for n, p in parts.items()}
    raise _ReadError("no numeric columns")  # pragma: no cover - the text pass never retries


def read_file(folder: Path, rel: str) -> FileDraft:
    """Read the numeric columns of one data file (``folder/rel``) into a :class:`FileDraft`.

    A file that cannot be read gets ``error`` set, never an exception.
    """
    path = folder / rel
    fmt = _FORMATS[path.suffix.lower()]
    draft = FileDraft(rel)
    draft.options = _detect_options(path) if fmt == "csv" else {}
    try:
        source = _open(path, fmt, draft.options)
        names = list(dict.fromkeys(_numeric_names(source)))
        data = _read_columns(source, names)
    except _ReadError as exc:
        draft.error = f"cannot read it: {exc}"
        return draft
    except Exception as exc:  # a damaged file: say so in the draft, keep going
        draft.error = f"cannot read it: {type(exc).__name__}: {exc}"
        return draft
    draft.data = {k: v for k, v in data.items() if v.size and np.all(np.isfinite(v))}
    if not draft.data:
        draft.error = "no column holds only numbers"
    return draft


def data_files(folder: Path) -> tuple[list[str], list[str]]:
    """Data files of a dataset folder and the files skipped.

    Returns
    -------
    files : list of str
        Paths relative to ``folder`` with a known ending (:data:`_FORMATS`), sorted; hidden
        files and folders are skipped, sub-folders searched :data:`_MAX_DEPTH` levels deep.
    skipped : list of str
        Other files (not ``dataset.yaml``), sorted.
    """
    files, skipped = [], []
    for path in sorted(folder.rglob("*")):
        rel = path.relative_to(folder)
        if any(part.startswith(".") for part in rel.parts) or not path.is_file():
            continue
        if len(rel.parts) > _MAX_DEPTH + 1 or rel.as_posix() == SPEC_FILE:
            continue
        (files if path.suffix.lower() in _FORMATS else skipped).append(rel.as_posix())
    return files, skipped


# --------------------------------------------------------------------------- guessing


def _run_ids(files: list[str]) -> list[str]:
    """A filename-safe, case-insensitively unique id per file: its stem, else its path."""
    stems = [Path(f).stem for f in files]
    folded = [s.casefold() for s in stems]
    ids, seen = [], set()
    for f, stem in zip(files, stems, strict=True):
        base = stem if folded.count(stem.casefold()) == 1 else str(Path(f).with_suffix(""))
        rid = re.sub(r"[^A-Za-z0-9._-]+", "_", base.replace("/", "-")).lstrip(".")[:100] or "run"
        unique, k = rid, 2
        while unique.casefold() in seen or not _ID_RE.fullmatch(unique):
            unique, k = f"{rid[:95]}-{k}", k + 1
        seen.add(unique.casefold())
        ids.append(unique)
    return ids


def _pooled_units(drafts: list[FileDraft]) -> dict[str, Guess]:
    """Units guessed from every file's time steps and pressures together."""
    steps = [np.diff(d.data[d.roles["t"].value]) for d in drafts if d.roles["t"].decided]
    pressures = [d.data[d.roles["p"].value] for d in drafts if d.roles["p"].decided]
    t_name = next((d.roles["t"].value for d in drafts if d.roles["t"].decided), None)
    if steps:
        t = guess_time_unit(np.concatenate([[0.0], np.cumsum(np.concatenate(steps))]), t_name)
    else:
        t = Guess(None, NO_TIME)
    name = next((d.roles["p"].value for d in drafts if d.roles["p"].decided), None)
    p = guess_pressure_unit(np.concatenate(pressures), name) if pressures else Guess(None, "no p")
    many = f" (over {len(drafts)} files)" if len(drafts) > 1 else ""
    return {
        "time": Guess(t.value, t.reason + (many if t.decided else "")),
        "pressure": Guess(p.value, p.reason + (many if p.decided else "")),
    }


def _guess_run(draft: FileDraft, time_unit: str | None) -> None:
    """Fill ``kind`` and ``modulator`` of a read file; without a time column the kind is
    guessed against the row index (the pressure's trend needs no clock)."""
    col = {k: g.value for k, g in draft.roles.items()}
    arrays = {k: None if col[k] is None else draft.data[col[k]] for k in ("p", "valve", "u")}
    if col["t"] is None:
        rows = next(len(a) for a in arrays.values() if a is not None) if col["p"] else 0
        t = np.arange(rows, dtype=np.float64)
    else:
        t = draft.data[col["t"]] * (1e-3 if time_unit == "ms" else 1.0)
    if col.get("r") is not None:
        draft.kind = Guess(CLOSED_LOOP, f"a set-point column {col['r']!r} beside the pressure")
    else:
        draft.kind = guess_kind(t, arrays["p"], arrays["valve"], arrays["u"])
        if col["t"] is None and draft.kind.decided:
            draft.kind = Guess(draft.kind.value, f"{draft.kind.reason} (by row: no time column)")
    if draft.kind.value in MODULATED_KINDS or (draft.kind.value is None and col["u"]):
        if arrays["valve"] is None:
            draft.modulator = Guess(None, "could not tell the modulator: no valve column")
        elif col["t"] is None:
            draft.modulator = Guess(
                None, "could not tell the modulator: no time column, so no edge times"
            )
        else:
            draft.modulator = guess_modulator(t, arrays["valve"], arrays["u"])


def draft_files(folder: str | Path) -> tuple[list[FileDraft], list[str]]:
    """Read and guess every data file of ``folder``.

    Returns
    -------
    drafts : list of FileDraft
        One per data file, sorted by path, with roles, units, kind and modulator guessed.
    skipped : list of str
        Files not drafted: an unknown ending, or ``.txt``/``.dat`` text that holds no table
        of numbers (notes).
    """
    folder = Path(folder)
    files, skipped = data_files(folder)
    drafts = [read_file(folder, f) for f in files]
    # .txt and .dat are as often notes as data: one that holds no table of numbers is skipped
    notes = {
        d.file
        for d in drafts
        if d.error is not None and PurePosixPath(d.file).suffix.lower() in (".txt", ".dat")
    }
    skipped += sorted(notes)
    files = [f for f in files if f not in notes]
    drafts = [d for d in drafts if d.file not in notes]
    for d, rid in zip(drafts, _run_ids(files), strict=True):
        d.id = rid
        if d.error is None:
            d.roles = guess_roles(d.data)
    read = [d for d in drafts if d.error is None]
    groups: dict[tuple[Any, ...], list[FileDraft]] = {}
    for d in read:
        groups.setdefault((d.roles["t"].value, d.roles["p"].value), []).append(d)
    for group in groups.values():
        units = _pooled_units(group)
        for d in group:
            d.units = units
            _guess_run(d, units["time"].value)
            d.data = {}
    return drafts, skipped


# --------------------------------------------------------------------------- YAML text


def _scalar(value: Any) -> str:
    """``value`` as YAML text that the project's loader reads back as ``value``."""
    text = dump_yaml(value, default_flow_style=True, width=10**9, sort_keys=False)
    text = text.removesuffix("\n").removesuffix("\n...")
    if yaml.load(text, Loader=_UniqueKeyLoader) != value and isinstance(value, str):
        text = "'" + value.replace("'", "''") + "'"
    return text


def _comment(reason: str) -> str:
    return "  # " + " ".join(reason.split())


def _line(indent: str, key: str, guess: Guess) -> str:
    value = _scalar(guess.value) if guess.decided else TODO
    return f"{indent}{key}: {value}{_comment(guess.reason)}"


def _shared(drafts: list[FileDraft], pick: Any) -> tuple[bool, Any]:
    """Whether every draft gives the same ``pick(draft)``, and that value."""
    values = [pick(d) for d in drafts]
    same = all(v == values[0] for v in values)
    return same, values[0] if values else None


#: Why an input fraction ``u`` is left out when the only command column is the 0/1 valve:
#: written above ``u: null``.
_NO_U = (
    "No input fraction is recorded: these runs serve as charge, discharge or pulse runs "
    "(identification), which need none. A staircase, sine or chirp run needs u; spa does "
    "not derive it from the valve as the duty of each pulse period, which would lose the "
    "timing within the period (u known once per period, up to a period late, and IPFM, "
    "IIPFM and delta-sigma periods vary with u): record u to use such runs."
)


def _columns_block(indent: str, roles: Mapping[str, Guess]) -> list[str]:
    """The ``columns:`` lines: each role named other than by its canonical name, and
    ``null`` for an optional role whose canonical name is a column taken by another role
    (a ``time,u,pressure`` log whose ``u`` is the 0/1 valve command)."""
    lines = []
    taken = {g.value: role for role, g in roles.items() if g.decided}
    for role in _ROLES:
        g = roles[role]
        if g.decided and g.value != role:
            lines.append(_line(indent + "  ", role, g))
        elif not g.decided and role == "t":
            why = f"{g.reason}: t = row index * sample_step"
            lines.append(f"{indent}  t: null{_comment(why)}")
        elif not g.decided and role == "p":
            lines.append(_line(indent + "  ", role, g))
        elif not g.decided and taken.get(role, role) != role:
            if role == "u" and taken[role] == "valve":
                wrap = textwrap.wrap(_NO_U, 92 - len(indent), break_on_hyphens=False)
                lines += [f"{indent}  # {text}" for text in wrap]
            why = f"the file column {role!r} is the {taken[role]} column: no {role} column"
            lines.append(f"{indent}  {role}: null{_comment(why)}")
    return [f"{indent}columns:", *lines] if lines else []


def _units_block(indent: str, units: Mapping[str, Guess]) -> list[str]:
    """The ``units:`` lines; no time unit for files without a time column (their step,
    ``sample_step``, is in s)."""
    keys = [k for k in ("time", "pressure") if k != "time" or units[k].reason != NO_TIME]
    return [f"{indent}units:", *(_line(indent + "  ", k, units[k]) for k in keys)]


def _clock_block(indent: str, drafts: list[FileDraft]) -> list[str]:
    """``sample_step: TODO`` when none of ``drafts`` has a time column; the commented
    ``valve_edges`` when one logs a valve command."""
    out = []
    if drafts and not any(d.roles["t"].decided for d in drafts):
        out.append(indent + _SAMPLE_STEP_TODO)
    if any(d.roles["valve"].decided for d in drafts):
        width = 92 - len(indent)
        wrap = textwrap.wrap(_VALVE_EDGES_NOTE[2:], width, break_on_hyphens=False)
        out += [f"{indent}# {wrap[0]}", *(f"{indent}#   {x}" for x in wrap[1:])]
    return out


def _options_block(indent: str, options: Mapping[str, Any]) -> list[str]:
    if not options:
        return []
    return [f"{indent}csv: {_scalar(dict(options))}  # detected from the file"]


def _merged_roles(drafts: list[FileDraft]) -> dict[str, Guess] | None:
    """One column mapping for every file (each role one name, or absent from some files;
    no name in two roles), or None when the files disagree."""
    merged: dict[str, Guess] = {}
    for role in _ROLES:
        names = {d.roles[role].value for d in drafts if d.roles[role].decided}
        if len(names) > 1:
            return None
        found = [d.roles[role] for d in drafts if d.roles[role].decided]
        if found:
            where = f" (in {len(found)} of {len(drafts)} files)" if len(drafts) > 1 else ""
            merged[role] = Guess(found[0].value, found[0].reason + where)
        else:
            merged[role] = drafts[0].roles[role] if drafts else Guess(None, "no files")
    names = [g.value for g in merged.values() if g.decided]
    return merged if len(names) == len(set(names)) else None


def render_draft(
    name: str,
    drafts: list[FileDraft],
    skipped: list[str],
    recorded: tuple[str | None, str] = (None, "no file header gives a date"),
) -> str:
    """The text of a draft ``dataset.yaml`` for the dataset ``name``; ``recorded`` is the
    session's day and where it is from (:func:`spa.datasets.recorded.session_date`), a
    ``# recorded: YYYY-MM-DD  TODO`` comment when there is none.

    Dataset-level ``units``, ``columns`` and ``csv`` options when every read file shares them,
    per run otherwise. Each guess carries its reason as a comment; a failed guess is ``TODO``.
    """
    read = [d for d in drafts if d.error is None]
    csvs = [d for d in read if d.file.lower().endswith(".csv")]
    roles = _merged_roles(read)
    same_units, units = _shared(read, lambda d: {k: g.value for k, g in d.units.items()})
    same_opts, options = _shared(csvs, lambda d: d.options)
    rate = ""
    if read and same_units and units["time"]:
        found = re.search(r"[\d.e+-]+ Hz", read[0].units["time"].reason)
        rate = found.group(0) if found else ""
    out = [
        "# Draft written by `spa init`: every guess has its reason as a comment.",
        "# Check each one, describe the dataset and the rig, then run `spa validate`. A TODO",
        "# marks what could not be guessed; spa validate rejects it until you replace it.",
    ]
    if skipped:
        out.append(f"# Not drafted (not a data table): {', '.join(skipped)}")
    out += [
        f"name: {_scalar(name)}",
        f"description: {_scalar(f'Bench recordings {name}, drafted by spa init.')}"
        "  # say what was recorded, when and how",
        "origin: bench  # bench (measured) or synthetic (generated)",
        f"recorded: {recorded[0]}{_comment(recorded[1])}"
        if recorded[0]
        else f"# recorded: YYYY-MM-DD  {TODO}: the day of the session ({recorded[1]})",
        "rig:  # describe the bench: valve, actuator, sensors, controller",
        f"  sensors: {_scalar(f'pressure logged at {rate}' if rate else 'to describe')}",
    ]
    if read and same_units:
        out += _units_block("", read[0].units)
    if read and roles is not None:
        out += _columns_block("", roles)
    if csvs and same_opts:
        out += _options_block("", options)
    same_clock = roles is not None and len({d.roles["t"].decided for d in read}) <= 1
    if same_clock:
        out += _clock_block("", read)
    out.append("runs:")
    for d in drafts:
        out.append(f"  - id: {_scalar(d.id)}")
        if d.error is not None:
            out.append(f"    kind: {TODO}{_comment('could not tell: ' + d.error)}")
            out.append(f"    file: {_scalar(d.file)}")
            continue
        out.append(_line("    ", "kind", d.kind))
        out.append(f"    file: {_scalar(d.file)}")
        if d.modulator is not None:
            out.append(_line("    ", "modulator", d.modulator))
        if d.kind.value == CLOSED_LOOP:
            out.append(f"    controller: {TODO}{_comment(_CONTROLLER_TODO)}")
        if not same_units:
            out += _units_block("    ", d.units)
        if roles is None:
            out += _columns_block("    ", d.roles)
        else:
            out += [
                f"    # {TODO}: {_comment(d.roles[r].reason)[4:]} (needs {r!r})"
                for r in ("t", "p")
                if not d.roles[r].decided and r == "p"
            ]
        if not same_clock:
            if roles is not None and not d.roles["t"].decided:
                out.append(f"    columns: {{t: null}}{_comment(NO_TIME)}")
            out += _clock_block("    ", [d])
        if not same_opts and d in csvs:
            out += _options_block("    ", d.options)
    return "\n".join(out) + "\n"


@fill_doc
def draft_dataset(folder: str | Path) -> str:
    """Draft the ``dataset.yaml`` of a dataset folder (reads the data files, writes nothing).

    Parameters
    ----------
    %(dataset_folder)s

    Returns
    -------
    str
        YAML text, readable by :mod:`spa.datasets.yaml_loader`.

    Raises
    ------
    ValueError
        If ``folder`` is not a folder or holds no data file.
    """
    folder = Path(folder)
    if not folder.is_dir():
        raise ValueError(f"{folder} is not a folder; give the dataset folder, raw/<name>")
    drafts, skipped = draft_files(folder)
    if not drafts:
        known = ", ".join(sorted(_FORMATS))
        raise ValueError(f"{folder} holds no data file ({known}); nothing to draft")
    recorded = session_date(folder, [d.file for d in drafts])
    return render_draft(folder.resolve().name, drafts, skipped, recorded)


def write_draft(folder: str | Path, force: bool = False) -> tuple[Path, str]:
    """Write ``<folder>/dataset.yaml`` drafted by :func:`draft_dataset`.

    This is the one write into a dataset folder the project makes: only that file, and only
    when it does not exist yet or ``force`` is given. Data files are never touched.

    Returns
    -------
    path : pathlib.Path
        The file written.
    text : str
        Its content.

    Raises
    ------
    FileExistsError
        If ``dataset.yaml`` exists and ``force`` is false.
    ValueError
        As :func:`draft_dataset`.
    """
    path = Path(folder) / SPEC_FILE
    if path.exists() and not force:
        raise FileExistsError(
            f"{path} exists; spa init never overwrites it: move it away, or give --force to "
            "replace it with a new draft"
        )
    text = draft_dataset(folder)
    path.write_text(text, encoding="utf-8")
    return path, text
