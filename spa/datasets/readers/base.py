"""What every reader returns: chunks of float columns, and the errors a reader raises."""

from __future__ import annotations

import numpy as np
import numpy.typing as npt
import pandas as pd
import pyarrow as pa

from spa.datasets.contract import _NA_TOKENS

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
