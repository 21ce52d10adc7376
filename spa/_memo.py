"""Arrays that a pure computation gave, kept between runs of the pipeline.

Inside a stage, a part of the work may depend on fewer settings than the stage: the tuning's
corners of the identification's 95 % box depend on the identified valve, the sweeps and the
ξ grid, not on the tuning's constraints, yet a ``tuning:`` change reruns the tuning stage.
:func:`memoised` keeps such a part's result in the results' store
(``results/.store/memo/<name>/<digest>.npy``), keyed by the SHA-256 of its arguments and of
the code (:func:`spa.pipeline.reuse.code_digest`: the whole ``spa`` package, the Python
version and the numerical libraries' versions), so an edit to ``spa/`` never serves an old
result. :func:`files_memoised` does the same for files a computation writes (a figure drawn
from the same data, :func:`spa.plots.save.draw`). The pipeline's analysis job sets the folder
(:func:`use_folder`); elsewhere (the command line, tests) nothing is kept and every call
computes.
"""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import tempfile
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

__all__ = ["files_memoised", "key_digest", "memoised", "use_folder"]

_FOLDER: list[Path | None] = [None]
_CODE: list[str | None] = [None]


def use_folder(folder: str | Path | None, code: str | None = None) -> None:
    """Keep results under ``folder`` from now on (None: keep nothing), keyed with ``code``,
    the digest of the code that computes them (:func:`spa.pipeline.reuse.code_digest`,
    taken by the caller once a job).

    Raises
    ------
    ValueError
        For a folder without the code's digest: a result kept without it could be served
        to edited code.
    """
    if folder is not None and not code:
        raise ValueError("use_folder: a folder needs the code's digest (code_digest())")
    _FOLDER[0] = Path(folder) if folder is not None else None
    _CODE[0] = code if folder is not None else None


def _code() -> str:
    """The code's digest given to :func:`use_folder`."""
    assert _CODE[0] is not None, "no memo folder in use"
    return _CODE[0]


def _plain(value: Any) -> Any:
    """JSON-ready data: mappings as lists of pairs in their order (the order may matter: a
    table's rows), sequences as lists, floats exact (repr)."""
    if isinstance(value, Mapping):
        return [[str(k), _plain(v)] for k, v in value.items()]
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    if isinstance(value, (bool, int, str)) or value is None:
        return value
    if isinstance(value, (float, np.floating)):
        return repr(float(value))
    if hasattr(value, "as_dict"):
        return _plain(value.as_dict())
    raise TypeError(f"memo key: {type(value).__name__} is not plain data")


def key_digest(name: str, key: Any, code: str) -> str:
    """The SHA-256 of a memoised computation's name, arguments and code.

    Examples
    --------
    >>> key_digest("x", {"a": 0.1}, "c") == key_digest("x", {"a": 0.1}, "c")
    True
    >>> key_digest("x", {"a": 0.1}, "c") == key_digest("x", {"a": 0.10000000000000002}, "c")
    False
    """
    text = json.dumps({"name": name, "key": _plain(key), "code": code}, sort_keys=True)
    return hashlib.sha256(text.encode()).hexdigest()


def memoised(name: str, key: Any, compute: Callable[[], npt.ArrayLike]) -> npt.NDArray[np.float64]:
    """``compute()`` as a float64 array, or the array it gave before for the same ``key``
    and code (only when a folder is set, :func:`use_folder`).

    Parameters
    ----------
    name : str
        What is computed (a folder of the memo).
    key : plain data
        Every argument the result depends on (mappings, sequences, numbers, text, objects
        with ``as_dict()``): equal keys must mean equal results under the same code.
    compute : callable
        The computation.

    Returns
    -------
    numpy.ndarray
        Bit for bit what ``compute()`` returns (``np.save`` / ``np.load``).
    """
    folder = _FOLDER[0]
    if folder is None:
        return np.asarray(compute(), dtype=np.float64)
    path = folder / name / f"{key_digest(name, key, _code())}.npy"
    try:
        return np.load(path, allow_pickle=False)
    except (OSError, ValueError):
        pass
    value = np.asarray(compute(), dtype=np.float64)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        handle, tmp = tempfile.mkstemp(prefix=".memo-", suffix=".npy", dir=path.parent)
        with os.fdopen(handle, "wb") as fh:
            np.save(fh, value, allow_pickle=False)
        os.replace(tmp, path)
    except OSError:  # a read-only store: the run goes on without it
        pass
    return value


def files_memoised(
    name: str, blob: bytes, paths: Sequence[str | Path], write: Callable[[], None]
) -> bool:
    """Put at ``paths`` the files ``write()`` wrote there before for the same ``blob`` and
    code, or call ``write()`` and keep what it wrote (only when a folder is set,
    :func:`use_folder`).

    Parameters
    ----------
    name : str
        What is written (a folder of the memo).
    blob : bytes
        Every argument the files depend on, serialised (equal bytes must mean equal files
        under the same code; unequal bytes for equal arguments only cost a miss).
    paths : sequence of path-like
        The files ``write`` writes, in a fixed order.
    write : callable
        Writes them.

    Returns
    -------
    bool
        True when the files came from the memo, False when ``write()`` ran.
    """
    folder = _FOLDER[0]
    if folder is None:
        write()
        return False
    h = hashlib.sha256(json.dumps({"name": name, "code": _code(), "n": len(paths)}).encode())
    h.update(blob)
    entry = folder / name / h.hexdigest()
    kept = [entry / f"{i}" for i in range(len(paths))]
    if all(k.is_file() for k in kept):
        for k, path in zip(kept, paths, strict=True):
            Path(path).parent.mkdir(parents=True, exist_ok=True)
            shutil.copyfile(k, path)
        return True
    write()
    tmp = None
    try:
        entry.parent.mkdir(parents=True, exist_ok=True)
        tmp = Path(tempfile.mkdtemp(prefix=".memo-", dir=entry.parent))
        for i, path in enumerate(paths):
            shutil.copyfile(path, tmp / f"{i}")
        os.replace(tmp, entry)
    except OSError:  # a read-only store, or another job kept the same files first
        if tmp is not None:
            shutil.rmtree(tmp, ignore_errors=True)
    return False
