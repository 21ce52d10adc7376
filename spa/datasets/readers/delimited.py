"""Delimited text (``.csv``, ``.txt``, ``.tsv``, ``.dat``, ``.log``): read in line-aligned
blocks, each normalised (decoded, comment lines dropped, runs of blanks or decimal commas
rewritten) and parsed by ``pyarrow.csv``. The options are those of ``csv:`` in
``dataset.yaml`` (see :mod:`spa.datasets.options`).

A file whose first line (after ``skip_rows`` and comment lines) holds only numbers has no
header: that line is data and the columns are named by position, ``col1``, ``col2``, ...
(``csv: {header: false}`` says so whatever the first line holds; ``header: true`` reads it
as the header whatever it holds)."""

from __future__ import annotations

import codecs
import csv
import re
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt
import pyarrow as pa
import pyarrow.csv as pacsv

from spa.datasets.options import POSITIONAL, WHITESPACE, csv_options
from spa.datasets.readers.base import Source, _Chunk, _ReadError, _Retry, _text_to_float

_CSV_BLOCK = 16 << 20  # bytes per CSV block read
_MAX_LINE = 1 << 20  # bytes: a longer line is not a row of a few numbers
_PROBE = "\n\r,;.\t |0123456789eE+-#%abcxyz"  # what must keep its bytes for bytes-level work
_BOMS = (
    (codecs.BOM_UTF32_LE, "utf-32"),
    (codecs.BOM_UTF32_BE, "utf-32"),
    (codecs.BOM_UTF8, "utf-8-sig"),
    (codecs.BOM_UTF16_LE, "utf-16"),
    (codecs.BOM_UTF16_BE, "utf-16"),
)


def _ascii_compatible(codec: str) -> bool:
    """True when ``codec`` writes line ends, digits, signs and separators as ASCII does."""
    try:
        return _PROBE.encode(codec) == _PROBE.encode("ascii")
    except (UnicodeError, LookupError):
        return False


_NUMBER = re.compile(r"[+-]?(\d+\.?\d*|\.\d+)([eE][+-]?\d+)?|[+-]?(nan|inf)", re.I)


def numbers_only(fields: list[str], decimal: str = ".") -> bool:
    """True when every field of a line is a number (or empty) and one at least is: a line of
    data, not a header naming the columns.

    Examples
    --------
    >>> numbers_only(["0.5", "12"]), numbers_only(["time_ms", "p"]), numbers_only(["0,5"], ",")
    (True, False, True)
    """
    cells = [f.strip().strip('"').strip() for f in fields]
    if decimal == ",":
        cells = [c.replace(",", ".") for c in cells]
    filled = [c for c in cells if c]
    return bool(filled) and all(_NUMBER.fullmatch(c) for c in filled)


def _squeeze_blanks(block: bytes) -> bytes:
    """Runs of spaces and tabs become one space; blanks at line starts and ends go."""
    arr = np.frombuffer(block, dtype=np.uint8)
    blank = (arr == 32) | (arr == 9)
    if not blank.any():
        return block
    end = (arr == 10) | (arr == 13)
    before = np.empty_like(blank)  # the byte before is a blank or a line end (or none)
    before[0] = True
    before[1:] = blank[:-1] | end[:-1]
    keep = ~(blank & before)
    out = arr[keep]
    out[blank[keep]] = 32
    # the one blank left of a run at a line end goes too
    return out.tobytes().replace(b" \n", b"\n").replace(b" \r", b"\r")


