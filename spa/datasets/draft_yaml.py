"""``spa init``: draft the ``dataset.yaml`` of a folder of recordings.

The files are read and their guesses made by :mod:`spa.datasets.draft_read` (the guesses
themselves are :mod:`spa.datasets.draft`'s); this module pools what the files share (units,
column names, file options) at the dataset level, and writes YAML text with the reason of
every guess as a comment and ``TODO`` where a guess failed (a value the parser rejects, so
``spa validate`` lists it). Every file it could not read is listed with the reason.

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
from pathlib import Path
from typing import Any

import yaml

from spa._docs import fill_doc
from spa.datasets.contract import SPEC_FILE
from spa.datasets.draft import Guess

# The reading half, importable from here as before.
from spa.datasets.draft_read import CLOSED_LOOP, NO_TIME, FileDraft, draft_files
from spa.datasets.draft_read import READERS as READERS
from spa.datasets.draft_read import _detect_options as _detect_options
from spa.datasets.draft_read import _open as _open
from spa.datasets.draft_read import _run_ids as _run_ids
from spa.datasets.draft_read import data_files as data_files
from spa.datasets.draft_read import read_file as read_file
from spa.datasets.recorded import session_date
from spa.datasets.yaml_loader import _UniqueKeyLoader
from spa.io import dump_yaml

__all__ = ["FileDraft", "draft_dataset", "draft_files", "draft_report", "write_draft"]

#: Marker written where a guess failed; every place it goes, the parser rejects it.
TODO = "TODO"

_ROLES = ("t", "p", "valve", "u", "r")

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

#: What a closed-loop run's draft asks for.
_CONTROLLER_TODO = (
    "the PI that ran, not in the data: {kp: <1/bar>, ki: <1/(bar s)>, dt: <s>} "
    "(raw/README.md, controller)"
)


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
    same_clock = len({d.roles["t"].decided for d in read}) <= 1  # all stamped, or none
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


def draft_report(folder: str | Path) -> tuple[str, dict[str, str]]:
    """Draft the ``dataset.yaml`` of a dataset folder, and say what could not be read.

    Parameters
    ----------
    folder : str or path-like
        The dataset folder, ``raw/<name>``; only read.

    Returns
    -------
    text : str
        YAML text, readable by :mod:`spa.datasets.yaml_loader`.
    unread : dict of str to str
        Each file not drafted, or drafted with ``kind: TODO`` because it could not be read,
        with why (an unknown ending, no table of numbers, a serial monitor's time stamps, a
        damaged file, ...).

    Raises
    ------
    ValueError
        If ``folder`` is not a folder, or holds no file spa can read (naming every file and
        why, or saying that the folder is empty).
    """
    folder = Path(folder)
    if not folder.is_dir():
        raise ValueError(f"{folder} is not a folder; give the dataset folder, raw/<name>")
    drafts, skipped = draft_files(folder)
    unread = {**skipped, **{d.file: d.error for d in drafts if d.error is not None}}
    unread = dict(sorted(unread.items()))
    if not drafts:
        if not unread:
            raise ValueError(f"{folder} holds no files; copy the recordings into it first")
        why = "; ".join(f"{f}: {reason}" for f, reason in unread.items())
        raise ValueError(f"{folder} holds no data file spa can read, nothing to draft: {why}")
    recorded = session_date(folder, [d.file for d in drafts])
    return render_draft(folder.resolve().name, drafts, list(skipped), recorded), unread


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
        As :func:`draft_report`, which also says what could not be read.
    """
    return draft_report(folder)[0]


def write_draft(folder: str | Path, force: bool = False) -> tuple[Path, str, dict[str, str]]:
    """Write ``<folder>/dataset.yaml`` drafted by :func:`draft_report`.

    This is the one write into a dataset folder the project makes: only that file, and only
    when it does not exist yet or ``force`` is given. Data files are never touched.

    Returns
    -------
    path : pathlib.Path
        The file written.
    text : str
        Its content.
    unread : dict of str to str
        The files that could not be read, each with why (:func:`draft_report`).

    Raises
    ------
    FileExistsError
        If ``dataset.yaml`` exists and ``force`` is false.
    ValueError
        As :func:`draft_report`.
    """
    path = Path(folder) / SPEC_FILE
    if path.exists() and not force:
        raise FileExistsError(
            f"{path} exists; spa init never overwrites it: move it away, or give --force to "
            "replace it with a new draft"
        )
    text, unread = draft_report(folder)
    path.write_text(text, encoding="utf-8")
    return path, text, unread
