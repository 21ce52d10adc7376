"""Guards that keep a user's recordings safe from the pipeline's own writes.

A bench recording is irreplaceable. Snakemake deletes an output folder before the job that
writes it, so a results folder that overlaps a dataset folder would destroy raw data; an
ingest into another dataset's folder would overwrite it. These checks run before anything is
written:

- :func:`check_results_dir`: the workflow's ``results`` folder (at the start of every run);
- :func:`check_ingest_output`: the output folder of ``spa ingest`` (and of the ingest API);
- :func:`check_dataset_names`: dataset names that would collide with the results folder's own
  entries (``analytic/``, ``logs/``, ``report.html``).
"""

from __future__ import annotations

import os
from collections.abc import Iterable
from pathlib import Path

__all__ = [
    "INGEST_MARKER",
    "RESERVED_NAMES",
    "UnsafePathError",
    "check_dataset_names",
    "check_ingest_output",
    "check_results_dir",
    "dataset_folders",
]

#: Written into a folder by every ingest: marks it as an ingest output that may be refilled.
INGEST_MARKER = ".spa-ingest"

#: Names the results folder uses for itself; no dataset may be called so.
RESERVED_NAMES = frozenset(
    {"analytic", "index", "logs", "overview.csv", "overview.png", "overview.svg", "report"}
    | {"report.html", "status.yaml"}
)

SPEC_FILE = "dataset.yaml"


class UnsafePathError(ValueError):
    """A folder the pipeline was asked to write to could destroy or mix up recordings."""


def _resolve(path: str | os.PathLike[str]) -> Path:
    return Path(os.path.abspath(os.path.expanduser(os.fspath(path)))).resolve()


def dataset_folders(raw_dir: str | os.PathLike[str]) -> list[Path]:
    """The folders directly under ``raw_dir`` that hold a ``dataset.yaml``, resolved."""
    root = _resolve(raw_dir)
    if not root.is_dir():
        return []
    return sorted(p.parent.resolve() for p in root.glob(f"*/{SPEC_FILE}"))


def _inside_dataset(target: Path) -> Path | None:
    """The nearest folder at or above ``target`` holding a ``dataset.yaml``, if any."""
    for folder in (target, *target.parents):
        if (folder / SPEC_FILE).is_file():
            return folder
    return None


def check_results_dir(
    results: str | os.PathLike[str] | None,
    raw_dir: str | os.PathLike[str],
    datasets: Iterable[str | os.PathLike[str]] = (),
) -> Path:
    """Refuse a results folder that could overwrite or delete recordings.

    Parameters
    ----------
    results : path-like
        The configured results folder (config key ``results``).
    raw_dir : path-like
        The bench datasets' folder (config key ``datasets.raw_dir``).
    datasets : iterable of path-like, optional
        Further dataset folders (by default those of ``raw_dir`` are checked).

    Returns
    -------
    pathlib.Path
        The results folder, resolved.

    Raises
    ------
    UnsafePathError
        If ``results`` is empty, a file-system root, the home folder, equal to or inside
        ``raw_dir`` or a dataset folder, or a folder that contains ``raw_dir``. The message
        names the key and both folders.

    Examples
    --------
    >>> check_results_dir("raw", "raw")  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    spa.pipeline.safety.UnsafePathError: config results: 'raw' is the raw-data folder ...
    """
    if results is None or not str(os.fspath(results)).strip():
        raise UnsafePathError(
            "config results: empty; give the folder that receives the results, e.g. "
            "`results: results`"
        )
    target = _resolve(results)
    raw = _resolve(raw_dir)
    where = f"config results: {os.fspath(results)!r}"
    if target == Path(target.anchor):
        raise UnsafePathError(f"{where} is the file-system root {target}; choose a folder")
    if target == _resolve("~"):
        raise UnsafePathError(f"{where} is the home folder {target}; choose a sub-folder")
    if target == raw:
        raise UnsafePathError(
            f"{where} is the raw-data folder datasets.raw_dir ({raw}); results must go "
            "elsewhere, or Snakemake would delete recordings"
        )
    if target.is_relative_to(raw):
        raise UnsafePathError(
            f"{where} ({target}) is inside the raw-data folder datasets.raw_dir ({raw}); "
            "results must go elsewhere, or Snakemake would delete recordings"
        )
    if raw.is_relative_to(target):
        raise UnsafePathError(
            f"{where} ({target}) contains the raw-data folder datasets.raw_dir ({raw}); "
            "choose a results folder beside it, e.g. `results: results`"
        )
    for folder in [*dataset_folders(raw_dir), *(_resolve(d) for d in datasets)]:
        if target == folder or target.is_relative_to(folder) or folder.is_relative_to(target):
            raise UnsafePathError(
                f"{where} ({target}) overlaps the dataset folder {folder}; results must go "
                "elsewhere, or Snakemake would delete recordings"
            )
    holder = _inside_dataset(target)
    if holder is not None:
        raise UnsafePathError(
            f"{where} ({target}) is inside the dataset folder {holder} (it holds a "
            f"{SPEC_FILE}); results must go elsewhere"
        )
    return target


