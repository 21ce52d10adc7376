"""Does a run's input have the shape its kind says? A staircase, a sine, a chirp.

The open-loop analyses assume the input fraction ``u`` of a run has the shape of its kind; a
run labelled wrongly in ``dataset.yaml`` would otherwise be analysed into numbers that mean
nothing. :func:`check_input_shape` says, in a sentence, why an input is not of its kind.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from spa.errors import RunError

__all__ = ["check_input_shape", "input_shape_problem"]

#: Share of the input's variance that a sine's strongest frequency must carry.
SINE_POWER = 0.5
#: A chirp's last zero-crossing intervals must be this much shorter than its first.
CHIRP_SPEEDUP = 1.5


def _staircase(u: np.ndarray) -> str | None:
    levels = u[np.r_[True, np.diff(u) != 0.0]]
    if levels.size < 2:
        return "u is constant: a staircase has at least two levels"
    steps = np.diff(levels)
    if np.any(steps < 0.0) and np.any(steps > 0.0):  # up, or down (a plan's way back), not both
        return "u goes both up and down between levels: a staircase steps one way, up or down"
    if levels.size > 0.01 * u.size + 2:
        return f"u changes on {levels.size - 1} samples: a staircase holds each level"
    return None


def _sine(u: np.ndarray) -> str | None:
    x = u - u.mean()
    crossings = int(np.count_nonzero(np.signbit(x[1:]) != np.signbit(x[:-1])))
    if crossings < 4:
        return f"u crosses its mean {crossings} times: a sine oscillates (two periods or more)"
    power = np.abs(np.fft.rfft(x)) ** 2
    power[0] = 0.0
    total = power.sum()
    if total <= 0.0:
        return "u is constant: a sine oscillates"
    k = int(np.argmax(power))
    share = power[max(k - 2, 1) : k + 3].sum() / total
    if share < SINE_POWER:
        return (
            f"its strongest frequency carries {share:.0%} of u's variance; a sine's carries "
            f"at least {SINE_POWER:.0%}"
        )
    return None


def _chirp(u: np.ndarray) -> str | None:
    x = u - np.median(u)
    crossings = np.flatnonzero(np.signbit(x[1:]) != np.signbit(x[:-1]))
    if crossings.size < 8:
        return f"u crosses its median {crossings.size} times: a chirp oscillates"
    gaps = np.diff(crossings).astype(np.float64)
    quarter = max(gaps.size // 4, 1)
    first, last = gaps[:quarter].mean(), gaps[-quarter:].mean()
    if first < CHIRP_SPEEDUP * last:
        return (
            f"its oscillation does not speed up (median crossings every {first:.0f} samples "
            f"at the start, {last:.0f} at the end): a chirp's frequency rises"
        )
    return None


_CHECKS = {"staircase": _staircase, "sine": _sine, "chirp": _chirp}


def input_shape_problem(kind: str, u: npt.ArrayLike) -> str | None:
    """Why the input ``u`` of a run is not of ``kind``, or None when it is (or ``kind`` has no
    shape to check).

    Examples
    --------
    >>> t = np.arange(0, 20, 1e-3)
    >>> input_shape_problem("staircase", np.floor(t / 5) / 4) is None
    True
    >>> input_shape_problem("staircase", 1 - np.floor(t / 5) / 4) is None  # stepping down
    True
    >>> input_shape_problem("staircase", 0.5 + 0.4 * np.sin(t))
    'u goes both up and down between levels: a staircase steps one way, up or down'
    >>> input_shape_problem("sine", 0.5 + 0.2 * np.sin(2 * np.pi * 0.5 * t)) is None
    True
    >>> input_shape_problem("chirp", 0.5 + 0.2 * np.sin(2 * np.pi * 0.5 * t))[:40]
    'its oscillation does not speed up (media'
    """
    check = _CHECKS.get(kind)
    arr = np.asarray(u, dtype=np.float64)
    arr = arr[np.isfinite(arr)]
    if check is None or arr.size < 16:
        return None
    return check(arr)


def check_input_shape(run: str, kind: str, u: npt.ArrayLike) -> None:
    """Raise :class:`~spa.errors.RunError` naming ``run`` when its input is not of its ``kind``.

    Raises
    ------
    spa.pipeline.status.RunError
        A ValueError: ``run 'x' is labelled <kind> but <why>; check its kind in dataset.yaml``.
    """
    problem = input_shape_problem(kind, u)
    if problem is not None:
        raise RunError(
            f"run {run!r} is labelled {kind} but {problem}; check its kind in dataset.yaml"
        )
