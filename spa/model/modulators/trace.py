"""A logged valve command read as a pulse train: what each kind's ``guess`` looks at.

``spa init`` (:func:`spa.datasets.draft.guess_modulator`) builds one :class:`Trace` from a
run's time, valve and input columns and asks every kind, in :attr:`ModulatorKind.guess_rank`
order, whether the pulses look like its own; the first that answers wins.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

__all__ = ["Trace", "duty_matches", "on_grid", "sig", "steady", "threshold_gain"]

_Array = npt.NDArray[np.float64]


def sig(x: float, digits: int = 3) -> float:
    """``x`` rounded to ``digits`` significant digits."""
    if x == 0 or not math.isfinite(x):
        return x
    return round(x, digits - 1 - math.floor(math.log10(abs(x))))


def steady(d: _Array, tol: float) -> tuple[float, float]:
    """Median of ``d`` and the fraction of ``d`` within ``tol`` of it."""
    if d.size == 0:
        return math.nan, 0.0
    m = float(np.median(d))
    return m, float(np.mean(np.abs(d - m) <= tol))


def on_grid(d: _Array, step: float, tol: float) -> float:
    """Fraction of ``d`` that are whole multiples of ``step`` (within ``tol``)."""
    if d.size == 0 or step <= 0:
        return 0.0
    r = d / step
    return float(np.mean(np.abs(r - np.round(r)) * step <= tol))


def duty_matches(u_at_rise: _Array, duty: _Array, step: float) -> bool:
    """True when 90 % of PWM pulses last ``u`` of the period (``u`` read at the rise), to two
    samples (``step`` = sample step / period) and 2 %: what tells PWM from a ΔΣ pattern
    that repeats on the same period."""
    return float(np.mean(np.abs(duty - u_at_rise) <= 2 * step + 0.02)) >= 0.9


def threshold_gain(drive: _Array, on: _Array, starts: npt.NDArray[np.intp]) -> float:
    """Gain G of an integrate-and-fire modulator from its firings.

    Each firing adds one pulse of width ``w`` (``on`` = the valve for IPFM, ``1 - valve`` for
    IIPFM; back-to-back pulses merge into one long one) and comes ``G w`` of integral of
    ``drive`` (``u`` for IPFM, ``1 - u`` for IIPFM) after the previous one, so from the first
    pulse's start to the last one's, ``G = ∫drive / ∫on``.
    """
    span = slice(starts[0], starts[-1])
    total = float(np.sum(on[span]))
    return float(np.sum(drive[span]) / total) if total > 0 else math.nan


@dataclass(frozen=True)
class Trace:
    """Edges and whole pulses of a 0/1 valve command sampled every ``dt``.

    Attributes
    ----------
    v, u : numpy.ndarray
        The command and the input fraction (``u`` None when not logged).
    dt, tol : float
        Sample step and the tolerance of time comparisons (half a sample).
    d : numpy.ndarray
        ``diff(v)``: +1 at a rise, -1 at a fall.
    rise, fall : numpy.ndarray
        Edge times, s.
    highs, lows : numpy.ndarray
        Durations of the whole high and low pulses, s.
    ok_h : numpy.ndarray of bool
        The rises that start a whole high pulse.
    """

    v: _Array
    u: _Array | None
    dt: float
    tol: float
    d: _Array
    rise: _Array
    fall: _Array
    highs: _Array
    lows: _Array
    ok_h: npt.NDArray[np.bool_]

    @classmethod
    def from_samples(cls, t: _Array, v: _Array, u: _Array | None, dt: float) -> Trace:
        """The edges and whole pulses of ``v`` sampled at ``t`` (at least one rise and fall)."""
        d = np.diff(v)
        rise, fall = t[1:][d > 0], t[1:][d < 0]
        # whole high and low pulses: between a rise and the next fall, a fall and the next rise
        nxt_fall = np.searchsorted(fall, rise)
        ok_h = nxt_fall < fall.size
        highs = fall[nxt_fall[ok_h]] - rise[ok_h]
        nxt_rise = np.searchsorted(rise, fall)
        ok = nxt_rise < rise.size
        lows = rise[nxt_rise[ok]] - fall[ok]
        return cls(v, u, dt, 0.51 * dt + 1e-9, d, rise, fall, highs, lows, ok_h)

    @property
    def count(self) -> str:
        """``"N high and M low pulses"``, for a reason string."""
        return f"{self.highs.size} high and {self.lows.size} low pulses"

    @property
    def shares(self) -> tuple[float, float]:
        """Fractions of the high and of the low pulses at their median duration."""
        return steady(self.highs, self.tol)[1], steady(self.lows, self.tol)[1]
