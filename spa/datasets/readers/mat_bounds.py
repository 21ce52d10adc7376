"""Bounds on what a MATLAB file may make spa allocate, checked before its data are read.

A ``.mat`` file is small on disk but may declare huge arrays: a v5 variable compressed with
zlib (1.5 GiB of zeros fit in 2 MB), or a v7.3 (HDF5) dataset declaring 2^40 samples that were
never written (HDF5 returns its fill value for them, so a 4 kB file "holds" 8 TB). ``scipy``
loads a v5 file whole, and a v7.3 vector is read block by block: either would allocate, or
read, for as long as the declaration says. So:

- v5: every top-level variable's declared dimensions (``scipy.io.whosmat``, which reads
  headers only) must hold at most :func:`max_samples` values, and every compressed variable is
  expanded as a stream, counted and discarded, stopping as soon as it exceeds
  ``8 * max_samples()`` bytes (a struct hides its fields' sizes from the header);
- v7.3: a dataset stored without compression cannot declare more bytes than the file has,
  and any dataset at most :func:`max_samples` values.

Each refusal is a :class:`~spa.datasets.readers.base._ReadError` (a problem of the run, naming
the variable and the sizes), so the dataset fails alone.
"""

from __future__ import annotations

import math
import os
import struct
import zlib
from collections.abc import Collection
from pathlib import Path
from typing import Any

from spa.datasets.readers.base import _ReadError

#: Default largest number of samples in one channel (variable) of a MATLAB file: 27 hours
#: at 1 kHz, 800 MB as float64. The environment variable ``SPA_MAX_SAMPLES`` changes it.
MAX_SAMPLES = 10**8

_MI_COMPRESSED = 15
_MI_MATRIX = 14
_COMPLEX = 0x0800  # array flags: complex, logical (MAT-file format, "Array Flags")
_LOGICAL = 0x0200
_HEAD = 4096  # expanded bytes that hold a variable's header
_CHUNK = 1 << 16
_OUT = 1 << 20


def max_samples() -> int:
    """The largest channel a MATLAB file may declare: ``SPA_MAX_SAMPLES`` or :data:`MAX_SAMPLES`.

    Examples
    --------
    >>> max_samples() == int(os.environ.get("SPA_MAX_SAMPLES", MAX_SAMPLES))
    True
    """
    value = os.environ.get("SPA_MAX_SAMPLES")
    return int(float(value)) if value else MAX_SAMPLES


def _refuse(what: str, detail: str = "") -> _ReadError:
    limit = max_samples()
    what = f"{what} {detail}" if detail else what
    return _ReadError(
        f"{what}; at most {limit:,} samples ({8 * limit / 1e6:,.0f} MB) a channel are "
        "read (set the environment variable SPA_MAX_SAMPLES to allow more)"
    )


def check_v5(path: Path, names: Collection[str] | None = None) -> list[tuple[str, list[int], str]]:
    """Refuse a v5 MAT file whose variables declare or expand to too many values.

    Each top-level variable's header (class, dimensions, name) is read, expanding only its
    first bytes when it is compressed; ``scipy.io.whosmat`` would expand it whole.

    Parameters
    ----------
    path : Path
        The file.
    names : collection of str, optional
        The variables whose compressed data are expanded (as a stream, counted and
        discarded) to bound what loading them allocates; None: every variable. The declared
        dimensions of every variable are checked either way.

    Returns
    -------
    list of (str, list of int, str)
        Name, dimensions and class of each top-level variable, in file order (``logical``
        and ``complex`` for numeric arrays so flagged); empty for a file that is not v5.

    Raises
    ------
    _ReadError
        Naming the variable, its declared shape or its compressed and expanded sizes.
    """
    limit = max_samples()
    most = 8 * limit + _OUT
    found = _v5_variables(path, most, names)
    for name, dims, kind, packed, expanded in found:
        count = math.prod(dims)
        if count > limit:
            shape = "x".join(str(n) for n in dims)
            raise _refuse(f"MATLAB variable {name!r} declares {shape} {kind} = {count:,} values")
        if expanded is None:
            raise _refuse(
                f"MATLAB variable {name!r}: its {packed:,} compressed bytes expand to more "
                f"than {most:,} bytes",
                "(a file can declare far more than it holds)",
            )
    return [(name, dims, kind) for name, dims, kind, _, _ in found]


_CLASSES = {1: "cell", 2: "struct", 3: "object", 4: "char", 5: "sparse", 6: "double"}
_CLASSES |= {7: "single", 8: "int8", 9: "uint8", 10: "int16", 11: "uint16", 12: "int32"}
_CLASSES |= {13: "uint32", 14: "int64", 15: "uint64"}


