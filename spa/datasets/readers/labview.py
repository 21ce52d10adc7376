"""LabVIEW measurement files (``.lvm``): text with header blocks, read natively in blocks.

A file starts with a file header (first line ``LabVIEW Measurement``), then one or more
segments, each a segment header; every header ends in a line ``***End_of_Header***``. The
line after a segment header names the columns, ``X_Value`` (the time) first and often
``Comment`` last; data lines follow until the next segment header or the end of the file.
``Separator`` (``Tab`` or ``Comma``) and ``Decimal_Separator`` (``.`` or ``,``) come from the
file header. Segments are concatenated in order and must have the same columns. Headers are
read line by line (they are small); data are parsed by ``pyarrow.csv`` in blocks.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt
import pyarrow as pa
import pyarrow.csv as pacsv

from spa.datasets.problems import _one_of, _suggest
from spa.datasets.readers.base import Source, _Chunk, _ReadError, _Retry, _text_to_float

_MARK = b"***End_of_Header***"
_BLOCK = 16 << 20  # bytes per block scanned or parsed
_HEAD = 1 << 16  # bytes: a header is smaller than this
_SEPARATORS = {"Tab": b"\t", "Comma": b","}


def _markers(path: Path) -> list[int]:
    """Byte offsets of every ``***End_of_Header***`` in the file, scanned in blocks."""
    found: list[int] = []
    with path.open("rb") as fh:
        carry = b""
        while data := fh.read(_BLOCK):
            data = carry + data
            origin = fh.tell() - len(data)
            at = data.find(_MARK)
            while at >= 0:
                found.append(origin + at)
                at = data.find(_MARK, at + 1)
            carry = data[-(len(_MARK) - 1) :]
    return found


def _line_end(fh: Any, at: int) -> int:
    """Offset just after the line holding byte ``at``."""
    fh.seek(at)
    line = fh.readline(_HEAD)
    return at + len(line)


def _header_start(fh: Any, marker: int, floor: int) -> int:
    """Offset of the first line of the segment header ending at ``marker`` (after data)."""
    start = max(floor, marker - _HEAD)
    fh.seek(start)
    lines = fh.read(marker - start).split(b"\n")
    offset = marker - len(lines[-1])
    for line in reversed(lines[:-1]):
        text = line.strip()
        if text and text[:1] not in b"*" and not text[:1].isalpha():
            break  # a data line
        offset -= len(line) + 1
    return offset


class _LvmSource(Source):
    """A LabVIEW ``.lvm`` measurement file with one X column (``X_Columns: One``)."""

    what = "LabVIEW channel"

    def __init__(self, path: Path, options: Mapping[str, Any] | None = None) -> None:
        self.path = path
        with path.open("rb") as fh:
            head = fh.read(_HEAD)
        if not head.lstrip(b"\xef\xbb\xbf").startswith(b"LabVIEW Measurement"):
            raise _ReadError(
                "not a LabVIEW measurement file: the first line should be 'LabVIEW Measurement'"
            )
        marks = _markers(path)
        if not marks:
            raise _ReadError(f"no {_MARK.decode()} line: the header never ends (truncated?)")
        keys = self._header(head[: marks[0]])
        self.sep = _SEPARATORS.get(keys.get("Separator", "Tab"))
        if self.sep is None:
            raise _ReadError(
                f"unknown Separator {keys['Separator']!r} in the file header; expected Tab or Comma"
            )
        self.decimal = keys.get("Decimal_Separator", ".")
        if self.decimal not in (".", ","):
            raise _ReadError(f"unknown Decimal_Separator {self.decimal!r}; expected '.' or ','")
        if self.decimal == "," and self.sep == b",":
            raise _ReadError("Separator Comma with Decimal_Separator ','; save with Separator Tab")
        if keys.get("X_Columns", "One") != "One":
            raise _ReadError(
                f"X_Columns is {keys['X_Columns']!r}; only files with one X column (X_Columns "
                "One, the time in X_Value) are read: save with 'X value columns: One column only'"
            )
        self.segments: list[tuple[int, int]] = []  # (first data byte, end) of each segment
        self.columns: list[str] = []
        with path.open("rb") as fh:
            size = fh.seek(0, 2)
            for i, mark in enumerate(marks):
                start = _line_end(fh, mark)
                fh.seek(start)
                line = b""
                while not line.strip() and fh.tell() < size:
                    start = fh.tell()
                    line = fh.readline(_HEAD)
                names = line.rstrip(b"\r\n").decode("utf-8", "replace").split(self.sep.decode())
                if names[0].strip() != "X_Value":
                    continue  # a header followed by another header
                names = [n.strip() for n in names]
                if names[-1] == "Comment":
                    names = names[:-1]
                if self.columns and names != self.columns:
                    raise _ReadError(
                        f"segment {len(self.segments) + 1} names the columns {names}, segment 1 "
                        f"{self.columns}; segments are joined and need the same channels"
                    )
                self.columns = names
                end = size if i + 1 == len(marks) else _header_start(fh, marks[i + 1], start)
                self.segments.append((start + len(line), end))
        if not self.segments:
            raise _ReadError("no data block: no header line starting with X_Value was found")

    @staticmethod
    def _header(block: bytes) -> dict[str, str]:
        keys: dict[str, str] = {}
        for raw in block.decode("utf-8", "replace").splitlines():
            parts = raw.replace(",", "\t", 1).split("\t") if "\t" not in raw else raw.split("\t")
            if len(parts) >= 2 and parts[0].strip():
                keys.setdefault(parts[0].strip(), parts[1].strip())
        return keys

    def resolve(self, name: str) -> str | None:
        """The column called ``name``; ``t``, when no column is so called, is ``X_Value``."""
        if name in self.columns:
            return name
        return "X_Value" if name == "t" else None

    def describe(self, name: str) -> str:
        """The channels the file holds and the closest to ``name``."""
        return f"; the file has the channels {_one_of(repr(c) for c in self.columns)}" + _suggest(
            name, self.columns
        )

    def check_types(self, names: list[str]) -> list[_ReadError]:
        return []

    def _blocks(self) -> Iterator[bytes]:
        with self.path.open("rb") as fh:
            for start, end in self.segments:
                fh.seek(start)
                carry, left = b"", end - start
                while left > 0:
                    data = fh.read(min(_BLOCK, left))
                    left -= len(data)
                    data = carry + data
                    cut = data.rfind(b"\n") + 1 if left > 0 else len(data)
                    carry = data[cut:]
                    if data[:cut].strip():
                        yield data[:cut]

    def chunks(self, names: list[str], as_text: bool = False) -> Iterator[_Chunk]:
        kind = pa.string() if as_text else pa.float64()
        width = None
        offset = 0
        index = {n: f"c{self.columns.index(self.resolve(n) or n)}" for n in names}
        for block in self._blocks():
            if self.decimal == ",":
                block = block.replace(b",", b".")
            if width is None:
                first = block.lstrip(b"\r\n").split(b"\n", 1)[0]
                width = first.count(self.sep) + 1
            keys = [f"c{i}" for i in range(width)]
            try:
                table = pacsv.read_csv(
                    pa.py_buffer(block),
                    read_options=pacsv.ReadOptions(column_names=keys),
                    parse_options=pacsv.ParseOptions(delimiter=self.sep.decode()),
                    convert_options=pacsv.ConvertOptions(
                        include_columns=[index[n] for n in names],
                        column_types={index[n]: kind for n in names},
                        strings_can_be_null=False,
                    ),
                )
            except pa.ArrowInvalid as exc:
                if not as_text and "conversion error" in str(exc):
                    raise _Retry from exc
                raise _ReadError(
                    f"cannot parse the data after row {offset}: {exc} (a truncated last line, "
                    "or lines with more fields than the first?)",
                    row=offset + 1,
                ) from exc
            values: dict[str, npt.NDArray[np.float64]] = {}
            bad: dict[str, npt.NDArray[np.bool_]] = {}
            for name in names:
                col = table.column(index[name])
                if as_text:
                    values[name], bad[name] = _text_to_float(col)
                else:
                    values[name] = col.to_numpy().astype(np.float64, copy=False)
            yield offset, values, bad
            offset += table.num_rows
