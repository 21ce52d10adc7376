"""A change reruns what depends on it: each stage of a shared job is reused when nothing it
reads has changed.

A dataset's analysis is one Snakemake job (:mod:`spa.pipeline.jobs`), and Snakemake reruns
a job whose parameters or code changed, after deleting every output it declares. So the
results of each stage are also kept in a content-addressed store under the results folder,
``results/.store/<stage>/<digest>/``, which Snakemake does not know about and never deletes.
Before a stage runs, the job computes its digest (:func:`stage_digest`) from everything the
stage can see:

- the content of every file it reads: the job's inputs (the dataset's run tables) and the
  outputs of the earlier stages it declares it reads (:attr:`Stage.reads
  <spa.pipeline.stage_types.Stage.reads>`), hashed after those stages ran or were restored,
  and the raw files it names (:attr:`~spa.pipeline.stage_types.Stage.raw_files`);
- its settings: its config section (``cfg``), the job parameters it declares
  (:attr:`~spa.pipeline.stage_types.Stage.params`: it sees those alone,
  :func:`spa.pipeline.jobs.stage_job`), the dataset's name, and the paths of its outputs
  (which of them the job draws);
- the code: the source of the whole ``spa`` package (:func:`spa.io.package_digest`), the
  stage's script, the Python version and the versions of the libraries the science runs on.

When the store holds an entry with that digest whose files still have the checksums recorded
when it was written, the stage's outputs are copied from it and the stage does not run; else it
runs, and its outputs go into the store (hard links where the file system allows: no copy). The
digest follows content, not modification times, so a stage whose inputs were recomputed to the
same bytes is reused too (a new ``tuning:`` option that leaves the recommendation unchanged
reruns tune alone). Each stage's status file says which (``"reuse": "reused"`` or
``"computed"``); the status's other fields and every other output are the same bytes either way.

Why a store rather than outputs marked ``update()``: Snakemake removes a job's outputs before
running it, a rerun of a shared job must restore the stages it does not recompute, and an
``update()`` output is never removed, so a failed or interrupted job could leave an old output
beside new ones with nothing to tell them apart; a store entry is written completely (in a
temporary folder, then renamed) or not at all, and the outputs are always the job's own.

Config ``reuse: false`` (``snakemake --forceall --config reuse=False``) recomputes every stage
and refreshes the store; deleting ``results/.store`` loses nothing but the reuse.
"""

from __future__ import annotations

import functools
import hashlib
import json
import os
import shutil
import sys
import tempfile
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

from spa.pipeline.store import MEMO, STORE

__all__ = [
    "JOB_GC_THRESHOLD",
    "LIBRARIES",
    "Store",
    "code_digest",
    "file_digest",
    "run_job",
    "run_or_reuse",
    "stage_digest",
]

LIBRARIES = ("numpy", "scipy", "pandas", "pyarrow", "matplotlib", "numba", "PyYAML")
"""Distributions whose version is part of every digest: an upgrade recomputes."""

JOB_GC_THRESHOLD = (10_000, 10, 10)
"""The cyclic garbage collector's thresholds in a shared job (Python's default: 700, 10, 10).

A job's imports leave some 200 000 tracked objects, and its stages allocate millions of
short-lived ones (a figure's ticks and texts, tables); at the default, a collection of the
youngest generation runs every 700 net allocations and each tenth of those scans the middle
one. Fourteen times fewer collections cut the collector's time in the example's analysis job
from 0.65-1.0 to 0.34-0.46 CPU-s with figures and from 0.26 to 0.12 without, its peak memory
unchanged (``benchmarks/README.md``, "What every process pays"). Garbage is collected
all the same, and nothing a stage computes depends on when."""

_STATUS_KEY = "status"
"""The output key of a stage's status file (:func:`spa.pipeline.status.write_status`)."""

_REUSE = "reuse"
"""The status field saying whether the stage was ``"reused"`` or ``"computed"``."""


def file_digest(path: str | Path, status: bool = False) -> str:
    """SHA-256 of a file's bytes, or of a folder's files (names and bytes, sorted).

    Parameters
    ----------
    path : path-like
        A file or a folder; a missing one has the digest of ``"missing"``.
    status : bool
        A status file: its ``"reuse"`` field is left out (it says how the file came, not
        what the stage found).

    Examples
    --------
    >>> file_digest("no/such/file") == hashlib.sha256(b"missing").hexdigest()
    True
    """
    p = Path(path)
    h = hashlib.sha256()
    if p.is_dir():
        for child in sorted(q for q in p.rglob("*") if q.is_file()):
            h.update(child.relative_to(p).as_posix().encode() + b"\0")
            h.update(_sha(child).encode() + b"\0")
        return h.hexdigest()
    if not p.is_file():
        return hashlib.sha256(b"missing").hexdigest()
    if status:
        try:
            record = json.loads(p.read_text())
        except ValueError:
            return _sha(p)
        if isinstance(record, dict):
            record.pop(_REUSE, None)
            return hashlib.sha256(json.dumps(record, sort_keys=True).encode()).hexdigest()
    return _sha(p)


