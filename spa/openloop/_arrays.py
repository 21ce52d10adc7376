"""Argument checks shared by the open-loop array functions."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

#: Fraction of a first-order step response reached after one time constant (63.2 %).
TAU_FRACTION = 1.0 - math.exp(-1.0)


# ---------------------------------------------------------------- validation helpers


def _array(name: str, a: Any, size: int | None = None, min_size: int = 1) -> np.ndarray:
    """``a`` as a finite one-dimensional float64 array, or ValueError naming ``name``."""
    try:
        x = np.asarray(a, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be an array of real numbers") from None
    if x.ndim != 1:
        raise ValueError(f"{name} must be a one-dimensional array, got shape {x.shape}")
    if size is not None and x.size != size:
        raise ValueError(f"{name} must have the same length as t ({size}), got {x.size}")
    if x.size < min_size:
        raise ValueError(f"{name} must hold at least {min_size} samples, got {x.size}")
    if not np.all(np.isfinite(x)):
        bad = int(np.flatnonzero(~np.isfinite(x))[0])
        raise ValueError(f"{name} must be finite; {name}[{bad}] = {x[bad]!r}")
    return x


def _time(t: Any) -> np.ndarray:
    tt = _array("t", t, min_size=2)
    if np.any(np.diff(tt) <= 0.0):
        bad = int(np.flatnonzero(np.diff(tt) <= 0.0)[0]) + 1
        raise ValueError(f"t must be strictly increasing; t[{bad}] = {tt[bad]!r} <= t[{bad - 1}]")
    return tt


def _fraction(name: str, value: Any) -> float:
    """A number in (0, 1], or ValueError naming it."""
    try:
        v = float(value)
    except (TypeError, ValueError):
        v = math.nan
    if not (0.0 < v <= 1.0):
        raise ValueError(f"{name} must be a fraction in (0, 1], got {value!r}")
    return v


def _nonnegative(name: str, value: Any, unit: str) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        v = math.nan
    if not (math.isfinite(v) and v >= 0.0):
        raise ValueError(f"{name} must be a finite number >= 0 ({unit}), got {value!r}")
    return v


def _valve(valve: Any, size: int) -> np.ndarray:
    v = _array("valve", valve, size=size)
    if not np.all((v == 0.0) | (v == 1.0)):
        bad = int(np.flatnonzero((v != 0.0) & (v != 1.0))[0])
        raise ValueError(f"valve must hold only 0 and 1; valve[{bad}] = {v[bad]!r}")
    return v


def uniform_step(t: np.ndarray, what: str, rtol: float = 1e-6) -> float:
    """The sample period of increasing times ``t``, or ValueError if they are not uniform."""
    steps = np.diff(t)
    dt = float(np.mean(steps))
    if np.max(np.abs(steps - dt)) > rtol * dt:
        raise ValueError(f"{what}: t must be uniformly sampled")
    return dt


def run_columns(run: Any, columns: tuple[str, ...], what: str) -> tuple[np.ndarray, ...]:
    """The named columns of a run table as float64 arrays, or ValueError naming the missing."""
    missing = [c for c in columns if c not in run.columns]
    if missing:
        raise ValueError(f"{what}: run table lacks column(s) {missing}; has {list(run.columns)}")
    return tuple(run[c].to_numpy(dtype=np.float64) for c in columns)
