"""MATLAB ``.mat`` files: v4/v5/v7 through ``scipy.io.loadmat`` (each numeric variable loaded
when it is read, so those ``dataset.yaml`` does not name never are), v7.3 (HDF5)
through ``h5py`` (read in blocks, see ``matlab_hdf5``); variables, struct fields and dSpace
recordings are named as described in ``structs``."""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from spa.datasets.readers.base import _ReadError
from spa.datasets.readers.structs import NUMERIC_CLASSES, _Leaf, _Recording, _StructSource

_HDF5_SIGNATURE = b"\x89HDF\r\n\x1a\n"

_CLASS_OF_DTYPE = {
    "f8": "double",
    "f4": "single",
    "b1": "logical",
    **{f"i{b // 8}": f"int{b}" for b in (8, 16, 32, 64)},
    **{f"u{b // 8}": f"uint{b}" for b in (8, 16, 32, 64)},
}


def _is_hdf5(path: Path) -> bool:
    """True for a MATLAB v7.3 file: a 512-byte MATLAB header (version 0x0200), then an HDF5
    superblock."""
    with path.open("rb") as fh:
        head = fh.read(520)
    return head[512:520] == _HDF5_SIGNATURE or head[124:128] == b"\x00\x02IM"


def _v5_kind(value: Any) -> str:
    if not isinstance(value, np.ndarray):
        return type(value).__name__
    if value.dtype.names:
        return "struct" if value.size == 1 else "struct array"
    if value.dtype.kind in "US":
        return "char"
    if value.dtype.kind == "O":
        return "cell"
    return _CLASS_OF_DTYPE.get(f"{value.dtype.kind}{value.dtype.itemsize}", str(value.dtype))


def _v5_reader(value: npt.NDArray[Any]) -> Any:
    flat = value.ravel()
    return lambda a, b: np.asarray(flat[a:b], dtype=np.float64)


def _v5_text(value: Any) -> str:
    if isinstance(value, np.ndarray) and value.dtype.kind in "US" and value.size:
        return str(value.ravel()[0])
    raise ValueError("not text")


def _v5_entries(value: Any) -> list[tuple[str, _Leaf]] | None:
    """The (Name, Data) entries of a dSpace X or Y struct array, or None if it is not one."""
    if not (isinstance(value, np.ndarray) and value.dtype.names):
        return None
    if not {"Name", "Data"} <= set(value.dtype.names):
        return None
    entries = []
    for item in value.ravel():
        try:
            name = _v5_text(item["Name"])
        except ValueError:
            return None
        data = item["Data"]
        entries.append((name, _v5_leaf(data)))
    return entries


def _v5_leaf(value: Any) -> _Leaf:
    kind = _v5_kind(value)
    shape = tuple(getattr(value, "shape", ()))
    fields = tuple(value.dtype.names or ()) if isinstance(value, np.ndarray) else ()
    if kind in ("char", "cell", "struct", "struct array") or not isinstance(value, np.ndarray):
        return _Leaf(kind, shape, fields=fields)
    return _Leaf(kind, shape, _v5_reader(value))


def _v5_walk(name: str, value: Any, leaves: dict[str, _Leaf], recs: list[_Recording]) -> None:
    leaves[name] = _v5_leaf(value)
    if leaves[name].kind != "struct":
        return
    record = value.ravel()[0]
    names = value.dtype.names
    skip: tuple[str, ...] = ()
    if "X" in names and "Y" in names:
        x, y = _v5_entries(record["X"]), _v5_entries(record["Y"])
        if x is not None and y is not None:
            recs.append(_Recording(name, x, y))
            skip = ("X", "Y")  # named by their signals
    for sub in names:
        if sub in skip:
            leaves[f"{name}.{sub}"] = _Leaf("struct array", record[sub].shape)
        else:
            _v5_walk(f"{name}.{sub}", record[sub], leaves, recs)


def _loadmat(path: Path, names: list[str] | None) -> dict[str, Any]:
    """``scipy.io.loadmat`` of the variables ``names`` (None: all), its failures as
    :class:`_ReadError`."""
    import scipy.io

    try:
        return scipy.io.loadmat(path, squeeze_me=False, mat_dtype=False, variable_names=names)
    except Exception as exc:  # scipy raises several types for a damaged file
        raise _ReadError(
            f"unreadable MATLAB file (truncated, damaged or not a .mat file?): "
            f"{type(exc).__name__}: {exc}"
        ) from exc


def _v5_lazy(path: Path, name: str) -> Any:
    """A reader of rows of the numeric variable ``name``, loaded (alone) at its first read."""
    loaded: list[npt.NDArray[Any]] = []

    def read(a: int, b: int) -> npt.NDArray[np.float64]:
        if not loaded:
            from spa.datasets.readers.mat_bounds import check_v5

            check_v5(path, names=[name])  # its expanded size, before it is loaded
            loaded.append(np.asarray(_loadmat(path, [name])[name]).ravel())
        return np.asarray(loaded[0][a:b], dtype=np.float64)

    return read


def _v5_tree(path: Path) -> tuple[dict[str, _Leaf], list[_Recording]]:
    """The leaves and recordings of a v4/v5 file. A numeric top-level variable is described
    by its header alone and loaded only when its rows are read (a file may hold variables
    that ``dataset.yaml`` never names, of any size); structs, cells and text are loaded."""
    from spa.datasets.readers.mat_bounds import check_v5

    headers = check_v5(path, names=())  # every header, before anything is expanded
    if not headers or any(kind == "unknown" for _, _, kind in headers):
        check_v5(path)  # v4, or damaged: load it whole and let scipy say what is wrong
        data = _loadmat(path, None)
        headers = [(name, [], "") for name in data if not name.startswith("__")]
        lazy: set[str] = set()
    else:
        lazy = {name for name, _, kind in headers if kind in NUMERIC_CLASSES}
        eager = [name for name, _, _ in headers if name not in lazy]
        check_v5(path, names=eager)
        data = _loadmat(path, eager) if eager else {}
    leaves: dict[str, _Leaf] = {}
    recs: list[_Recording] = []
    for name, dims, kind in headers:
        if name in lazy:
            leaves[name] = _Leaf(kind, tuple(dims), _v5_lazy(path, name))
        elif name in data:
            _v5_walk(name, data[name], leaves, recs)
    return leaves, recs


class _MatSource(_StructSource):
    """A MATLAB ``.mat`` file (v4 to v7.3) holding vectors, structs or a dSpace recording."""

    def __init__(self, path: Path, options: Mapping[str, Any] | None = None) -> None:
        if _is_hdf5(path):
            from spa.datasets.readers.matlab_hdf5 import _hdf5_tree

            self.file, leaves, recs = _hdf5_tree(path)
        else:
            leaves, recs = _v5_tree(path)
        super().__init__(path, leaves, recs)
