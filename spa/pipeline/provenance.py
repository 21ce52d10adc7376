"""What a result was made from: content digests of raw datasets and indexes of run tables.

Snakemake decides what to rerun from modification times. A recording whose content changes
while its modification time goes back (restored from a backup, ``rsync -t``, copied from a
logger's card) would then never be re-ingested, and a file merely touched would be re-ingested
for nothing. The workflow therefore reads raw data through a per-dataset *manifest*
(:func:`write_manifest`): a small file listing every file of the dataset with its sha256,
rewritten only when a digest changed (:func:`dataset_digest` is a parameter of the rule that
writes it, so Snakemake reruns that rule exactly when the content changed).

Hashing every recording at every start would be slow for large datasets, so digests are
cached by (size, modification time, status-change time, inode): a file whose ``stat`` is
unchanged is not read again. The status-change time (``ctime``) cannot be set back by any
copy tool, so restored content is always re-hashed.

A folder of run tables is indexed (:func:`write_run_index`); :func:`damaged_run_folders` finds
folders that lost or changed a member since, so that the workflow rebuilds them.
"""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import stat as stat_module
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

__all__ = [
    "RUN_INDEX",
    "altered_outputs",
    "damaged_run_folders",
    "dataset_digest",
    "file_digests",
    "missing_outputs",
    "output_ledger",
    "record_outputs",
    "remove_altered_outputs",
    "remove_damaged_run_folders",
    "write_manifest",
    "write_run_index",
]

#: File name of the index written into every folder of run tables.
RUN_INDEX = "index.json"

_CHUNK = 1 << 20


def _sha256(path: Path) -> str:
    h = hashlib.sha256()
    with path.open("rb") as fh:
        while chunk := fh.read(_CHUNK):
            h.update(chunk)
    return h.hexdigest()


def _stat_key(st: os.stat_result) -> list[int]:
    return [st.st_size, st.st_mtime_ns, st.st_ctime_ns, st.st_ino]


_MEMO: dict[str, tuple[list[int], dict[str, Any]]] = {}
"""Caches read or written by this process, by path, with the ``stat`` they had: the DAG build
digests every dataset against one cache, which is parsed once, not once per dataset."""


def _load_cache(cache: Path | None) -> dict[str, Any]:
    if cache is None:
        return {}
    try:
        stat = _stat_key(cache.stat())
    except OSError:
        return {}
    memo = _MEMO.get(str(cache))
    if memo is not None and memo[0] == stat:
        return memo[1]
    try:
        data = json.loads(cache.read_text())
    except (OSError, ValueError):
        return {}
    data = data if isinstance(data, dict) else {}
    _MEMO[str(cache)] = (stat, data)
    return data


def _save_cache(cache: Path, data: Mapping[str, Any], prune: bool = False) -> None:
    """Write a cache, best effort: a cache that cannot be written (a full disk, a file-size
    limit) costs only time, never the run. With ``prune``, entries of files that no longer
    exist (temporary folders) are dropped."""
    if prune:
        data = {k: v for k, v in data.items() if os.path.exists(k.removeprefix("names:"))}
    tmp = cache.with_name(f".{cache.name}.{os.getpid()}.tmp")
    try:
        cache.parent.mkdir(parents=True, exist_ok=True)
        tmp.write_text(json.dumps(data, sort_keys=True))
        os.replace(tmp, cache)
        _MEMO[str(cache)] = (_stat_key(cache.stat()), dict(data))
    except OSError:
        tmp.unlink(missing_ok=True)


def _named_files(root: Path, known: dict[str, Any]) -> tuple[list[str] | None, bool]:
    """The files ``dataset.yaml`` names (itself first), or None for a folder without one;
    and whether ``known`` was updated.

    Only ``runs[].file`` is read, with the contract's own loader (size and alias limits); a
    ``dataset.yaml`` that cannot be read names itself alone (the ingest then says why). The
    list is remembered in ``known`` (the digest cache) by the ``stat`` of ``dataset.yaml``.
    """
    from spa.datasets.contract import SPEC_FILE

    spec = root / SPEC_FILE
    try:
        if not spec.is_file():
            return None, False
        stat = _stat_key(spec.stat())
    except OSError:
        return [SPEC_FILE], False
    key = f"names:{spec.resolve()}"
    hit = known.get(key)
    if isinstance(hit, dict) and hit.get("stat") == stat and isinstance(hit.get("names"), list):
        return [str(n) for n in hit["names"]], False
    names = _read_named_files(spec)
    known[key] = {"stat": stat, "names": names}
    return names, True


