"""MATLAB ``.mat`` files (v5, flat vectors): loaded whole by ``scipy.io.loadmat``."""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import Any

import numpy as np

from spa.datasets.contract import _BATCH_ROWS
from spa.datasets.readers.base import _Chunk, _ReadError


class _MatSource:
    """A MATLAB v4/v5/v7 ``.mat`` file holding one vector variable per column."""

    def __init__(self, path: Path, options: Mapping[str, Any] | None = None) -> None:
        del options  # nothing to choose: the file says how it is written
        import scipy.io

        self.path = path
        try:
            self.data = scipy.io.loadmat(path, squeeze_me=False, mat_dtype=False)
        except NotImplementedError as exc:
            raise _ReadError(
                "MATLAB v7.3 (HDF5) files are not supported; save with "
                "save(..., '-v7') or export CSV/Parquet"
            ) from exc
        except Exception as exc:  # scipy raises several types for a damaged file
            raise _ReadError(
                f"unreadable MATLAB file (truncated, damaged or not a .mat file?): "
                f"{type(exc).__name__}: {exc}"
            ) from exc
        self.columns = [k for k in self.data if not k.startswith("__")]

    def check_types(self, names: list[str]) -> list[_ReadError]:
        errors = []
        lengths: dict[str, int] = {}
        for name in names:
            value = self.data[name]
            if not isinstance(value, np.ndarray) or value.dtype.kind not in "biuf":
                kind = getattr(value, "dtype", type(value).__name__)
                errors.append(
                    _ReadError(
                        f"MATLAB variable holds {kind}, not real numbers; "
                        "expected a numeric vector",
                        column=name,
                    )
                )
            elif value.ndim > 2 or (value.ndim == 2 and min(value.shape) > 1):
                errors.append(
                    _ReadError(
                        f"MATLAB variable has shape {value.shape}; expected a vector (n×1 or 1×n)",
                        column=name,
                    )
                )
            else:
                lengths[name] = value.size
        if len(set(lengths.values())) > 1:
            sizes = ", ".join(f"{k}: {v}" for k, v in lengths.items())
            errors.append(
                _ReadError(
                    f"MATLAB variables have different lengths ({sizes}); expected one length"
                )
            )
        return errors

    def chunks(self, names: list[str], as_text: bool = False) -> Iterator[_Chunk]:
        arrays = {n: np.asarray(self.data[n], dtype=np.float64).ravel() for n in names}
        n = len(next(iter(arrays.values()))) if arrays else 0
        for start in range(0, n, _BATCH_ROWS):
            yield start, {k: v[start : start + _BATCH_ROWS] for k, v in arrays.items()}, {}
