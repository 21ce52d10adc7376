"""``spa init``'s reading: every data file of a dataset folder read through the readers of
:mod:`spa.datasets.readers` (so every format they know is drafted), its columns' roles,
units, kind and modulator guessed (:mod:`spa.datasets.draft`), and what could not be read
kept with the reason, for :mod:`spa.datasets.draft_yaml` to write and ``spa init`` to say.

Each file is read whole (its numeric columns as float64: 8 bytes per value), once.
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path, PurePosixPath
from typing import Any

import numpy as np
import numpy.typing as npt

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
from spa.datasets.readers.sniff import prefix_hint

__all__ = ["FileDraft", "data_files", "draft_files", "read_file"]

_MAX_DEPTH = 2  # sub-folder levels searched for data files

#: The reason given for a time unit when the files have no time column.
NO_TIME = "no time column"

#: The kind of a run with a set-point column.
CLOSED_LOOP = "closed_loop"


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
    if draft.error is not None and fmt == "csv":
        draft.error += prefix_hint(path)
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
        span = float(np.median([s.sum() for s in steps]))  # the files' median duration
        t = guess_time_unit(
            np.concatenate([[0.0], np.cumsum(np.concatenate(steps))]), t_name, span
        )
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


#: Endings of text that is as often notes as data: one holding no table of numbers is
#: skipped (with its reason), not drafted as a run.
NOTE_ENDINGS = (".txt", ".dat", ".log")


def draft_files(folder: str | Path) -> tuple[list[FileDraft], dict[str, str]]:
    """Read and guess every data file of ``folder``.

    Returns
    -------
    drafts : list of FileDraft
        One per data file, sorted by path, with roles, units, kind and modulator guessed.
    skipped : dict of str to str
        Files not drafted, sorted, each with why: an unknown ending, or text ending in one
        of :data:`NOTE_ENDINGS` that holds no table of numbers (notes, or a log spa cannot
        read: the reason says which).
    """
    folder = Path(folder)
    files, others = data_files(folder)
    known = ", ".join(sorted(_FORMATS))
    skipped = {
        f: f"its ending {PurePosixPath(f).suffix or '(none)'!r} is not one spa reads ({known})"
        for f in others
    }
    drafts = [read_file(folder, f) for f in files]
    notes = {
        d.file: d.error
        for d in drafts
        if d.error is not None and PurePosixPath(d.file).suffix.lower() in NOTE_ENDINGS
    }
    skipped = dict(sorted({**skipped, **notes}.items()))
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