def _sha(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def code_digest(script: str | Path | None = None, package: str | None = None) -> str:
    """The digest of the code a stage runs: the ``spa`` package's source, the script's,
    the Python version and :data:`LIBRARIES`' versions.

    ``package``: :func:`spa.io.package_digest` when already taken (once a job).

    Examples
    --------
    >>> len(code_digest())
    64
    """
    from spa.io import package_digest

    h = hashlib.sha256()
    package = package_digest() if package is None else package
    h.update(package.encode() + b"\0" + sys.version.encode() + b"\0")
    h.update(_versions(LIBRARIES).encode())
    if script is not None:
        h.update(Path(script).read_bytes())
    return h.hexdigest()


@functools.lru_cache(maxsize=4)
def _versions(names: tuple[str, ...]) -> str:
    """``name==version`` of each distribution (``absent`` when not installed), once a job."""
    from importlib.metadata import PackageNotFoundError, version

    out = []
    for name in names:
        try:
            out.append(f"{name}=={version(name)}")
        except PackageNotFoundError:
            out.append(f"{name} absent")
    return "\0".join(out)


def _canonical(value: Any) -> Any:
    """Plain data for JSON: mappings as sorted dicts, sequences as lists, paths as text."""
    if isinstance(value, Mapping):
        return {str(k): _canonical(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_canonical(v) for v in value]
    if isinstance(value, (str, int, float, bool)) or value is None:
        return value
    return str(value)


def stage_digest(
    view: Any,
    stage: str,
    code: str,
    reads: Mapping[str, str | Path],
    raw: Mapping[str, str | Path] = {},
    results: str | Path | None = None,
    digest: Callable[[str | Path, bool], str] = file_digest,
) -> str:
    """The digest of one stage of a shared job: what it reads, its settings, its code.

    Parameters
    ----------
    view : types.SimpleNamespace
        The stage's view of the job (:func:`spa.pipeline.jobs.stage_job`): its ``params``
        (``cfg`` and the parameters it declares), ``wildcards`` and ``output``.
    stage : str
        The stage.
    code : str
        :func:`code_digest` of its script.
    reads : mapping of str to path
        Every input file or folder it reads, by key (``status`` keys are status files).
    raw : mapping of str to path
        The raw files it reads itself, by name.
    results : path-like, optional
        The results folder: output paths are taken relative to it (a moved results folder
        keeps its store).
    digest : callable
        ``(path, is_status) -> hex``: :func:`file_digest`, or a memo of it.

    Returns
    -------
    str
        64 hex digits.
    """
    from spa.pipeline.outputs import get_stage

    root = Path(results) if results is not None else None

    def rel(path: Any) -> str:
        p = Path(str(path))
        inside = root is not None and p.is_relative_to(root)
        return p.relative_to(root).as_posix() if inside else str(path)

    record = {
        # outputs may name the results folder (tune's recommendation names its source)
        "results": str(root.resolve()) if root is not None else None,
        "stage": stage,
        "code": code,
        "wildcards": _canonical(dict(view.wildcards.items())),
        "params": _canonical(dict(view.params.items())),
        "outputs": {k: rel(v) for k, v in view.output.items()},
        "reads": {
            k: [rel(p), digest(p, k == _STATUS_KEY or k.endswith("__status"))]
            for k, p in reads.items()
        },
        "raw": {k: digest(p, False) for k, p in raw.items()},
        "kinds": {o.key: o.kind for o in get_stage(stage).outputs},
    }
    text = json.dumps(record, sort_keys=True, default=str)
    return hashlib.sha256(text.encode()).hexdigest()


class Store:
    """The content-addressed store of stage results: ``<root>/<stage>/<digest>/``.

    An entry holds ``manifest.json`` (each output key: a file or a folder and the sha256 of
    each of its files), the outputs under ``files/<key>`` and the stage's log as it was
    written. It is written in a temporary folder and renamed into place, so it is complete
    or absent; a file changed since (in place, through a hard link) fails its checksum and
    the entry is dropped.
    """

    def __init__(self, root: str | Path) -> None:
        self.root = Path(root)

    def entry(self, stage: str, digest: str) -> Path:
        """The folder of a stage's entry."""
        return self.root / stage / digest

    def restore(self, stage: str, digest: str, outputs: Mapping[str, str], log: str | None) -> bool:
        """Copy an entry's files into ``outputs`` (output key -> path) and its log into
        ``log``; False, and nothing written, when there is no sound entry.

        Every output key must be in the entry; a damaged entry is removed.
        """
        entry = self.entry(stage, digest)
        manifest = _read_manifest(entry)
        if manifest is None or set(manifest["outputs"]) != set(outputs):
            return False
        for key, item in manifest["outputs"].items():
            for rel, sha in item["files"].items():
                stored = entry / "files" / key / rel if item["dir"] else entry / "files" / key
                if not stored.is_file() or _sha(stored) != sha:
                    shutil.rmtree(entry, ignore_errors=True)
                    return False
        for key, item in manifest["outputs"].items():
            target = Path(outputs[key])
            if target.is_dir() and not target.is_symlink():
                shutil.rmtree(target)
            elif target.exists() or target.is_symlink():
                target.unlink()
            if item["dir"]:
                target.mkdir(parents=True)
                for rel in item["files"]:
                    dest = target / rel
                    dest.parent.mkdir(parents=True, exist_ok=True)
                    shutil.copyfile(entry / "files" / key / rel, dest)
            else:
                target.parent.mkdir(parents=True, exist_ok=True)
                shutil.copyfile(entry / "files" / key, target)
        if log is not None:
            stored_log = entry / "stage.log"
            text = stored_log.read_text(errors="replace") if stored_log.is_file() else ""
            Path(log).parent.mkdir(parents=True, exist_ok=True)
            Path(log).write_text(text + f"reused: {stage} from {entry}\n")
        return True

    def save(self, stage: str, digest: str, outputs: Mapping[str, str], log: str | None) -> bool:
        """Put a stage's outputs (output key -> path, all present) and log into the store;
        False when an output is missing or the entry could not be written (the run goes on)."""
        final = self.entry(stage, digest)
        try:
            final.parent.mkdir(parents=True, exist_ok=True)
            tmp = Path(tempfile.mkdtemp(prefix=f".{digest[:12]}-", dir=final.parent))
        except OSError:
            return False
        try:
            manifest: dict[str, Any] = {"stage": stage, "outputs": {}}
            for key, path in outputs.items():
                src = Path(path)
                dest = tmp / "files" / key
                dest.parent.mkdir(parents=True, exist_ok=True)
                if src.is_dir():
                    files = {}
                    for child in sorted(q for q in src.rglob("*") if q.is_file()):
                        rel = child.relative_to(src).as_posix()
                        (dest / rel).parent.mkdir(parents=True, exist_ok=True)
                        _link_or_copy(child, dest / rel)
                        files[rel] = _sha(dest / rel)
                    manifest["outputs"][key] = {"dir": True, "files": files}
                elif src.is_file():
                    _link_or_copy(src, dest)
                    manifest["outputs"][key] = {"dir": False, "files": {"": _sha(dest)}}
                else:
                    raise FileNotFoundError(path)
            if log is not None and Path(log).is_file():
                shutil.copyfile(log, tmp / "stage.log")
            (tmp / "manifest.json").write_text(json.dumps(manifest, indent=1, sort_keys=True))
            if final.exists():
                shutil.rmtree(final, ignore_errors=True)
            os.rename(tmp, final)
            return True
        except OSError:
            shutil.rmtree(tmp, ignore_errors=True)
            return False


def _read_manifest(entry: Path) -> dict[str, Any] | None:
    try:
        manifest = json.loads((entry / "manifest.json").read_text())
    except (OSError, ValueError):
        return None
    return manifest if isinstance(manifest, dict) and "outputs" in manifest else None


def _link_or_copy(src: Path, dest: Path) -> None:
    """A hard link of ``src`` at ``dest``, or a copy where links are refused."""
    try:
        os.link(src, dest)
    except OSError:
        shutil.copyfile(src, dest)


def _mark(status_path: str | Path, how: str) -> None:
    """Write ``"reuse": how`` into a status file, as a new file (a hard link into the store
    keeps the stored bytes)."""
    path = Path(status_path)
    try:
        record = json.loads(path.read_text())
    except (OSError, ValueError):
        return
    if not isinstance(record, dict):
        return
    record[_REUSE] = how
    tmp = path.with_name(f".{path.name}.tmp")
    tmp.write_text(json.dumps(record, indent=1) + "\n")
    os.replace(tmp, path)


def run_or_reuse(
    view: Any,
    stage: str,
    script: str | Path,
    run: Callable[[], None],
    *,
    results: str | Path,
    reads: Mapping[str, str | Path],
    raw: Mapping[str, str | Path] = {},
    enabled: bool = True,
    digest: Callable[[str | Path, bool], str] = file_digest,
    package: str | None = None,
) -> str:
    """Restore a stage's outputs from the store when its digest is there, else run it and
    store them.

    Parameters
    ----------
    view : types.SimpleNamespace
        The stage's view of the job (:func:`spa.pipeline.jobs.stage_job`).
    stage : str
        The stage.
    script : path-like
        Its script (part of the digest).
    run : callable
        Runs the stage (its script with ``view`` as ``snakemake``).
    results : path-like
        The results folder; the store is ``<results>/.store``.
    reads : mapping of str to path
        Every file or folder the stage reads (the outputs of
        :func:`spa.pipeline.jobs.read_stages` and the job's inputs), by key.
    raw : mapping of str to path
        Raw files the stage reads itself.
    enabled : bool
        False (config ``reuse: false``): always run, and refresh the store.
    digest : callable
        ``(path, is_status) -> hex`` (:func:`file_digest` or a memo of it).
    package : str, optional
        :func:`spa.io.package_digest`, when the job already took it.

    Returns
    -------
    str
        ``"reused"`` or ``"computed"``, also written into the stage's status file.
    """
    code = code_digest(script, package)
    key = stage_digest(view, stage, code, reads, raw, results, digest)
    store = Store(Path(results) / STORE)
    outputs = dict(view.output.items())
    log = view.log[0] if len(view.log) else None
    how = "computed"
    if enabled and store.restore(stage, key, outputs, log):
        how = "reused"
    else:
        run()
        store.save(stage, key, outputs, log)
    if _STATUS_KEY in outputs:
        _mark(outputs[_STATUS_KEY], how)
    return how


def run_job(smk: Any, scriptdir: str | Path) -> dict[str, str]:
    """Run a shared job's stages in turn (``params.stages``: stage -> script name), each its
    own script seeing :func:`spa.pipeline.jobs.stage_job`'s view as ``snakemake``; with
    ``params.store`` (the analysis job), through :func:`run_or_reuse`, unless config
    ``reuse`` is false; then too, the parts of a stage's work that depend on fewer settings
    than the stage are kept in ``<results>/.store/memo`` (:mod:`spa._memo`). The stages run
    with the garbage collector's thresholds at :data:`JOB_GC_THRESHOLD`; the caller's are
    restored after them.

    Returns
    -------
    dict
        Stage -> ``"reused"``, ``"computed"`` or, without a store, ``"run"``.
    """
    import gc
    import runpy

    from spa._memo import use_folder
    from spa.io import package_digest
    from spa.pipeline.jobs import read_files, stage_job
    from spa.pipeline.outputs import dataset_folder, get_stage

    store = bool(smk.params.get("store"))
    enabled = bool((getattr(smk, "config", None) or {}).get("reuse", True))
    package = package_digest() if store else None  # the job's code does not change under it
    memo: dict[tuple[str, bool], str] = {}

    def digest(path: str | Path, status: bool = False) -> str:
        """:func:`file_digest`, once per file and job (earlier stages' outputs stay put)."""
        key = (str(path), status)
        if key not in memo:
            memo[key] = file_digest(path, status)
        return memo[key]

    how = {}
    previous = gc.get_threshold()
    gc.set_threshold(*JOB_GC_THRESHOLD)
    try:
        for stage, script in smk.params.stages.items():
            view = stage_job(smk, stage)
            path = Path(scriptdir) / f"{script}.py"

            def run(path: Path = path, view: Any = view) -> None:
                runpy.run_path(str(path), init_globals={"snakemake": view}, run_name="__main__")

            if not store:
                run()
                how[stage] = "run"
                continue
            folder = dataset_folder(stage, dict(view.output.items()))
            raw = Path(str(smk.params.get("raw_dir", ""))) / str(smk.wildcards.dataset)
            memo_folder = folder.parent / STORE / MEMO if enabled else None
            use_folder(memo_folder, code_digest(None, package))
            how[stage] = run_or_reuse(
                view,
                stage,
                path,
                run,
                results=folder.parent,
                reads=read_files(smk, stage),
                raw={name: raw / name for name in get_stage(stage).raw_files},
                enabled=enabled,
                digest=digest,
                package=package,
            )
    finally:
        gc.set_threshold(*previous)
        use_folder(None)  # the store is this job's: nothing after it memoises into it
    return how