def _read_named_files(spec: Path) -> list[str]:
    from spa.datasets.contract import SPEC_FILE
    from spa.datasets.yaml_loader import MAX_SPEC_BYTES, _UniqueKeyLoader

    try:
        if spec.stat().st_size > MAX_SPEC_BYTES:
            return [SPEC_FILE]
        import yaml

        doc = yaml.load(spec.read_text(encoding="utf-8"), Loader=_UniqueKeyLoader)
    except (OSError, ValueError, yaml.YAMLError):
        return [SPEC_FILE]
    runs = doc.get("runs") if isinstance(doc, dict) else None
    files = {
        str(run["file"])
        for run in (runs if isinstance(runs, list) else [])
        if isinstance(run, dict) and isinstance(run.get("file"), str) and run["file"].strip()
    }
    return [SPEC_FILE, *sorted(files - {SPEC_FILE})]


def _all_files(root: Path) -> list[str]:
    """Every file under ``root`` but hidden files and folders, as relative POSIX paths."""
    found = []
    for dirpath, dirnames, filenames in os.walk(root):
        dirnames[:] = sorted(d for d in dirnames if not d.startswith("."))
        for name in sorted(filenames):
            if not name.startswith("."):
                found.append((Path(dirpath) / name).relative_to(root).as_posix())
    return found


def file_digests(folder: str | os.PathLike[str], cache: str | os.PathLike[str] | None = None):
    """The sha256 of every file of a dataset folder that its ``dataset.yaml`` names.

    Files that ``dataset.yaml`` does not name (notes, a stray pipe or dangling link, a name in
    an unknown encoding) are not read: they cannot change a result. A folder without a
    ``dataset.yaml`` stands for all its files (hidden files and folders skipped). A named
    file that is not a regular file (a pipe, a device: never opened) or cannot be read gets a
    marker instead of a digest, so the digest is still defined; ingesting the dataset then
    fails with that file named, and for that dataset alone.

    Parameters
    ----------
    folder : path-like
        A dataset folder; only read.
    cache : path-like, optional
        A JSON file remembering digests by path and ``stat`` (size, mtime, ctime, inode);
        created or updated when a digest had to be computed. Never inside ``folder``.

    Returns
    -------
    dict
        Path relative to ``folder`` (POSIX form) -> sha256 hex digest (or a marker such as
        ``"not a regular file"``), sorted by path.
    """
    root = Path(folder)
    cache_path = Path(cache) if cache is not None else None
    if cache_path is not None and cache_path.resolve().is_relative_to(root.resolve()):
        raise ValueError(f"cache {cache_path} must not be inside the dataset folder {root}")
    known = _load_cache(cache_path)
    out: dict[str, str] = {}
    names, changed = _named_files(root, known)
    inside = root.resolve()
    for rel in _all_files(root) if names is None else names:
        path = root / rel
        try:
            st = path.stat()
            if not path.resolve().is_relative_to(inside):
                out[rel] = "outside the dataset folder"
                continue
        except (OSError, ValueError) as exc:
            out[rel] = f"cannot be read: {getattr(exc, 'strerror', None) or exc}"
            continue
        if not stat_module.S_ISREG(st.st_mode):
            out[rel] = "not a regular file"
            continue
        key = os.fsencode(path.resolve()).decode("utf-8", "backslashreplace")
        stat = _stat_key(st)
        hit = known.get(key)
        if isinstance(hit, dict) and hit.get("stat") == stat:
            out[rel] = str(hit["sha256"])
            continue
        try:
            digest = _sha256(path)
        except OSError as exc:
            out[rel] = f"cannot be read: {exc.strerror}"
            continue
        known[key] = {"stat": stat, "sha256": digest}
        out[rel] = digest
        changed = True
    if changed and cache_path is not None:
        _save_cache(cache_path, known, prune=True)
    return dict(sorted(out.items()))


def dataset_digest(
    folder: str | os.PathLike[str], cache: str | os.PathLike[str] | None = None
) -> str:
    """One sha256 over the names and contents of every file of a dataset folder.

    It changes exactly when a file is added, removed, renamed or its content changes; not
    when a modification time alone moves. See :func:`file_digests` for ``cache``.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> d = pathlib.Path(tempfile.mkdtemp())
    >>> _ = (d / "a.csv").write_text("t,p\\n0,1\\n")
    >>> before = dataset_digest(d)
    >>> os.utime(d / "a.csv", ns=(0, 0))                # only the time moves
    >>> dataset_digest(d) == before
    True
    >>> _ = (d / "a.csv").write_text("t,p\\n0,2\\n")
    >>> os.utime(d / "a.csv", ns=(0, 0))                # new content, old time
    >>> dataset_digest(d) == before
    False
    """
    return _combined(file_digests(folder, cache))


