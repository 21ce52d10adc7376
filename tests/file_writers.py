"""Writers of bench file formats for the tests, the corpus and the benchmarks: MATLAB v7.3
(HDF5 with MATLAB's header and attributes), dSpace ControlDesk recordings (MATLAB structs),
LabVIEW ``.lvm`` text and TDMS.

Each streaming writer takes an iterable of chunks (``{column: array}``), so a long recording
is written without holding it in memory.
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterable, Iterator, Mapping
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa
import pyarrow.csv as pacsv

Chunk = Mapping[str, np.ndarray]

_CLASSES = {
    "f8": "double",
    "f4": "single",
    "b1": "logical",
    "i4": "int32",
    "u1": "uint8",
    "i8": "int64",
    "i1": "int8",
    "u2": "uint16",
}


def _mat73_header() -> bytes:
    text = (
        b"MATLAB 7.3 MAT-file, Platform: GLNXA64, Created on: Mon Mar  3 12:00:00 2025 "
        b"HDF5 schema 1.00 ."
    )
    header = bytearray(text.ljust(116, b" ")) + b" " * 8 + b"\x00\x02IM"
    return bytes(header.ljust(512, b"\x00"))


@contextlib.contextmanager
def mat73_file(path: Path) -> Iterator[Any]:
    """An ``h5py.File`` laid out as a MATLAB v7.3 file (header in the 512-byte user block)."""
    import h5py

    with h5py.File(path, "w", userblock_size=512, libver="earliest") as f:
        yield f
    with path.open("r+b") as fh:
        fh.write(_mat73_header())


def _set_class(node: Any, kind: str) -> None:
    node.attrs["MATLAB_class"] = np.bytes_(kind)


def _put(f: Any, group: Any, name: str, value: Any, row: bool = False) -> Any:
    """Write ``value`` (array, str, dict = struct, list of dicts = struct array) as ``name``."""
    import h5py

    if isinstance(value, str):
        ds = group.create_dataset(name, data=np.array([[ord(c)] for c in value], np.uint16))
        _set_class(ds, "char")
        ds.attrs["MATLAB_int_decode"] = np.int32(2)
        return ds
    if isinstance(value, dict):
        sub = group.create_group(name)
        _set_class(sub, "struct")
        for key, item in value.items():
            _put(f, sub, key, item)
        return sub
    if isinstance(value, list):  # struct array (1×n): one reference per element and field
        sub = group.create_group(name)
        _set_class(sub, "struct")
        refs = f.require_group("#refs#")
        for key in value[0]:
            targets = []
            for item in value:
                target = _put(f, refs, f"r{len(refs)}", item[key])
                targets.append(target.ref)
            sub.create_dataset(key, data=np.array(targets, dtype=h5py.ref_dtype).reshape(-1, 1))
        return sub
    array = np.asarray(value)
    kind = _CLASSES[f"{array.dtype.kind}{array.dtype.itemsize}"]
    data = array.astype(np.uint8) if kind == "logical" else array
    # MATLAB writes arrays transposed: an n×1 column vector is an HDF5 dataset of shape (1, n)
    data = data.reshape(-1, 1) if row else (data.reshape(1, -1) if data.ndim == 1 else data.T)
    ds = group.create_dataset(name, data=data)
    _set_class(ds, kind)
    return ds


def write_mat73(path: Path, variables: Mapping[str, Any], row: bool = False) -> None:
    """Write ``variables`` (arrays as column vectors, or rows with ``row``) as MATLAB v7.3."""
    with mat73_file(path) as f:
        for name, value in variables.items():
            _put(f, f, name, value, row=row)


def dspace_recording(
    time_name: str, time: np.ndarray, signals: Mapping[str, np.ndarray]
) -> dict[str, Any]:
    """A ControlDesk recording as nested dicts: ``X`` (time) and ``Y`` (signals) entries."""
    return {
        "Description": "ControlDesk recording",
        "X": [{"Name": time_name, "Data": np.asarray(time).reshape(1, -1)}],
        "Y": [
            {"Name": k, "Data": np.asarray(v, np.float64).reshape(1, -1)}
            for k, v in signals.items()
        ],
    }


def to_savemat(value: Any) -> Any:
    """Nested dicts and lists of dicts as ``scipy.io.savemat`` takes struct (arrays)."""
    if isinstance(value, dict):
        return {k: to_savemat(v) for k, v in value.items()}
    if isinstance(value, list):
        keys = list(value[0])
        out = np.empty((1, len(value)), dtype=[(k, object) for k in keys])
        for i, item in enumerate(value):
            for k in keys:
                out[0, i][k] = to_savemat(item[k])
        return out
    return value


def write_lvm(
    path: Path, segments: Iterable[Iterable[Chunk]], decimal: str = ",", separator: str = "Tab"
) -> None:
    """Write a LabVIEW measurement file: one segment per item of ``segments``, ``X_Value``
    first in each chunk, numbers with ``decimal`` as decimal separator."""
    sep = "\t" if separator == "Tab" else ","
    head = [
        "LabVIEW Measurement",
        "Writer_Version\t2",
        "Reader_Version\t2",
        f"Separator\t{separator}",
        f"Decimal_Separator\t{decimal}",
        "Multi_Headings\tNo",
        "X_Columns\tOne",
        "Time_Pref\tRelative",
        "Operator\tbench",
        "Date\t2025/03/03",
        "Time\t12:00:00.000",
        "***End_of_Header***",
        "",
    ]
    with path.open("wb") as fh:
        fh.write(("\n".join(h.replace("\t", sep) for h in head) + "\n").encode())
        for segment in segments:
            first = True
            for chunk in segment:
                names = list(chunk)
                if first:
                    seg = [
                        f"Channels\t{len(names) - 1}",
                        "X_Dimension" + "\tTime" * (len(names) - 1),
                        "X0" + "\t0" * (len(names) - 1),
                        "***End_of_Header***",
                    ]
                    text = "\n".join(h.replace("\t", sep) for h in seg) + "\n"
                    text += sep.join([*names, "Comment"]) + "\n"
                    fh.write(text.encode())
                    first = False
                sink = pa.BufferOutputStream()
                table = pa.table({k: pa.array(np.asarray(v)) for k, v in chunk.items()})
                pacsv.write_csv(
                    table,
                    sink,
                    pacsv.WriteOptions(include_header=False, delimiter=sep, quoting_style="none"),
                )
                data = sink.getvalue().to_pybytes()
                fh.write(data.replace(b".", decimal.encode()) if decimal != "." else data)


def write_tdms(
    path: Path, group: str, chunks: Iterable[Chunk], waveform: tuple[float, float] | None = None
) -> None:
    """Write a TDMS file, one segment per chunk; ``waveform`` = (start offset, increment)
    in s is stored as each channel's ``wf_start_offset`` and ``wf_increment``."""
    from nptdms import ChannelObject, GroupObject, TdmsWriter

    with TdmsWriter(str(path)) as writer:
        first = True
        for chunk in chunks:
            objects: list[Any] = [GroupObject(group)] if first else []
            for name, values in chunk.items():
                props = {}
                if first and waveform is not None:
                    props = {
                        "wf_start_offset": float(waveform[0]),
                        "wf_increment": float(waveform[1]),
                        "wf_samples": len(values),
                    }
                objects.append(ChannelObject(group, name, np.asarray(values), properties=props))
            writer.write_segment(objects)
            first = False