def _subelement(buf: bytes, pos: int, order: str) -> tuple[bytes, int]:
    """The data of the (possibly small) data element at ``pos`` and the position after it."""
    mdtype, nbytes = struct.unpack_from(order + "II", buf, pos)
    if mdtype >> 16:  # small element: size in the upper half, data in the tag's 4 bytes
        small = mdtype >> 16 if order == "<" else nbytes
        return buf[pos + 4 : pos + 4 + min(small, 4)], pos + 8
    return buf[pos + 8 : pos + 8 + nbytes], pos + 8 + nbytes + (-nbytes % 8)


def _matrix_header(buf: bytes, order: str) -> tuple[str, list[int], str]:
    """(name, dimensions, class) of the miMATRIX element at the start of ``buf``."""
    try:
        flags, pos = _subelement(buf, 8, order)
        raw_dims, pos = _subelement(buf, pos, order)
        name, _ = _subelement(buf, pos, order)
        dims = list(struct.unpack(f"{order}{len(raw_dims) // 4}i", raw_dims))
        word = struct.unpack_from(order + "I", flags)[0]
        kind = _CLASSES.get(word & 0xFF, "unknown")
        if word & _COMPLEX:
            kind = "complex"
        elif word & _LOGICAL:
            kind = "logical"
    except struct.error:
        return "?", [], "unknown"  # damaged: loadmat says so
    return name.rstrip(b"\0").decode("latin-1"), [max(d, 0) for d in dims], kind


def _v5_variables(
    path: Path, limit: int, names: Collection[str] | None = None
) -> list[tuple[str, list[int], str, int, int | None]]:
    """(name, dims, class, compressed size, expanded size or None above ``limit``) of each
    top-level variable of a v5 file; nothing is kept of the expanded data. Only the
    variables in ``names`` (None: all) are expanded whole; of the others, their header
    (the expanded size is then given as 0)."""
    out: list[tuple[str, list[int], str, int, int | None]] = []
    with path.open("rb") as fh:
        header = fh.read(128)
        if len(header) < 128 or header[126:128] not in (b"IM", b"MI"):
            return out  # v4 or not a MAT file: loadmat decides
        order = "<" if header[126:128] == b"IM" else ">"
        size = path.stat().st_size
        while fh.tell() + 8 <= size:
            mdtype, nbytes = struct.unpack(order + "II", fh.read(8))
            start = fh.tell()
            if mdtype == _MI_COMPRESSED:
                head = bytearray()
                expanded = _expanded(fh, nbytes, limit, head, whole=names is None)
                header = _matrix_header(bytes(head), order)
                if names is not None and header[0] in names:
                    fh.seek(start)
                    expanded = _expanded(fh, nbytes, limit, bytearray())
                out.append((*header, nbytes, expanded))
                fh.seek(start + nbytes)
            elif mdtype == _MI_MATRIX:
                head = struct.pack(order + "II", mdtype, nbytes) + fh.read(min(nbytes, 4096))
                out.append((*_matrix_header(head, order), nbytes, nbytes))
                fh.seek(start + nbytes + (-nbytes % 8))
            else:
                fh.seek(start + nbytes + (-nbytes % 8))
    return out


def _expanded(fh: Any, nbytes: int, limit: int, head: bytearray, whole: bool = True) -> int | None:
    """Bytes that ``nbytes`` of zlib data at ``fh`` expand to, or None once above ``limit``;
    the first 4 kB expanded are put in ``head``. With ``whole`` False, only those 4 kB are
    expanded (and 0 returned)."""
    inflate = zlib.decompressobj()
    total, left = 0, nbytes
    try:
        while left > 0 and not inflate.eof:
            data = fh.read(min(_CHUNK, left))
            if not data:
                break
            left -= len(data)
            while data:
                chunk = inflate.decompress(data, _OUT if whole else _HEAD)
                if len(head) < _HEAD:
                    head += chunk[: _HEAD - len(head)]
                if not whole and (len(head) >= _HEAD or inflate.eof):
                    return 0
                total += len(chunk)
                if total > limit:
                    return None
                data = inflate.unconsumed_tail
    except zlib.error:
        return total  # damaged: loadmat says so
    return total


def check_hdf5_dataset(node: Any, file_size: int) -> None:
    """Refuse a v7.3 dataset declaring more than the file can hold or a channel may have.

    Raises
    ------
    _ReadError
        Naming the dataset, its declared shape and bytes, and the file's size.
    """
    count = math.prod(int(n) for n in node.shape)
    declared = count * node.dtype.itemsize
    dims = "x".join(str(n) for n in reversed(node.shape))
    what = f"MATLAB v7.3 variable {node.name} declares {dims} = {count:,} values"
    if not node.compression and not getattr(node, "_filters", None) and declared > file_size:
        raise _ReadError(
            f"{what} ({declared:,} bytes) but the file has {file_size:,} bytes: the data "
            "were never written (truncated or forged file?)"
        )
    if count > max_samples():
        raise _refuse(what)
