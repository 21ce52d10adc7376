"""The dataset folders of ``raw/``: the sub-folders holding a ``dataset.yaml``."""

from __future__ import annotations

import os
from pathlib import Path

from spa.datasets.contract import SPEC_FILE

__all__ = ["find_datasets", "undecodable_datasets"]


def find_datasets(raw_dir: str | Path) -> list[str]:
    """Names of the dataset folders in ``raw_dir``: its sub-folders holding a ``dataset.yaml``.

    Parameters
    ----------
    raw_dir : str or path-like
        The folder of datasets, usually ``raw``. A missing folder holds no datasets.

    Returns
    -------
    list of str
        Sorted folder names (hidden folders, starting with ``.``, and names that are not
        UTF-8, :func:`undecodable_datasets`, are skipped).
    """
    return [name for name in _dataset_folders(raw_dir) if _is_text(name)]


def undecodable_datasets(raw_dir: str | Path) -> list[str]:
    """Folders of ``raw_dir`` holding a ``dataset.yaml`` whose names are not UTF-8 (a
    Windows zip's Latin-1, say): no dataset can be named so; shown with ``\\x`` escapes.

    They are left out of :func:`find_datasets`, so that one such folder stops nothing; the
    workflow warns about them.
    """
    return [
        os.fsencode(name).decode("utf-8", "backslashreplace")
        for name in _dataset_folders(raw_dir)
        if not _is_text(name)
    ]


def _is_text(name: str) -> bool:
    try:
        name.encode("utf-8")
    except UnicodeEncodeError:
        return False
    return True


def _dataset_folders(raw_dir: str | Path) -> list[str]:
    root = Path(raw_dir)
    if not root.is_dir():
        return []
    return sorted(
        p.name
        for p in root.iterdir()
        if p.is_dir() and not p.name.startswith(".") and (p / SPEC_FILE).is_file()
    )