# ---- hostile MATLAB files: small on disk, huge as declared ------------------------------
def _v5_element(mdtype: int, payload: bytes) -> bytes:
    import struct

    return struct.pack("<II", mdtype, len(payload)) + payload + b"\0" * (-len(payload) % 8)


def _v5_matrix_head(name: bytes, dims: list[int], cls: int, body: int) -> bytes:
    import struct

    inner = (
        _v5_element(6, struct.pack("<II", cls, 0))  # array flags: class
        + _v5_element(5, struct.pack(f"<{len(dims)}i", *dims))
        + _v5_element(1, name)
    )
    return struct.pack("<II", 14, len(inner) + body) + inner


def write_v5_zeros(path: Path, n: int, in_struct: bool = False) -> None:
    """A MATLAB v5 file whose variable ``p`` (or field ``s.p``) holds ``n`` zeros, compressed
    with zlib as MATLAB does: 8n bytes declared, about n/1000 on disk, written without ever
    holding the zeros in memory."""
    import struct
    import zlib

    if in_struct:
        field = _v5_matrix_head(b"", [1, n], 6, 8 + 8 * n)
        width = struct.pack("<HH", 5, 4) + struct.pack("<i", 8)  # field name length: 8
        names = width + _v5_element(1, b"p".ljust(8, b"\0"))
        head = _v5_matrix_head(b"s", [1, 1], 2, len(names) + len(field) + 8 + 8 * n) + names + field
    else:
        head = _v5_matrix_head(b"p", [1, n], 6, 8 + 8 * n)
    deflate = zlib.compressobj(6)
    parts = [deflate.compress(head + struct.pack("<II", 9, 8 * n))]
    zero, left = bytes(1 << 20), 8 * n
    while left:
        parts.append(deflate.compress(zero[: min(left, len(zero))]))
        left -= min(left, len(zero))
    blob = b"".join([*parts, deflate.flush()])
    header = b"MATLAB 5.0 MAT-file".ljust(116, b" ") + b"\0" * 8 + struct.pack("<H", 0x0100) + b"IM"
    path.write_bytes(header + struct.pack("<II", 15, len(blob)) + blob)


def write_v73_declared(path: Path, n: int) -> None:
    """A MATLAB v7.3 file whose ``t`` and ``p`` declare ``n`` samples that were never written
    (HDF5 reads its fill value for them): a few kB on disk whatever ``n``."""
    with mat73_file(path) as f:
        for name in ("t", "p"):
            _set_class(f.create_dataset(name, shape=(1, n), dtype="f8"), "double")


def append_v5_zeros(path: Path, names: list[str], n: int) -> None:
    """Append to a MATLAB v5 file one compressed double variable of ``n`` zeros (1×n) per
    name: 8n bytes each once expanded, about n/1000 on disk. The zeros are deflated once
    and shared: each variable's zlib stream is its own header, flushed, then that deflate
    stream, then the Adler-32 of both."""
    import struct
    import zlib

    raw = zlib.compressobj(9, zlib.DEFLATED, -15)
    zero, left, parts = bytes(1 << 22), 8 * n, []
    while left:
        parts.append(raw.compress(zero[: min(left, len(zero))]))
        left -= min(left, len(zero))
    zeros_stream = b"".join([*parts, raw.flush()])
    with path.open("ab") as fh:
        for name in names:
            head = _v5_matrix_head(name.encode(), [1, n], 6, 8 + 8 * n) + struct.pack(
                "<II", 9, 8 * n
            )
            first = zlib.compressobj(1, zlib.DEFLATED, -15)
            start = first.compress(head) + first.flush(zlib.Z_FULL_FLUSH)
            check, left = zlib.adler32(head), 8 * n
            while left:
                check = zlib.adler32(zero[: min(left, len(zero))], check)
                left -= min(left, len(zero))
            blob = b"\x78\x01" + start + zeros_stream + struct.pack(">I", check)
            fh.write(struct.pack("<II", 15, len(blob)) + blob)
