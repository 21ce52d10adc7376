"""The input fractions of the open-loop experiments: staircase, sine and chirp."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import numpy.typing as npt

__all__ = ["chirp_input", "sine_input", "staircase_input"]

# ---- input signals ----------------------------------------------------------------------


def staircase_input(t: npt.ArrayLike, step: float = 0.1, hold: float = 5.0) -> np.ndarray:
    """Staircase of the input fraction: 0, ``step``, ``2*step``, ... held ``hold`` s each, up to 1.

    Parameters
    ----------
    t : array_like
        Times in s, from 0.
    step : float
        Increment of the input fraction per level (paper: 0.1).
    hold : float
        Duration of each level in s (paper: 5 s).

    Returns
    -------
    numpy.ndarray
        ``min(floor(t/hold)*step, 1)``.

    Examples
    --------
    >>> staircase_input([0.0, 4.9, 5.0, 12.0, 99.0]).tolist()
    [0.0, 0.0, 0.1, 0.2, 1.0]
    """
    if not (step > 0 and hold > 0):
        raise ValueError(f"step and hold must be > 0, got step={step!r}, hold={hold!r}")
    t = np.asarray(t, dtype=np.float64)
    level = np.floor(t / hold + 1e-9)
    return np.minimum(np.round(level * step, 12), 1.0)


def sine_input(
    t: npt.ArrayLike,
    frequency: float,
    amplitudes: Sequence[float],
    periods_per_level: int = 2,
    offset: float = 0.5,
) -> np.ndarray:
    """Fixed-frequency sine whose amplitude decreases piece-wise (Fig. 8's input).

    Level ``i`` lasts ``periods_per_level`` whole periods with amplitude ``amplitudes[i]``;
    after the last level the input stays at ``offset``.

    Parameters
    ----------
    t : array_like
        Times in s, from 0.
    frequency : float
        Sine frequency in Hz.
    amplitudes : sequence of float
        Amplitude of each level (input-fraction units), e.g. ``[0.5, 0.4, 0.3, 0.2, 0.1]``.
    periods_per_level : int
        Whole periods per amplitude level.
    offset : float
        Mean input fraction.

    Returns
    -------
    numpy.ndarray
        ``offset + A(t) * sin(2*pi*frequency*t)``.
    """
    if frequency <= 0 or periods_per_level < 1 or not amplitudes:
        raise ValueError("frequency must be > 0, periods_per_level >= 1, amplitudes non-empty")
    t = np.asarray(t, dtype=np.float64)
    level = np.floor(t * frequency / periods_per_level + 1e-9).astype(np.int64)
    amp = np.asarray([*amplitudes, 0.0], dtype=np.float64)
    a = amp[np.minimum(level, len(amplitudes))]
    return offset + a * np.sin(2 * np.pi * frequency * t)


def chirp_input(
    t: npt.ArrayLike,
    f0: float = 0.1,
    f1: float = 100.0,
    duration: float | None = None,
    offset: float = 0.5,
    amplitude: float = 0.25,
    method: str = "linear",
) -> np.ndarray:
    """Chirp of the input fraction (Fig. 9's input: 0.1 to 100 Hz, 0.5 ± 0.25).

    Parameters
    ----------
    t : array_like
        Times in s, from 0.
    f0, f1 : float
        Start and end frequencies in Hz.
    duration : float, optional
        Sweep time in s (default: the span of ``t``).
    offset, amplitude : float
        Mean and amplitude of the input fraction.
    method : {"linear", "logarithmic"}, default "linear"
        How the frequency sweeps: linearly in time (the paper's chirp), or geometrically
        (``f0 > 0``), which spends as long on each decade.

    Returns
    -------
    numpy.ndarray
        ``offset + amplitude*sin(phase)``; linear:
        ``phase = 2*pi*(f0*t + (f1 - f0)*t**2/(2*duration))``, logarithmic:
        ``phase = 2*pi*f0*duration*(k**(t/duration) - 1)/ln(k)`` with ``k = f1/f0``
        (instantaneous frequency ``f0*k**(t/duration)``).
    """
    t = np.asarray(t, dtype=np.float64)
    if duration is None:
        duration = float(t[-1]) if t.size > 1 else 1.0
    if f0 < 0 or f1 <= 0 or duration <= 0:
        raise ValueError("need f0 >= 0, f1 > 0 and duration > 0")
    if method == "linear":
        phase = 2 * np.pi * (f0 * t + (f1 - f0) * t**2 / (2 * duration))
    elif method == "logarithmic":
        if f0 <= 0 or f1 == f0:
            raise ValueError("a logarithmic chirp needs f0 > 0 and f1 != f0")
        log_k = np.log(f1 / f0)
        phase = 2 * np.pi * f0 * duration * np.expm1(log_k * t / duration) / log_k
    else:
        raise ValueError(f"method must be 'linear' or 'logarithmic', got {method!r}")
    return offset + amplitude * np.sin(phase)
