"""Delimited text (``.csv``): read in line-aligned blocks parsed by ``pyarrow.csv``."""

from __future__ import annotations

import csv
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt
import pyarrow as pa
import pyarrow.csv as pacsv

from spa.datasets.readers.base import _Chunk, _ReadError, _Retry, _text_to_float

_CSV_BLOCK = 16 << 20  # bytes per CSV block read
_MAX_LINE = 1 << 20  # bytes: a longer line is not a row of a few numbers


class _CsvSource:
    """Comma-separated text with one header line, parsed by ``pyarrow.csv`` block by block.

    The file is cut at line ends into blocks of about ``_CSV_BLOCK`` bytes, read one at a time
    (``pyarrow.csv.open_csv`` reads ahead without bound on a fast disk), so memory stays flat
    whatever the length of the file. Quoted fields must not hold line breaks.
    """

    def __init__(self, path: Path) -> None:
        self.path = path
        self.invalid: list[tuple[int | None, str, int, int]] = []
        # (first data row, first line, rows map one-to-one onto lines) of each block read
        self.blocks: list[tuple[int, int, bool]] = []
        with path.open("rb") as fh:
            head = fh.read(1 << 16)
        if head.startswith((b"\xff\xfe", b"\xfe\xff")) or b"\x00" in head:
            bom = (
                "" if head.startswith((b"\xff\xfe", b"\xfe\xff")) else " without a byte-order mark"
            )
            raise _ReadError(
                f"the file looks like UTF-16 text{bom} (it holds NUL bytes); save it as UTF-8 "
                "(in Excel: CSV UTF-8), or convert it with `iconv -f UTF-16 -t UTF-8`"
            )
        if b"\r" in head and b"\n" not in head:
            raise _ReadError(
                "the lines end in CR alone (old Mac OS text); save the file with LF or CR LF "
                "line ends, e.g. `tr '\\r' '\\n' < in.csv > out.csv`"
            )
        with path.open("rb") as fh:
            first = fh.readline(_MAX_LINE)
        if not first.endswith(b"\n") and len(first) == _MAX_LINE:
            raise _ReadError(f"line 1 (the header) is longer than {_MAX_LINE} bytes")
        self.header_size = len(first)
        try:
            text = first.decode("utf-8-sig")
        except UnicodeDecodeError:
            raise _ReadError(
                "the header line is not UTF-8 text; is this really a CSV file?"
            ) from None
        names = next(csv.reader([text.rstrip("\r\n")]), [])
        if not any(n.strip() for n in names):
            raise _ReadError("the first line is empty; expected a header line naming the columns")
        self.columns = names

    def _blocks(self) -> Iterator[bytes]:
        with self.path.open("rb") as fh:
            fh.seek(self.header_size)
            carry = b""
            line = 2  # of the first data line
            while True:
                data = fh.read(_CSV_BLOCK)
                if not data:
                    if carry:
                        yield carry
                    return
                data = carry + data
                cut = data.rfind(b"\n") + 1
                carry = data[cut:]
                if len(carry) > _MAX_LINE:
                    long_line = line + data.count(b"\n", 0, cut)
                    raise _ReadError(
                        f"line {long_line} is longer than {_MAX_LINE} "
                        "bytes; a row holds a few numbers (is this a text file with line ends?)"
                    )
                if cut:
                    line += data.count(b"\n", 0, cut)
                    yield data[:cut]

    def _parse(
        self, block: bytes, names: list[str], kind: pa.DataType, threads: bool, invalid: list[Any]
    ) -> pa.Table:
        def handler(row: Any) -> str:
            invalid.append(row)
            return "skip"

        keys = [f"c{i}" for i in range(len(self.columns))]  # names in files may repeat
        include = [keys[self.columns.index(n)] for n in names]
        table = pacsv.read_csv(
            pa.py_buffer(block),
            read_options=pacsv.ReadOptions(column_names=keys, use_threads=threads),
            parse_options=pacsv.ParseOptions(invalid_row_handler=handler),
            convert_options=pacsv.ConvertOptions(
                include_columns=include,
                column_types=dict.fromkeys(include, kind),
                strings_can_be_null=False,
            ),
        )
        return table.rename_columns(names)

    def chunks(self, names: list[str], as_text: bool = False) -> Iterator[_Chunk]:
        self.invalid = []
        self.blocks = []
        kind = pa.string() if as_text else pa.float64()
        offset, line = 0, 2
        try:
            for block in self._blocks():
                try:
                    block.decode("utf-8")
                except UnicodeDecodeError as exc:
                    bad = line + block.count(b"\n", 0, exc.start)
                    raise _ReadError(
                        f"line {bad} is not UTF-8 text (byte {block[exc.start]:#04x}); save the "
                        "file as UTF-8 (in Excel: CSV UTF-8)"
                    ) from None
                invalid: list[Any] = []
                table = self._parse(block, names, kind, True, invalid)
                if invalid:  # parse again on one thread, which numbers the bad lines
                    invalid = []
                    table = self._parse(block, names, kind, False, invalid)
                lines = block.count(b"\n") + (not block.endswith(b"\n"))
                for row in invalid:
                    number = None if row.number is None else line + row.number - 1
                    self.invalid.append(
                        (number, row.text, row.expected_columns, row.actual_columns)
                    )
                self.blocks.append((offset + 1, line, table.num_rows == lines))
                values: dict[str, npt.NDArray[np.float64]] = {}
                bad: dict[str, npt.NDArray[np.bool_]] = {}
                for name in names:
                    col = table.column(name)
                    if as_text:
                        values[name], bad[name] = _text_to_float(col)
                    else:
                        values[name] = col.to_numpy().astype(np.float64, copy=False)
                yield offset, values, bad
                offset += table.num_rows
                line += lines
        except pa.ArrowInvalid as exc:
            if not as_text and "conversion error" in str(exc):
                raise _Retry from exc
            raise _ReadError(f"cannot parse the CSV file: {exc}") from exc

    def line_of(self, row: int | None) -> int | None:
        """Line of data row ``row`` (1-based), when blank or malformed lines do not blur it."""
        if row is None:
            return None
        for first_row, first_line, exact in reversed(self.blocks):
            if row >= first_row:
                return first_line + row - first_row if exact else None
        return None
