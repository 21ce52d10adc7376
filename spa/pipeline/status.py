"""One bad dataset costs only itself: every per-dataset stage records whether it worked.

A workflow job of a dataset runs its work through :func:`run_stage`. When the work raises
(bad data, an identification that cannot be done, a run that is not what its kind says), the
job does not fail: it logs the error (its traceback too when it is a bug, not an input
error: :func:`anticipated`), fills each of its outputs with a
placeholder, and writes its status file (``results/<dataset>/status/<stage>.json``) saying
what failed. A later stage of the same dataset finds the failed status and skips its work the
same way. So every other dataset, and the report, are still built; the report lists the failed
datasets with their first errors (:func:`dataset_failures`), and the final ``check`` job of
``reproduce-all`` exits non-zero naming them (:func:`failure_summary`).

A status file is ``{"stage", "dataset", "ok", "errors": [...], "upstream"}`` (with
``warnings`` and ``skipped``, the parts of a stage that worked left out by name with their
reason: :class:`Skipped`, when there are any, and ``no_runs``, what of the stage had no runs
of its kind to analyse: :class:`NoRuns`); ``upstream`` names
the earlier stage that failed when this one was skipped for it. A stage that failed itself also
records whose fault it was (:func:`fault_of`): ``"data"`` when the dataset breaks the contract
that ``spa validate`` checks, ``"lacking"`` when the data pass validation but lack what the
stage needs (its error's message says what), ``"stage"`` otherwise. The report tells the user
to fix the data only for the first.

An error of the machine rather than of the data (a full disk or quota, a file too large for
``ulimit -f``, a read-only or forbidden results folder, memory exhausted:
:func:`environment_error`) is not recorded as the dataset's failure: the job fails, with no
placeholder and no status, saying so (:class:`EnvironmentFailure`), so that once the cause is
fixed a rerun completes and equals a clean run. A job killed from outside leaves nothing
either (Snakemake removes the outputs of a failed job).
"""

from __future__ import annotations

import errno
import json
import logging
import os
import shutil
import sys
import traceback
from collections.abc import Callable, Iterable, Iterator, Mapping
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from spa.errors import ENVIRONMENT_ERRNOS, RunError
from spa.pipeline.notes import NoRuns, Skipped

__all__ = [
    "DATA_ERRORS",
    "ENVIRONMENT_ERRNOS",
    "LACKING_ERRORS",
    "STATUS_DIR",
    "EnvironmentFailure",
    "NoRuns",
    "RunError",
    "Skipped",
    "anticipated",
    "data_fault",
    "dataset_failures",
    "dataset_statuses",
    "environment_error",
    "failure_summary",
    "fault_of",
    "guard_environment",
    "naming_run",
    "read_status",
    "reuse_summary",
    "run_stage",
    "write_placeholder",
    "write_status",
]


#: Folder of a dataset's results holding one ``<stage>.json`` per stage.
STATUS_DIR = "status"

_MAX_ERRORS = 10

# A 1x1 transparent PNG: a valid figure file that says nothing (the report never shows it).
_EMPTY_PNG = bytes.fromhex(
    "89504e470d0a1a0a0000000d49484452000000010000000108060000001f15c489"
    "0000000d49444154789c6360000002000001e221bc330000000049454e44ae426082"
)

# Its SVG copy: an empty 1x1 drawing.
_EMPTY_SVG = '<svg xmlns="http://www.w3.org/2000/svg" width="1" height="1"/>\n'


#: Refused access: the environment's fault when the file is the job's own (or not named).
_ACCESS_ERRNOS = frozenset({errno.EACCES, errno.EPERM})


class EnvironmentFailure(SystemExit):
    """A stage stopped by its environment: the job exits non-zero with this message."""