def _combined(files: Mapping[str, str]) -> str:
    """One sha256 over (relative path, sha256) pairs, in their order."""
    h = hashlib.sha256()
    for rel, digest in files.items():
        h.update(rel.encode("utf-8", "surrogateescape") + b"\0" + digest.encode() + b"\0")
    return h.hexdigest()


def write_manifest(
    folder: str | os.PathLike[str],
    path: str | os.PathLike[str],
    cache: str | os.PathLike[str] | None = None,
) -> dict[str, Any]:
    """Write the manifest of a dataset folder: its digest and every file's sha256 (JSON).

    Returns
    -------
    dict
        What was written: ``{"folder", "digest", "files": {relative path: sha256}}``.
    """
    files = file_digests(folder, cache)
    manifest = {"folder": str(folder), "digest": _combined(files), "files": files}
    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(manifest, indent=1, sort_keys=True) + "\n")
    return manifest


def write_run_index(folder: str | os.PathLike[str], paths: Iterable[str | os.PathLike[str]]):
    """Record the run tables of a folder (name and size of each) in :data:`RUN_INDEX`."""
    root = Path(folder)
    members = {Path(p).name: Path(p).stat().st_size for p in paths}
    index = {"members": dict(sorted(members.items()))}
    (root / RUN_INDEX).write_text(json.dumps(index, indent=1, sort_keys=True) + "\n")
    return index


def damaged_run_folders(folders: Iterable[str | os.PathLike[str]]) -> dict[str, str]:
    """Folders of run tables that lost, changed or gained a member since they were written.

    Parameters
    ----------
    folders : iterable of path-like
        Folders written with :func:`write_run_index`; folders that do not exist, or have no
        index (an older results folder), are skipped.

    Returns
    -------
    dict
        Folder -> what is wrong with it (first problem found).
    """
    damaged: dict[str, str] = {}
    for folder in folders:
        root = Path(folder)
        index_path = root / RUN_INDEX
        if not index_path.is_file():
            continue
        try:
            members = json.loads(index_path.read_text())["members"]
        except (OSError, ValueError, KeyError, TypeError):
            damaged[str(root)] = f"unreadable {RUN_INDEX}"
            continue
        for name, size in members.items():
            member = root / name
            if not member.is_file():
                damaged[str(root)] = f"run table {name} is missing"
                break
            if member.stat().st_size != size:
                damaged[str(root)] = f"run table {name} changed size"
                break
        else:
            extra = sorted({p.name for p in root.glob("*.parquet")} - set(members))
            if extra:
                damaged[str(root)] = f"run table {extra[0]} was not written by this run"
    return damaged


def remove_damaged_run_folders(
    results: str | os.PathLike[str], folders: Iterable[str | os.PathLike[str]]
) -> dict[str, str]:
    """Delete the damaged folders of run tables under ``results`` so that they are rebuilt.

    Only folders inside ``results`` that carry a :data:`RUN_INDEX` are ever removed: this is
    the pipeline's own output, which Snakemake would delete before rebuilding it anyway.

    Returns
    -------
    dict
        The folders removed -> why.
    """
    root = Path(results).resolve()
    damaged = damaged_run_folders(folders)
    for folder in damaged:
        path = Path(folder).resolve()
        if path.is_relative_to(root) and path != root and (path / RUN_INDEX).exists():
            shutil.rmtree(path)
    return damaged


def output_ledger(results: str | os.PathLike[str]) -> str:
    """Where :func:`record_outputs` keeps the record of a results folder.

    ``.snakemake/spa/outputs-<digest of the folder's absolute path>.json``: one per results
    folder, beside Snakemake's own records.

    >>> output_ledger("results") == output_ledger(Path("results").resolve())
    True
    """
    key = hashlib.sha256(str(Path(results).resolve()).encode()).hexdigest()[:16]
    return str(Path(".snakemake") / "spa" / f"outputs-{key}.json")


def _output_files(paths: Iterable[str | os.PathLike[str]]) -> list[Path]:
    """The files of ``paths``: a folder stands for the regular files in it (not below)."""
    files: list[Path] = []
    for p in map(Path, paths):
        if p.is_dir():
            files += sorted(f for f in p.iterdir() if f.is_file() and f.name != RUN_INDEX)
        elif p.is_file():
            files.append(p)
    return files


