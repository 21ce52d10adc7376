"""MATLAB v7.3 ``.mat`` files (HDF5 after a 512-byte MATLAB header), read through ``h5py``.

MATLAB stores each array transposed (an n×1 vector is an HDF5 dataset of shape (1, n)) with
its class in the ``MATLAB_class`` attribute; a struct is a group whose members are its fields;
a struct array or a cell holds HDF5 object references (into ``#refs#``) to its elements.
Vectors are read by slices of ``_BATCH_ROWS`` rows, so memory stays flat.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from spa.datasets.readers.base import _ReadError
from spa.datasets.readers.structs import _Leaf, _Recording


def _class(node: Any) -> str:
    value = node.attrs.get("MATLAB_class", b"")
    return value.decode() if isinstance(value, bytes) else str(value)


def _reader(ds: Any) -> Any:
    if ds.ndim == 2 and ds.shape[0] == 1:
        return lambda a, b: np.asarray(ds[0, a:b], dtype=np.float64)
    if ds.ndim == 2:
        return lambda a, b: np.asarray(ds[a:b, 0], dtype=np.float64)
    return lambda a, b: np.asarray(ds[a:b], dtype=np.float64)


def _member(group: Any, key: str) -> Any:
    """``group[key]``, refusing soft and external links (MATLAB writes neither), so nothing
    outside the file is ever opened."""
    import h5py

    if not isinstance(group.get(key, getlink=True), h5py.HardLink):
        raise _ReadError(
            f"{group.name.rstrip('/')}/{key} is a link, not data; a MATLAB file holds no "
            "links (save the data again from MATLAB)"
        )
    return _own(group[key])


def _own(node: Any) -> Any:
    """``node``, refusing a dataset that keeps its data in other files."""
    import h5py

    if isinstance(node, h5py.Dataset) and (node.external or node.is_virtual):
        raise _ReadError(
            f"{node.name} keeps its data in other files (external or virtual dataset); "
            "save the data again from MATLAB"
        )
    return node


def _leaf(node: Any) -> _Leaf:
    import h5py

    kind = _class(node) or ("struct" if isinstance(node, h5py.Group) else "unknown")
    if isinstance(node, h5py.Group):
        members = [_member(node, f) for f in node]
        if members and all(
            isinstance(m, h5py.Dataset)
            and h5py.check_dtype(ref=m.dtype) is not None
            and _class(m) != "cell"
            for m in members
        ):  # fields of references: a struct array
            return _Leaf("struct array", tuple(reversed(members[0].shape)), fields=tuple(node))
        return _Leaf(kind, (1, 1), fields=tuple(node))
    shape = tuple(reversed(node.shape))
    if node.attrs.get("MATLAB_empty", 0):
        return _Leaf(kind, tuple(0 for _ in shape))
    if h5py.check_dtype(ref=node.dtype) is not None:
        return _Leaf("cell" if kind in ("cell", "unknown") else kind, shape)
    if node.dtype.kind not in "biuf" or node.ndim > 2:
        return _Leaf(kind, shape)
    from spa.datasets.readers.mat_bounds import check_hdf5_dataset

    check_hdf5_dataset(node, Path(node.file.filename).stat().st_size)
    return _Leaf(kind, shape, _reader(node))


def _text(node: Any) -> str:
    return "".join(chr(c) for c in np.asarray(node[()]).ravel())


def _entries(file: Any, node: Any) -> list[tuple[str, _Leaf]] | None:
    """The (Name, Data) entries of a dSpace X or Y struct (array), or None if not one."""
    import h5py

    if not (isinstance(node, h5py.Group) and "Name" in node and "Data" in node):
        return None
    names, data = _member(node, "Name"), _member(node, "Data")
    if h5py.check_dtype(ref=names.dtype) is None:  # a 1×1 struct: fields hold the values
        return [(_text(names), _leaf(data))]
    if h5py.check_dtype(ref=data.dtype) is None or names.shape != data.shape:
        return None
    refs = zip(names[()].ravel(), data[()].ravel(), strict=True)
    return [(_text(_own(file[n])), _leaf(_own(file[d]))) for n, d in refs]


def _walk(
    file: Any, name: str, node: Any, leaves: dict[str, _Leaf], recs: list[_Recording]
) -> None:
    leaf = _leaf(node)
    leaves[name] = leaf
    if leaf.kind != "struct" or not leaf.fields:
        return
    skip: tuple[str, ...] = ()
    if "X" in leaf.fields and "Y" in leaf.fields:
        x, y = _entries(file, _member(node, "X")), _entries(file, _member(node, "Y"))
        if x is not None and y is not None:
            recs.append(_Recording(name, x, y))
            skip = ("X", "Y")  # named by their signals
    for sub in leaf.fields:
        if sub in skip:
            leaves[f"{name}.{sub}"] = _Leaf("struct array", (1, 1))
        else:
            _walk(file, f"{name}.{sub}", _member(node, sub), leaves, recs)


def _hdf5_tree(path: Path) -> tuple[Any, dict[str, _Leaf], list[_Recording]]:
    """Open a v7.3 file; return it (kept open for reading) with its leaves and recordings."""
    import h5py

    try:
        file = h5py.File(path, "r")
    except Exception as exc:  # h5py raises OSError and others for a damaged file
        raise _ReadError(
            f"unreadable MATLAB v7.3 (HDF5) file (truncated or damaged?): {exc}"
        ) from exc
    leaves: dict[str, _Leaf] = {}
    recs: list[_Recording] = []
    try:
        for name in file:
            if not name.startswith("#"):
                _walk(file, name, _member(file, name), leaves, recs)
    except _ReadError:
        raise
    except Exception as exc:
        raise _ReadError(
            f"unreadable MATLAB v7.3 (HDF5) file (damaged?): {type(exc).__name__}: {exc}"
        ) from exc
    return file, leaves, recs