def environment_error(exc: BaseException, own: str | Path | None = None) -> str | None:
    """Why ``exc`` is the environment's fault rather than the data's, or None.

    Parameters
    ----------
    exc : BaseException
        The error (its ``__cause__`` and ``__context__`` are looked at too).
    own : path-like, optional
        The folder of the job's outputs: a refused access to a file in it (or to an unnamed
        file) is the environment's; to any other file (a recording) it is the data's.

    Examples
    --------
    >>> print(environment_error(OSError(errno.ENOSPC, "No space left on device", "r/x.csv")))
    [Errno 28] No space left on device: 'r/x.csv'
    >>> environment_error(PermissionError(errno.EACCES, "Permission denied", "raw/d/a.csv"),
    ...                   own="results/d") is None
    True
    >>> environment_error(ValueError("u above 1")) is None
    True
    """
    seen: set[int] = set()
    todo: list[BaseException | None] = [exc]
    while todo:
        err = todo.pop()
        if err is None or id(err) in seen:
            continue
        seen.add(id(err))
        if isinstance(err, MemoryError):
            return f"out of memory ({type(err).__name__}: {err})"
        if isinstance(err, OSError) and err.errno in ENVIRONMENT_ERRNOS:
            return str(err)
        if isinstance(err, OSError) and err.errno in _ACCESS_ERRNOS:
            name = err.filename
            if name is None or own is None:
                return str(err)
            if Path(os.fsdecode(name)).resolve().is_relative_to(Path(own).resolve()):
                return str(err)
        todo += [err.__cause__, err.__context__]
    return None


def anticipated(exc: BaseException) -> bool:
    """Whether ``exc`` is an input error that spa raises on purpose, with a full message.

    Those are :class:`ValueError` subclasses of spa itself (:class:`RunError`,
    ``DatasetError``, ``IdentificationError``, ``TuningError``, ``ConfigError``...): their
    message says what is wrong, and a traceback would only hide it. Anything else (an
    ``IndexError``, a ``ValueError`` from inside numpy) is a bug: its traceback is logged.

    Examples
    --------
    >>> anticipated(RunError("run 's1' (staircase): u goes down")), anticipated(ValueError())
    (True, False)
    """
    return isinstance(exc, ValueError) and type(exc).__module__.startswith("spa.")


#: spa's error classes that say the recordings break the contract ``spa validate`` checks
#: (:func:`data_fault`).
DATA_ERRORS = frozenset({"DatasetError"})

#: spa's error classes that say data which ``spa validate`` accepts lack what a stage needs
#: (a missing run, too few samples, a run that is not what its kind says): :func:`fault_of`.
LACKING_ERRORS = frozenset({"RunError", "IdentificationError"})


def _spa_classes(exc: BaseException) -> set[str]:
    return {c.__name__ for c in type(exc).__mro__ if c.__module__.startswith("spa.")}


def _wraps_a_bug(exc: BaseException) -> bool:
    """A ``RunError`` that only wraps another library's error (:func:`naming_run` around an
    ``IndexError`` from numpy): nothing says the data is wrong."""
    cause = exc.__cause__
    return isinstance(exc, RunError) and cause is not None and not anticipated(cause)


def data_fault(exc: BaseException) -> bool:
    """Whether a stage's failure is the data's: the dataset fails validation, and the user
    must fix it.

    The rule is the error's class. The data is at fault only when spa raised one of
    :data:`DATA_ERRORS` (or a subclass) about it: ``DatasetError``, the dataset breaks the
    contract of raw/README.md (what ``spa validate`` and the ingest refuse). An
    ``IdentificationError`` or a ``RunError`` is raised on data that validation accepted:
    the data lack what the stage needs (:func:`fault_of` says ``"lacking"``), and the report
    says what, in the error's own words, and that validation passed. Every other error is
    the stage's: a ``TuningError`` or a design that cannot use the identification's own
    output, a ``ConfigError`` (the config, not the data), a bug.

    Examples
    --------
    >>> from spa.datasets import DatasetError
    >>> data_fault(DatasetError("raw/d", []))
    True
    >>> data_fault(RunError("run 's1' (staircase): u goes down"))
    False
    >>> data_fault(IndexError("index 0 is out of bounds for axis 0 with size 0"))
    False
    """
    return bool(_spa_classes(exc) & DATA_ERRORS) and not _wraps_a_bug(exc)


def fault_of(exc: BaseException) -> str:
    """Whose fault a stage's failure is: ``"data"`` (validation fails: :func:`data_fault`),
    ``"lacking"`` (data that validation accepts lack what the stage needs:
    :data:`LACKING_ERRORS`) or ``"stage"``.

    Examples
    --------
    >>> fault_of(RunError("run 's1' is labelled staircase but u goes down"))
    'lacking'
    >>> try:
    ...     with naming_run("s1", "staircase"):
    ...         [][0]
    ... except RunError as exc:
    ...     fault_of(exc)
    'stage'
    >>> fault_of(KeyError("k2"))
    'stage'
    """
    if data_fault(exc):
        return "data"
    if _spa_classes(exc) & LACKING_ERRORS and not _wraps_a_bug(exc):
        return "lacking"
    return "stage"