def check_ingest_output(out_dir: str | os.PathLike[str], dataset: str | os.PathLike[str]) -> Path:
    """Refuse an ingest output folder that is raw data or holds something else.

    Parameters
    ----------
    out_dir : path-like
        Where the run tables would go.
    dataset : path-like
        The dataset folder being ingested.

    Returns
    -------
    pathlib.Path
        ``out_dir``, resolved.

    Raises
    ------
    UnsafePathError
        If ``out_dir`` is the dataset folder or inside it, the folder holding the dataset
        (``raw/``) or inside it, at or inside any folder holding a ``dataset.yaml``, or an
        existing non-empty folder without the :data:`INGEST_MARKER` of an earlier ingest.
    """
    target = _resolve(out_dir)
    source = _resolve(dataset)
    where = f"output folder {os.fspath(out_dir)!r}"
    if target == source or target.is_relative_to(source):
        raise UnsafePathError(
            f"{where} is inside the dataset folder {source}; ingest never writes into raw/"
        )
    if target.is_relative_to(source.parent):
        raise UnsafePathError(
            f"{where} ({target}) is inside {source.parent}, the folder that holds the dataset "
            f"{source.name}: that is raw data (another dataset's folder, or a new one beside "
            "it); write the run tables elsewhere, e.g. results/<name>/runs"
        )
    holder = _inside_dataset(target)
    if holder is not None:
        raise UnsafePathError(
            f"{where} ({target}) is inside the dataset folder {holder} (it holds a "
            f"{SPEC_FILE}); ingest never writes into raw/"
        )
    if target.is_file():
        raise UnsafePathError(f"{where} is a file, not a folder")
    if target.is_dir() and any(target.iterdir()) and not (target / INGEST_MARKER).exists():
        raise UnsafePathError(
            f"{where} ({target}) is not empty and is not the output of an earlier ingest (no "
            f"{INGEST_MARKER} marker); give an empty or new folder"
        )
    return target


def check_dataset_names(names: Iterable[str]) -> None:
    """Refuse dataset names that the results folder uses for itself.

    Raises
    ------
    UnsafePathError
        If a name is one of :data:`RESERVED_NAMES` (case-insensitively); the message names it.

    Examples
    --------
    >>> check_dataset_names(["sim", "bench1"])
    >>> check_dataset_names(["logs"])  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    spa.pipeline.safety.UnsafePathError: dataset name 'logs' is reserved ...
    """
    for name in names:
        if name.lower() in RESERVED_NAMES:
            raise UnsafePathError(
                f"dataset name {name!r} is reserved for the results folder's own entries "
                f"({', '.join(sorted(RESERVED_NAMES))}); rename the folder or the simulated "
                "dataset, or list it under datasets.exclude"
            )
