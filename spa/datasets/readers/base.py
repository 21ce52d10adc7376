"""What every reader returns: chunks of float columns, and the errors a reader raises."""

from __future__ import annotations

from collections.abc import Iterator, Mapping, Sequence
from pathlib import Path
from typing import Any, ClassVar, Protocol

import numpy as np
import numpy.typing as npt
import pandas as pd
import pyarrow as pa

from spa.datasets.contract import _NA_TOKENS
from spa.datasets.problems import _one_of, _suggest

# --------------------------------------------------------------------------- readers


class _ReadError(Exception):
    """A file (or one of its columns) cannot be read; becomes a Problem."""

    def __init__(self, message: str, column: str | None = None, row: int | None = None):
        super().__init__(message)
        self.column = column
        self.row = row


class _Retry(Exception):
    """The fast CSV path met a value it cannot parse as a number: re-read as text."""


# A chunk: (rows before it, values by file column, non-numeric mask by file column or None).
_Chunk = tuple[int, dict[str, npt.NDArray[np.float64]], dict[str, npt.NDArray[np.bool_]]]


def _text_to_float(
    values: pa.Array | pa.ChunkedArray,
) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.bool_]]:
    """Parse text as numbers; return the values (NaN where missing) and a non-numeric mask."""
    obj = pd.Series(values.to_numpy(zero_copy_only=False), dtype=object)
    numbers = pd.to_numeric(obj, errors="coerce").to_numpy(dtype=np.float64, na_value=np.nan)
    stripped = obj.map(lambda s: s.strip() if isinstance(s, str) else "")
    bad = np.isnan(numbers) & ~stripped.isin(_NA_TOKENS).to_numpy()
    return numbers, bad


def _numeric_type(kind: pa.DataType) -> bool:
    return (
        pa.types.is_integer(kind)
        or pa.types.is_floating(kind)
        or pa.types.is_boolean(kind)
        or pa.types.is_decimal(kind)
        or pa.types.is_null(kind)
    )


def _text_type(kind: pa.DataType) -> bool:
    return pa.types.is_string(kind) or pa.types.is_large_string(kind)


# --------------------------------------------------------------------------- the protocol


class Source(Protocol):
    """What the ingest and ``spa init`` ask of a reader of one file format.

    A reader subclasses it: ``__init__``, :attr:`columns` and :meth:`chunks` are its own; the
    other hooks have the defaults below, which a format overrides where it knows more (a
    MATLAB file's field paths, a LabVIEW file's channels, a CSV file's line numbers). No
    caller asks whether a reader has a hook: every reader has them all.

    Parameters
    ----------
    path : pathlib.Path
        The run's file.
    options : mapping, optional
        The run's resolved ``csv:`` options; only delimited text uses them.
    """

    #: What the file calls a column, in messages (``"MATLAB variable"``, ``"LabVIEW channel"``).
    what: ClassVar[str] = "column"
    #: Field separator, named in messages about malformed lines (delimited text).
    sep: str | bytes = ","
    #: Malformed lines met by the last :meth:`chunks`: (line, text, fields expected, found).
    invalid: Sequence[tuple[int | None, str, int, int]] = ()
    #: The names in the file, in its order.
    columns: list[str]

    def __init__(self, path: Path, options: Mapping[str, Any] | None = None) -> None: ...

    def chunks(self, names: list[str], as_text: bool = False) -> Iterator[_Chunk]:
        """Chunks of the columns ``names``: (rows before, values, non-numeric masks or None);
        ``as_text``: parse text cells one by one (after :class:`_Retry`)."""
        ...

    def resolve(self, name: str) -> str | None:
        """The file's name for ``name`` (None when absent); raises :class:`_ReadError` when it
        is ambiguous."""
        return name if name in self.columns else None

    def describe(self, name: str) -> str:
        """What the file holds instead of a missing ``name``, for its message."""
        return (
            f"; the file has {_one_of(repr(c) for c in self.columns)}{_suggest(name, self.columns)}"
        )

    def check_types(self, names: list[str]) -> list[_ReadError]:
        """Problems of the columns' types known before reading (none by default)."""
        return []

    def line_of(self, row: int | None) -> int | None:
        """The file's line of data row ``row`` (1-based) where the format knows it; else None."""
        return None