def _environment_message(what: str, cause: str) -> str:
    return (
        f"spa: {what} was stopped by its environment, not by its data: {cause}. Nothing was "
        "recorded against the data; free space, memory or permissions and run again."
    )


def guard_environment(log: logging.Logger, what: str) -> None:
    """Make an uncaught error of the environment one line saying so, not a traceback.

    For the jobs that are no dataset's stage (the analytic tables and figures, the report,
    the check): they write nothing on failure anyway, and exit non-zero; this only changes
    what they say. Any other error keeps its traceback.

    Parameters
    ----------
    log : logging.Logger
        The job's log (and the console).
    what : str
        The job, for the message (``"analytic table 1"``).
    """
    default = sys.excepthook

    def hook(kind: type[BaseException], exc: BaseException, tb: Any) -> None:
        cause = environment_error(exc) if isinstance(exc, Exception) else None
        if cause is None:
            default(kind, exc, tb)
        else:
            log.error("%s", _environment_message(what, cause))

    sys.excepthook = hook


@contextmanager
def naming_run(run: str, kind: str) -> Iterator[None]:
    """Re-raise an error of the analysis of one run with the run named.

    Examples
    --------
    >>> with naming_run("s1", "staircase"):
    ...     raise ValueError("xi must be strictly increasing")
    Traceback (most recent call last):
    ...
    spa.errors.RunError: run 's1' (staircase): ValueError: xi must be strictly increasing
    """
    try:
        yield
    except (ValueError, ArithmeticError, LookupError, TypeError) as exc:
        if isinstance(exc, RunError):
            raise
        raise RunError(f"run {run!r} ({kind}): {type(exc).__name__}: {exc}") from exc


def write_status(
    path: str | Path,
    stage: str,
    dataset: str,
    errors: Iterable[str] = (),
    upstream: str | None = None,
    warnings: Iterable[str] = (),
    fault: str | None = None,
) -> dict[str, Any]:
    """Write a stage's status file; ``errors`` empty means it worked (``warnings``, such as
    an implausible supply pressure, are recorded when there are any, the :class:`Skipped`
    among them also as ``skipped``, part -> reason, the :class:`NoRuns` as ``no_runs``;
    ``fault``, ``"data"``, ``"lacking"`` or
    ``"stage"``, whose fault a failure is: :func:`fault_of`)."""
    errs = [str(e) for e in errors][:_MAX_ERRORS]
    status: dict[str, Any] = {
        "stage": stage,
        "dataset": dataset,
        "ok": not errs,
        "errors": errs,
        "upstream": upstream,
    }
    if errs and fault is not None:
        status["fault"] = fault
    given = [w for w in warnings if isinstance(w, str | Skipped | NoRuns)]
    notes = [str(w) for w in given][:_MAX_ERRORS]
    if notes:
        status["warnings"] = notes
    skipped = {w.part: w.reason for w in given if isinstance(w, Skipped)}
    if skipped:
        status["skipped"] = skipped
    empty = [w.to_mapping() for w in given if isinstance(w, NoRuns)]
    if empty and not errs:
        status["no_runs"] = empty
    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(status, indent=1) + "\n")
    return status


def read_status(path: str | Path) -> dict[str, Any] | None:
    """A status file's content, or None when it does not exist (the stage did not run)."""
    p = Path(path)
    if not p.is_file():
        return None
    try:
        status = json.loads(p.read_text())
    except ValueError:
        return {"stage": p.stem, "ok": False, "errors": [f"unreadable status file {p}"]}
    return status if isinstance(status, dict) else None


