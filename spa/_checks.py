"""Argument checks shared by spa's public functions: one place for the same few rules.

Every check validates one argument at the boundary of a public function and returns it in
the form the function computes with (a float, an int, a float64 array). A bad value raises
:class:`ValueError` naming the argument and the allowed range; a value of the wrong type
(a string, ``None``, a boolean where a number is expected: YAML's ``true`` is not 1 Hz)
raises :class:`ArgumentTypeError`, which is both a :class:`TypeError` and a
:class:`ValueError` so that callers catching either see it.

``name`` is whatever the message should call the argument, e.g. ``"n_xi"`` or
``"pwm: setting 'f_w'"``.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import numpy.typing as npt

__all__ = [
    "ArgumentTypeError",
    "finite_array",
    "float_or_nan",
    "fraction",
    "integer",
    "nonnegative",
    "number",
    "positive",
    "positive_array",
]

#: Most points a sweep (``analytic.sweeps.*``, ``tuning.gain_sweep``) may have.
MAX_SWEEP_POINTS = 100_000
#: Most values of one cost evaluation, sweep points x ``n_xi`` (x gains): 160 MB per array.
MAX_GRID_VALUES = 20_000_000

_REALS = (int, float, np.integer, np.floating)


class ArgumentTypeError(TypeError, ValueError):
    """An argument of the wrong type (also a ValueError, as spa's other argument errors)."""


def number(name: str, value: Any) -> float:
    """``value`` as a float; booleans, strings and other non-numbers are refused.

    Raises
    ------
    ArgumentTypeError
        If ``value`` is not a real number (``bool`` is refused).

    Examples
    --------
    >>> number("gain", 2)
    2.0
    """
    if isinstance(value, bool | np.bool_) or not isinstance(value, _REALS):
        raise ArgumentTypeError(f"{name} must be a number, got {value!r}")
    return float(value)


def float_or_nan(value: Any) -> float:
    """``float(value)``, or NaN when ``value`` is not a number (a missing YAML key, a string).

    For reading an optional number back from a written file: the caller decides what a NaN
    means; nothing is raised.

    Examples
    --------
    >>> float_or_nan("2.5"), float_or_nan(None), float_or_nan("n/a")
    (2.5, nan, nan)
    """
    try:
        return float(value)
    except (TypeError, ValueError):
        return math.nan


def _unit(unit: str) -> str:
    return f" {unit}" if unit else ""


def positive(name: str, value: Any, unit: str = "") -> float:
    """A finite number > 0.

    Raises
    ------
    ArgumentTypeError
        If ``value`` is not a number.
    ValueError
        If it is not finite or not > 0; the message names ``name`` and the range.

    Examples
    --------
    >>> positive("dt", 1e-3, "s")
    0.001
    >>> positive("dt", 0.0, "s")
    Traceback (most recent call last):
    ...
    ValueError: dt must be finite and > 0 s, got 0.0
    """
    v = number(name, value)
    if not (math.isfinite(v) and v > 0.0):
        raise ValueError(f"{name} must be finite and > 0{_unit(unit)}, got {value!r}")
    return v


def nonnegative(name: str, value: Any, unit: str = "") -> float:
    """A finite number >= 0; raises as :func:`positive` does, for a negative value."""
    v = number(name, value)
    if not (math.isfinite(v) and v >= 0.0):
        raise ValueError(f"{name} must be finite and >= 0{_unit(unit)}, got {value!r}")
    return v


def fraction(name: str, value: Any, *, low_open: bool = False, high_open: bool = False) -> float:
    """A number in [0, 1]; ``low_open``/``high_open`` exclude the end points.

    Raises
    ------
    ArgumentTypeError
        If ``value`` is not a number.
    ValueError
        If it is outside the interval; the message writes the interval, e.g. ``(0, 1]``.

    Examples
    --------
    >>> fraction("settle", 0.4, low_open=True)
    0.4
    """
    v = number(name, value)
    above = v > 0.0 if low_open else v >= 0.0
    below = v < 1.0 if high_open else v <= 1.0
    if not (above and below):
        interval = f"{'(' if low_open else '['}0, 1{')' if high_open else ']'}"
        raise ValueError(f"{name} must be a fraction in {interval}, got {value!r}")
    return v


def integer(name: str, value: Any, minimum: int = 1) -> int:
    """An integer >= ``minimum`` (a float such as ``10.0`` or a bool is refused).

    Raises
    ------
    ArgumentTypeError
        If ``value`` is not an integer.
    ValueError
        If it is below ``minimum``.

    Examples
    --------
    >>> integer("n_xi", 100, minimum=2)
    100
    """
    if isinstance(value, bool | np.bool_) or not isinstance(value, int | np.integer):
        raise ArgumentTypeError(f"{name} must be an integer >= {minimum}, got {value!r}")
    if value < minimum:
        raise ValueError(f"{name} must be an integer >= {minimum}, got {value!r}")
    return int(value)


def _where(name: str, bad: npt.NDArray[np.bool_], x: npt.NDArray[np.float64]) -> str:
    """``name[i] = value`` of the first flagged element (``name = value`` for a scalar)."""
    if x.ndim == 0:
        return f"{name} = {float(x[()])!r}"
    first = np.unravel_index(int(np.flatnonzero(bad)[0]), x.shape)
    return f"{name}[{', '.join(str(int(i)) for i in first)}] = {float(x[first])!r}"


def finite_array(
    name: str, value: Any, *, ndim: int | None = None, min_size: int = 0
) -> npt.NDArray[np.float64]:
    """``value`` as a float64 array of finite numbers.

    Parameters
    ----------
    name : str
        Name of the argument, for messages.
    value : array_like
        The argument.
    ndim : int, optional
        Required number of dimensions (1 for a signal).
    min_size : int, default 0
        Fewest elements allowed.

    Raises
    ------
    ArgumentTypeError
        If ``value`` is not numeric.
    ValueError
        For the wrong number of dimensions, too few elements, or a NaN or infinity (the
        message gives the first one's index).

    Examples
    --------
    >>> finite_array("xi", [0.0, float("nan")], ndim=1)
    Traceback (most recent call last):
    ...
    ValueError: xi must be finite; xi[1] = nan
    """
    x = _numeric(name, value)
    if ndim is not None and x.ndim != ndim:
        what = "one-dimensional" if ndim == 1 else f"{ndim}-dimensional"
        raise ValueError(f"{name} must be a {what} array, got shape {x.shape}")
    if x.size < min_size:
        raise ValueError(f"{name} must hold at least {min_size} values, got {x.size}")
    bad = ~np.isfinite(x)
    if np.any(bad):
        raise ValueError(f"{name} must be finite; {_where(name, bad, x)}")
    return x


def _numeric(name: str, value: Any) -> npt.NDArray[np.float64]:
    """``value`` as a float64 array; ArgumentTypeError naming ``name`` when not numeric."""
    if isinstance(value, str | bytes):
        raise ArgumentTypeError(f"{name} must be numeric, got {value!r}")
    try:
        return np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise ArgumentTypeError(f"{name} must be numeric, got {value!r}") from None


def positive_array(name: str, value: Any) -> npt.NDArray[np.float64]:
    """``value`` as a float64 array, finite and > 0 everywhere.

    Raises
    ------
    ArgumentTypeError
        If ``value`` is not numeric.
    ValueError
        If an element is not finite or not > 0 (the message gives the first).

    Examples
    --------
    >>> positive_array("period", [0.02, 0.0])
    Traceback (most recent call last):
    ...
    ValueError: period must be finite and > 0 everywhere; period[1] = 0.0
    """
    x = _numeric(name, value)
    bad = ~(np.isfinite(x) & (x > 0.0))
    if np.any(bad):
        raise ValueError(f"{name} must be finite and > 0 everywhere; {_where(name, bad, x)}")
    return x
