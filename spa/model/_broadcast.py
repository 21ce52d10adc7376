"""Private helpers of the averaged analysis: broadcasting inputs and NumPy-scalar outputs.

:mod:`spa.model.averaging`, :mod:`spa.model.chattering` and :mod:`spa.model.thresholds` take
``xi`` and modulator settings as scalars or arrays that broadcast (NumPy rules) and give a
NumPy scalar back when every input was a scalar.
"""

from __future__ import annotations

from typing import TypeAlias

import numpy as np
import numpy.typing as npt

from spa import _checks as checks

__all__ = ["Floats", "as_output", "input_fraction", "safe_div"]

#: A float64 array, or a NumPy float scalar when every input was a scalar.
Floats: TypeAlias = npt.NDArray[np.float64] | np.float64


def input_fraction(xi: npt.ArrayLike) -> npt.NDArray[np.float64]:
    """``xi`` as a finite float64 array clipped to [0, 1] (as the modulators clip it)."""
    return np.clip(checks.finite_array("xi", xi), 0.0, 1.0)


def as_output(a: npt.ArrayLike) -> Floats:
    """0-d arrays become NumPy scalars; other arrays pass through (as float64)."""
    return np.asarray(a, dtype=np.float64)[()]


def safe_div(num: npt.ArrayLike, den: npt.ArrayLike, fill: float) -> npt.NDArray[np.float64]:
    """``num/den`` where ``den != 0``, else ``fill``; never warns."""
    num, den = np.broadcast_arrays(np.asarray(num, np.float64), np.asarray(den, np.float64))
    out = np.full(num.shape, fill, dtype=np.float64)
    np.divide(num, den, out=out, where=den != 0.0)
    return out