def write_placeholder(path: str | Path, kind: str, message: str) -> None:
    """Fill one output of a failed stage so that the workflow can go on.

    Parameters
    ----------
    path : path-like
        The output.
    kind : str
        Its kind in :mod:`spa.pipeline.outputs` (``table``, ``data``, ``figure``, ``params``,
        ``figures``, ``runs``, ...).
    message : str
        Why there is no result; written into tables and parameter files.
    """
    out = Path(path)
    if kind in ("figures", "runs"):
        if out.is_dir():
            shutil.rmtree(out)
        out.mkdir(parents=True)
        return
    out.parent.mkdir(parents=True, exist_ok=True)
    if out.suffix == ".png":
        out.write_bytes(_EMPTY_PNG)
    elif out.suffix == ".svg":
        out.write_text(_EMPTY_SVG)
    elif out.suffix in (".yaml", ".yml"):
        out.write_text(json.dumps({"failed": message}) + "\n")
    else:
        out.write_text("error\n" + json.dumps(message) + "\n")


def _upstream_failure(status_dir: Path, before: Iterable[str]) -> dict[str, Any] | None:
    for stage in before:
        status = read_status(status_dir / f"{stage}.json")
        if status is not None and not status.get("ok", False):
            return status
    return None


def run_stage(
    smk: Any,
    stage: str,
    work: Callable[[], None],
    log: logging.Logger,
) -> bool:
    """Run one dataset stage's work; on failure, placeholders and a failed status instead.

    Parameters
    ----------
    smk : snakemake.script.Snakemake
        The job (``snakemake`` in a workflow script): its ``output`` must have a ``status``.
    stage : str
        The stage's name in :data:`spa.pipeline.outputs.STAGES`.
    work : callable
        Does the stage's work and writes every output but ``status``; it may return a list
        of warnings (str, :class:`Skipped` for a part left out, :class:`NoRuns` for runs of
        a kind the dataset lacks), which the status records (``warnings``, ``skipped``,
        ``no_runs``).
    log : logging.Logger
        The job's log: the error and its traceback go there.

    Returns
    -------
    bool
        True when the work ran and succeeded.

    Raises
    ------
    EnvironmentFailure
        When the work was stopped by the machine (:func:`environment_error`): no placeholder
        and no status are written, and the job exits non-zero with a message saying so.
    """
    from spa.pipeline.outputs import STAGES

    dataset = str(smk.wildcards.dataset)
    status_path = Path(smk.output.status)
    names = [s.name for s in STAGES if s.per_dataset]
    known = {s.name: s for s in STAGES}
    upstream = known[stage].upstream if stage in known else None
    before = names[: names.index(stage)] if upstream is None and stage in names else upstream
    failed = _upstream_failure(status_path.parent, before)
    if failed is not None:
        errors = [f"skipped: stage {failed['stage']} failed"]
        log.error("%s: %s (%s)", dataset, errors[0], "; ".join(failed.get("errors", [])[:3]))
        _fill(smk, stage, errors[0])
        write_status(status_path, stage, dataset, errors, upstream=str(failed["stage"]))
        return False
    try:
        notes = _profiled(work, stage, dataset)
    except Exception as exc:
        cause = environment_error(exc, status_path.parents[2])
        if cause is not None:
            message = _environment_message(f"dataset {dataset}: stage {stage}", cause)
            log.error("%s", message)
            raise EnvironmentFailure(message) from None
        problems = getattr(exc, "problems", None)
        if problems:
            errors = [str(p) for p in problems if getattr(p, "is_error", True)]
            for p in problems:
                (log.error if getattr(p, "is_error", True) else log.warning)("%s", p)
        else:
            errors = [f"{type(exc).__name__}: {exc}"]
        if anticipated(exc):  # bad input, said by spa: its message, no traceback
            log.error("%s: stage %s failed: %s", dataset, stage, errors[0])
        else:  # a bug: where it happened
            log.error("%s: stage %s failed:\n%s", dataset, stage, traceback.format_exc())
        _fill(smk, stage, errors[0])
        write_status(status_path, stage, dataset, errors, fault=fault_of(exc))
        return False
    write_status(status_path, stage, dataset, warnings=notes or ())
    return True


