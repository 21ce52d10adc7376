"""Parquet files: read by record batches."""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt
import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.parquet as pq

from spa.datasets.contract import _BATCH_ROWS
from spa.datasets.readers.base import (
    Source,
    _Chunk,
    _numeric_type,
    _ReadError,
    _text_to_float,
    _text_type,
)


def _beyond_float(col: pa.Array) -> bool:
    """True when an integer column holds a value a float64 cannot represent exactly."""
    top = pc.max(pc.abs_checked(pc.cast(col, pa.int64()))) if len(col) else None
    return top is not None and top.is_valid and top.as_py() > 2**53


class _ParquetSource(Source):
    """A Parquet file, read by record batches."""

    def __init__(self, path: Path, options: Mapping[str, Any] | None = None) -> None:
        del options  # nothing to choose: the file says how it is written
        self.path = path
        try:
            self.file = pq.ParquetFile(path)
        except Exception as exc:  # pyarrow raises several types for a damaged file
            raise _ReadError(f"unreadable Parquet file (truncated or damaged?): {exc}") from exc
        self.schema = self.file.schema_arrow
        self.columns = list(self.schema.names)

    def check_types(self, names: list[str]) -> list[_ReadError]:
        errors = []
        for name in names:
            kind = self.schema.field(name).type
            if not (_numeric_type(kind) or _text_type(kind)):
                errors.append(
                    _ReadError(f"column has Parquet type {kind}; expected numbers", column=name)
                )
        return errors

    def chunks(self, names: list[str], as_text: bool = False) -> Iterator[_Chunk]:
        offset = 0
        try:
            for batch in self.file.iter_batches(batch_size=_BATCH_ROWS, columns=names):
                values: dict[str, npt.NDArray[np.float64]] = {}
                bad: dict[str, npt.NDArray[np.bool_]] = {}
                for name in names:
                    col = batch.column(name)
                    if _text_type(col.type):
                        values[name], bad[name] = _text_to_float(col)
                    elif pa.types.is_integer(col.type) and _beyond_float(col):
                        raise _ReadError(
                            f"integers from row {offset + 1} on reach 2^53 = {2**53}, beyond "
                            "what a float holds exactly (time in ns since 1970?); subtract the "
                            "start time, or store the column as float seconds",
                            column=name,
                        )
                    else:
                        values[name] = pc.cast(col, pa.float64()).to_numpy(zero_copy_only=False)
                yield offset, values, bad
                offset += batch.num_rows
        except (pa.ArrowException, OSError) as exc:
            raise _ReadError(
                f"unreadable Parquet data after row {offset} (truncated or damaged?): {exc}",
                row=offset + 1,
            ) from exc