class _CsvSource(Source):
    """Delimited text with one header line, parsed by ``pyarrow.csv`` block by block.

    The file is cut at line ends into blocks of about ``_CSV_BLOCK`` bytes, read one at a time
    (``pyarrow.csv.open_csv`` reads ahead without bound on a fast disk), so memory stays flat
    whatever the length of the file. Quoted fields must not hold line breaks.

    Parameters
    ----------
    path : pathlib.Path
        The file.
    options : mapping, optional
        ``csv:`` options (see :data:`spa.datasets.options.CSV_KEYS`); missing keys take the
        defaults of the file's ending.
    """

    def __init__(self, path: Path, options: Mapping[str, Any] | None = None) -> None:
        self.path = path
        self.options = csv_options(options or {}, path.suffix)
        self.invalid: list[tuple[int | None, str, int, int]] = []
        # (first data row, first line, rows map one-to-one onto lines, kept lines or None)
        self.blocks: list[tuple[int, int, bool, npt.NDArray[np.int64] | None]] = []
        sep = self.options["sep"]
        self.sep = " " if sep == WHITESPACE else sep
        with path.open("rb") as fh:
            head = fh.read(1 << 16)
        self.codec, self.bom = self._codec(head)
        # Text in a codec that does not keep ASCII bytes is turned into UTF-8 as it is read.
        self.transcode = not _ascii_compatible(self.codec)
        self.work = "utf-8" if self.transcode else self.codec
        if self.transcode:
            head = head[len(self.bom) :].decode(self.codec, errors="ignore").encode("utf-8")
        if b"\r" in head and b"\n" not in head:
            raise _ReadError(
                "the lines end in CR alone (old Mac OS text); save the file with LF or CR LF "
                "line ends, e.g. `tr '\\r' '\\n' < in.csv > out.csv`"
            )
        comment = self.options["comment"]
        try:
            self.comment = None if comment is None else comment.encode(self.work)
        except UnicodeEncodeError:
            raise _ReadError(
                f"csv: comment {comment!r} cannot be written in {self.codec}; use ASCII"
            ) from None
        self.comment_utf8 = None if comment is None else comment.encode("utf-8")
        self.skipped: list[str] = []
        self.units: list[str] = []
        self.columns: list[str] = []
        self.header_line = 0
        self.headerless = False  # no header line: columns named by position
        self._size = 1 << 16  # the first read is small: only the lines above the data
        above = self._data()
        next(above, None)
        above.close()
        self._size = _CSV_BLOCK
        if not self.columns:
            raise _ReadError("the file holds no header line naming the columns")

    def _codec(self, head: bytes) -> tuple[str, bytes]:
        """The codec to decode with and the byte-order mark to skip."""
        chosen = self.options["encoding"]
        if chosen is not None:
            name = codecs.lookup(chosen).name
            if name in ("utf-8", "utf-8-sig") and head.startswith(codecs.BOM_UTF8):
                return "utf-8", codecs.BOM_UTF8
            return name, b""
        for bom, codec in _BOMS:
            if head.startswith(bom):
                return ("utf-8", bom) if codec == "utf-8-sig" else (codec, b"")
        if b"\x00" in head:
            raise _ReadError(
                "the file looks like UTF-16 text without a byte-order mark (it holds NUL "
                "bytes); save it as UTF-8 (in Excel: CSV UTF-8), or convert it with "
                "`iconv -f UTF-16 -t UTF-8`"
            )
        return "utf-8", b""

    def _chunks(self) -> Iterator[bytes]:
        """The file's bytes from after the byte-order mark, in the working codec."""
        with self.path.open("rb") as fh:
            fh.seek(len(self.bom))
            decoder = codecs.getincrementaldecoder(self.codec)() if self.transcode else None
            done = 0
            while True:
                data = fh.read(self._size)
                if decoder is None:
                    if not data:
                        return
                    yield data
                    continue
                try:
                    text = decoder.decode(data, final=not data)
                except UnicodeDecodeError as exc:
                    raise _ReadError(
                        f"the bytes near offset {done + exc.start} are not {self.codec} text "
                        f"({exc.reason}); {self._fix()}"
                    ) from None
                done += len(data)
                if text:
                    yield text.encode("utf-8")
                if not data:
                    return

    def _lines(self) -> Iterator[tuple[int, bytes]]:
        """Blocks of whole lines and the number of each block's first line."""
        carry = b""
        line = 1
        for data in self._chunks():
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
                yield line, data[:cut]
                line += data.count(b"\n", 0, cut)
        if carry:
            yield line, carry

    def _text(self, raw: bytes, line: int, what: str) -> str:
        try:
            return raw.decode(self.work).rstrip("\r\n")
        except UnicodeDecodeError as exc:
            raise _ReadError(
                f"line {line} ({what}) is not {self._codec_name()} text (byte "
                f"{raw[exc.start]:#04x}); is this really a CSV file?",
                row=None,
            ) from None

    def _fix(self) -> str:
        if self.options["encoding"] is None:
            return (
                "the file starts with a byte-order mark of that encoding: is it damaged? "
                "Save it as UTF-8 (in Excel: CSV UTF-8)"
            )
        return "check csv: {encoding: ...} in dataset.yaml"

    def _codec_name(self) -> str:
        return "UTF-8" if self.codec == "utf-8" else self.codec

    def _split(self, text: str) -> list[str]:
        if self.options["sep"] == WHITESPACE:
            return text.split()
        try:
            return next(csv.reader([text], delimiter=self.sep), [])
        except csv.Error as exc:
            raise _ReadError(f"cannot split the line {text[:80]!r} into fields: {exc}") from None

    def _data(self) -> Iterator[tuple[int, bytes]]:
        """Blocks of the data lines (after the skipped lines, the header and the units row)
        with the number of their first line; fills ``columns`` on the way."""
        skip = self.options["skip_rows"]
        stage = 0  # 0: skipped lines, 1: header, 2: units row, 3: data
        for line, block in self._lines():
            while stage < 3 and block:
                if stage == 0 and line > skip:
                    stage = 1
                cut = block.find(b"\n") + 1 or len(block)
                raw, block = block[:cut], block[cut:]
                if stage == 0:
                    self.skipped.append(raw.decode(self.work, errors="replace").rstrip("\r\n"))
                elif not (self.comment and raw.startswith(self.comment)):
                    if stage == 1:
                        text = self._text(raw, line, "the header")
                        if not text.strip():
                            raise _ReadError(
                                f"line {line}, where the header should be, is empty; expected "
                                "a header line naming the columns"
                            )
                        fields = self._split(text.lstrip("\ufeff"))
                        if self._headerless(fields):  # the line is data: put it back
                            self.headerless = True
                            self.columns = [POSITIONAL.format(i + 1) for i in range(len(fields))]
                            block = raw + block
                            stage = 3
                            continue
                        self.columns = fields
                        self.header_line = line
                        stage = 2 if self.options["units_row"] else 3
                    else:
                        self.units = self._split(self._text(raw, line, "the units row"))
                        stage = 3
                line += 1
            if block:
                yield line, block

    def _headerless(self, fields: list[str]) -> bool:
        """True when the file has no header line: ``csv: {header: false}``, or, when
        ``header`` is not given, a first line of numbers only (:func:`numbers_only`)."""
        header = self.options.get("header")
        if header is not None:
            return not header
        return not self.options["units_row"] and numbers_only(fields, self.options["decimal"])

    def describe(self, name: str) -> str:
        """The columns the file has, and, for a file without a header line, how they are
        named."""
        said = super().describe(name)
        if not self.headerless:
            return said
        return (
            f"{said} (no header line: the first line holds only numbers, so the columns are "
            f"named by position, {POSITIONAL.format(1)}, {POSITIONAL.format(2)}, ...; "
            "csv: {header: true} reads it as the header)"
        )

    def _prepare(self, block: bytes, line: int) -> tuple[bytes, npt.NDArray[np.int64] | None]:
        """A block as UTF-8 ``pyarrow`` reads; the numbers of its lines when some were
        dropped (comment lines)."""
        if not block.isascii():
            try:
                text = block.decode(self.work)
            except UnicodeDecodeError as exc:
                bad = line + block.count(b"\n", 0, exc.start)
                hint = (
                    "save the file as UTF-8 (in Excel: CSV UTF-8)"
                    if self.codec == "utf-8"
                    else self._fix()
                )
                raise _ReadError(
                    f"line {bad} is not {self._codec_name()} text (byte {block[exc.start]:#04x}); "
                    f"{hint}"
                ) from None
            if self.work != "utf-8":
                block = text.encode("utf-8")
        kept = None
        comment = self.comment_utf8
        if comment is not None and (block.startswith(comment) or b"\n" + comment in block):
            lines = block.split(b"\n")
            if not lines[-1]:
                lines.pop()
            keep = [not x.startswith(comment) for x in lines]
            kept = line + np.flatnonzero(keep)
            block = b"".join(x + b"\n" for x, k in zip(lines, keep, strict=True) if k)
        if self.options["sep"] == WHITESPACE:
            block = _squeeze_blanks(block)
        if self.options["decimal"] == ",":
            block = block.replace(b",", b".")
        return block, kept

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
            parse_options=pacsv.ParseOptions(delimiter=self.sep, invalid_row_handler=handler),
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
        offset = 0
        try:
            for line, raw in self._data():
                block, kept = self._prepare(raw, line)
                if not block:
                    continue
                invalid: list[Any] = []
                table = self._parse(block, names, kind, True, invalid)
                if invalid:  # parse again on one thread, which numbers the bad lines
                    invalid = []
                    table = self._parse(block, names, kind, False, invalid)
                lines = block.count(b"\n") + (not block.endswith(b"\n"))
                for row in invalid:
                    number = None
                    if row.number is not None:
                        index = row.number - 1
                        number = line + index if kept is None else int(kept[index])
                    self.invalid.append(
                        (number, row.text, row.expected_columns, row.actual_columns)
                    )
                table_rows = table.num_rows
                self.blocks.append((offset + 1, line, table_rows == lines, kept))
                values: dict[str, npt.NDArray[np.float64]] = {}
                bad: dict[str, npt.NDArray[np.bool_]] = {}
                for name in names:
                    col = table.column(name)
                    if as_text:
                        values[name], bad[name] = _text_to_float(col)
                    else:
                        values[name] = col.to_numpy().astype(np.float64, copy=False)
                del table
                yield offset, values, bad
                offset += table_rows
                # hand the parser's buffers back now: under load the allocator may keep them
                pa.default_memory_pool().release_unused()
        except pa.ArrowInvalid as exc:
            if not as_text and "conversion error" in str(exc):
                raise _Retry from exc
            raise _ReadError(f"cannot parse the CSV file: {exc}") from exc

    def line_of(self, row: int | None) -> int | None:
        """Line of data row ``row`` (1-based), when blank or malformed lines do not blur it."""
        if row is None:
            return None
        for first_row, first_line, exact, kept in reversed(self.blocks):
            if row >= first_row:
                if not exact:
                    return None
                return first_line + row - first_row if kept is None else int(kept[row - first_row])
        return None