def _profiled(work: Callable[[], Any], stage: str, dataset: str) -> Any:
    """Run ``work``; with ``SPA_PROFILE_DIR`` set, record where the job's time went.

    A development aid for the benchmarks (``benchmarks/README.md``): the job's CPU seconds
    before its work (interpreter start and imports) and in all go to
    ``<SPA_PROFILE_DIR>/<stage>-<dataset>.json``; with ``SPA_PROFILE=cprofile`` also, the
    work runs under cProfile, stats to ``<stage>-<dataset>.prof`` (readable with
    :mod:`pstats`).
    """
    folder = os.environ.get("SPA_PROFILE_DIR")
    if not folder:
        return work()
    import resource
    import time

    def cpu() -> float:
        usage = resource.getrusage(resource.RUSAGE_SELF)
        return usage.ru_utime + usage.ru_stime

    out = Path(folder) / f"{stage}-{dataset}"
    out.parent.mkdir(parents=True, exist_ok=True)
    before, start = cpu(), time.perf_counter()
    try:
        if os.environ.get("SPA_PROFILE") == "cprofile":
            import cProfile

            profile = cProfile.Profile()
            try:
                return profile.runcall(work)
            finally:
                profile.dump_stats(out.with_suffix(".prof"))
        else:
            return work()
    finally:
        timing = {"cpu_before_work": before, "cpu_total": cpu()}
        timing["wall_work"] = time.perf_counter() - start
        out.with_suffix(".json").write_text(json.dumps(timing))


def _fill(smk: Any, stage: str, message: str) -> None:
    from spa.pipeline.outputs import get_stage

    kinds = {o.key: o.kind for o in get_stage(stage).outputs}
    for key, path in smk.output.items():
        if key != "status":
            write_placeholder(path, kinds.get(key, "data"), message)


def dataset_failures(
    results: str | Path, datasets: Iterable[str]
) -> dict[str, list[dict[str, Any]]]:
    """The failed stages of each dataset (first failure first), from the status files.

    Returns
    -------
    dict
        Dataset -> its failed status records (empty datasets are left out); a stage skipped
        because of an earlier one is listed after it.
    """
    from spa.pipeline.outputs import STAGES

    order = [s.name for s in STAGES if s.per_dataset]
    out: dict[str, list[dict[str, Any]]] = {}
    for name in datasets:
        folder = Path(results) / name / STATUS_DIR
        failed = []
        for stage in order:
            status = read_status(folder / f"{stage}.json")
            if status is not None and not status.get("ok", False):
                failed.append(status)
        if failed:
            out[name] = failed
    return out


def dataset_statuses(results: str | Path, dataset: str) -> dict[str, dict[str, Any] | None]:
    """Every dataset stage's status record (None: the stage did not run), in stage order.

    Examples
    --------
    >>> dataset_statuses("nowhere", "d1")["identify"] is None
    True
    """
    from spa.pipeline.outputs import STAGES

    folder = Path(results) / dataset / STATUS_DIR
    return {s.name: read_status(folder / f"{s.name}.json") for s in STAGES if s.per_dataset}


def failure_summary(failures: Mapping[str, list[dict[str, Any]]]) -> str:
    """One paragraph per failed dataset: the stage that failed, whose fault (the data's,
    the data's lack on data that passed validation, or the stage's: :func:`fault_of`) and
    its first errors."""
    lines = []
    for name, records in failures.items():
        first = next((r for r in records if not r.get("upstream")), records[0])
        fault = first.get("fault")
        whose = {
            "data": " (the data: fix it)",
            "lacking": " (validation passed; the data lack what the stage needs)",
            "stage": " (the stage, not the data)",
        }
        lines.append(f"dataset {name}: stage {first['stage']} failed{whose.get(fault, '')}")
        lines += [f"  {e}" for e in first.get("errors", [])[:5]]
        skipped = [r["stage"] for r in records if r.get("upstream")]
        if skipped:
            lines.append(f"  (skipped for it: {', '.join(skipped)})")
    return "\n".join(lines)


def reuse_summary(results: str | Path, datasets: Iterable[str]) -> dict[str, dict[str, str]]:
    """How each dataset stage of the last run came: ``"reused"`` (restored from the results'
    store, :mod:`spa.pipeline.reuse`) or ``"computed"``, from the status files; stages
    whose status says neither (a stage of a job that keeps no store) are left out.

    Examples
    --------
    >>> reuse_summary("nowhere", ["d1"])
    {'d1': {}}
    """
    out: dict[str, dict[str, str]] = {}
    for name in datasets:
        records = dataset_statuses(results, name)
        out[name] = {
            stage: str(record["reuse"])
            for stage, record in records.items()
            if record is not None and record.get("reuse") in ("reused", "computed")
        }
    return out