def record_outputs(
    paths: Iterable[str | os.PathLike[str]], ledger: str | os.PathLike[str]
) -> dict[str, Any]:
    """Remember what the run's outputs are: size, modification time and sha256 of each.

    Called by the last job of ``reproduce-all`` (``check``), when every output has just been
    written; :func:`altered_outputs` compares against it when the next run starts. A file whose
    ``stat`` did not change since the previous record is not read again.

    Parameters
    ----------
    paths : iterable of path-like
        Every output of the run; a folder (of run tables) stands for its files.
    ledger : path-like
        The JSON file to write (outside the results folder's outputs).

    Returns
    -------
    dict
        Path -> ``{"stat": [size, mtime_ns], "sha256"}``, as written.
    """
    old = _load_cache(Path(ledger))
    record: dict[str, Any] = {}
    for path in _output_files(paths):
        st = path.stat()
        stat = [st.st_size, st.st_mtime_ns]
        hit = old.get(str(path))
        same = isinstance(hit, dict) and hit.get("stat") == stat
        record[str(path)] = {"stat": stat, "sha256": hit["sha256"] if same else _sha256(path)}
    _save_cache(Path(ledger), record)
    return record


def altered_outputs(ledger: str | os.PathLike[str]) -> dict[str, str]:
    """Outputs recorded by :func:`record_outputs` whose content changed since.

    A file whose size and modification time are as recorded is taken as unchanged (nothing is
    read); otherwise its sha256 decides, so that a file merely touched, or rewritten with the
    same bytes by a partial run, is not reported. Missing files are not reported here (the
    workflow asks for every missing output anyway).

    Returns
    -------
    dict
        Path -> why it is taken as altered.
    """
    out: dict[str, str] = {}
    for name, hit in _load_cache(Path(ledger)).items():
        path = Path(name)
        try:
            st = path.stat()
        except OSError:
            continue
        if not isinstance(hit, dict) or hit.get("stat") == [st.st_size, st.st_mtime_ns]:
            continue
        if not path.is_file() or _sha256(path) != hit.get("sha256"):
            out[name] = "changed since it was written"
    return out


def remove_altered_outputs(
    results: str | os.PathLike[str],
    ledger: str | os.PathLike[str],
    run_folders: Iterable[str | os.PathLike[str]] = (),
) -> dict[str, str]:
    """Delete the outputs under ``results`` that changed since they were written.

    A changed run table takes its whole folder (one of ``run_folders``) with it, since the
    folder is one output of its job; any other output is deleted alone. The workflow then
    finds them missing and rebuilds them, and what depends on them (see
    :func:`missing_outputs`). Nothing outside ``results`` is ever removed.

    Returns
    -------
    dict
        The paths removed -> why.
    """
    root = Path(results).resolve()
    folders = {Path(f).resolve() for f in run_folders}
    removed: dict[str, str] = {}
    for name, why in altered_outputs(ledger).items():
        path = Path(name).resolve()
        if not path.is_relative_to(root) or path == root:
            continue
        if path.parent in folders:
            if path.parent.is_dir():
                shutil.rmtree(path.parent)
            removed[str(Path(name).parent)] = f"run table {path.name} {why}"
        elif path.is_file():
            path.unlink()
            removed[name] = why
    return removed


def missing_outputs(
    paths: Iterable[str | os.PathLike[str]], downstream: Iterable[str | os.PathLike[str]] = ()
) -> list[str]:
    """Those of ``paths`` that do not exist; none when every one of ``downstream`` is missing.

    Snakemake does not rebuild a missing output whose downstream files are up to date (its
    issue 1978); the workflow names these as targets of ``reproduce-all`` so that their jobs
    rerun, and, their outputs being newer, every job downstream of them. When the files
    downstream of all of them (the report's and the check's) are all missing, their jobs run
    and ask for every missing file themselves: naming them again would only double the files
    the DAG resolves (a first run of 100 datasets: 5,000 files).

    Examples
    --------
    >>> missing_outputs(["no/a", "no/b"])
    ['no/a', 'no/b']
    >>> missing_outputs(["no/a", "no/b"], downstream=["no/report.html"])
    []
    """
    after = [str(p) for p in downstream]
    if after and not any(os.path.exists(p) for p in after):
        return []
    return [str(p) for p in paths if not os.path.exists(p)]
