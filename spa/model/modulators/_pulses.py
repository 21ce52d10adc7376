"""Sampled pulse laws shared by the modulator kinds (vectorised, no per-sample loop).

``x[k]`` is the input fraction at ``t = k*dt`` (already clipped to [0, 1]); every function
returns the 0/1 command held over ``[k*dt, (k+1)*dt)`` or the step indices of its events.
Event times are quantised to the step: a pulse of width ``w`` lasts ``round(w/dt)`` steps
(at least one).
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

__all__ = ["EPS", "fire_pulses", "from_edges", "period_starts", "pwm", "steps", "ticks_held"]

#: Relative tolerance used when comparing accumulated floating-point times to event times.
EPS = 1e-9


def steps(width: float, dt: float) -> int:
    """Number of steps a pulse of ``width`` seconds lasts (at least one)."""
    return max(1, math.floor(width / dt + 0.5))


def first_steps(times: npt.NDArray[np.float64], dt: float) -> npt.NDArray[np.int64]:
    """Index of the first step at or after each event time (to a relative tolerance)."""
    return np.ceil(times / dt - EPS).astype(np.int64)


def from_edges(
    n: int, rise: npt.NDArray[np.int64], fall: npt.NDArray[np.int64]
) -> npt.NDArray[np.int8]:
    """0/1 signal high on the union of the intervals ``[rise[i], fall[i])`` (clipped to n)."""
    d = np.zeros(n + 1, dtype=np.int32)
    np.add.at(d, np.minimum(rise, n), 1)
    np.subtract.at(d, np.minimum(fall, n), 1)
    return (np.cumsum(d[:-1]) > 0).view(np.int8)


def period_starts(n: int, dt: float, period: float) -> npt.NDArray[np.int64]:
    """First step of each clock period ``m*period`` that starts within ``n`` steps."""
    m = np.arange(math.floor(n * dt / period) + 2)
    starts = first_steps(m * period, dt)
    starts = starts[starts < n]
    return np.unique(starts)


def pwm(duty: npt.NDArray[np.float64], dt: float, f_w: float) -> npt.NDArray[np.int8]:
    """PWM at ``f_w`` Hz: ``duty`` sampled at the start of each period, high that fraction."""
    period = 1.0 / f_w
    starts = period_starts(duty.size, dt, period)  # the duty is sampled at these steps
    t_start = np.arange(starts.size) * period
    ends = first_steps(t_start + duty[starts] * period, dt)
    nxt = np.append(starts[1:], duty.size)
    ends = np.clip(ends, starts, nxt)
    return from_edges(duty.size, starts, ends)


def firings(x: npt.NDArray[np.float64], dt: float, threshold: float) -> npt.NDArray[np.int64]:
    """Steps at which an integrate-and-fire modulator with reset-by-subtraction fires.

    The integral up to ``t_k`` (exclusive, in units of ``dt``) crosses the m-th multiple of
    the threshold exactly where the integrator with subtraction reaches the threshold.
    """
    n_steps = threshold / dt
    c = np.cumsum(x)  # c[k] = integral up to t_{k+1}
    total = math.floor(c[-1] / n_steps + EPS) if c.size else 0
    targets = (np.arange(1, total + 1) - EPS) * n_steps
    fire = np.searchsorted(c, targets, side="left") + 1  # first k with integral(t_k) >= target
    return np.unique(fire[fire < x.size])


def fire_pulses(
    x: npt.NDArray[np.float64], dt: float, threshold: float, width: float
) -> npt.NDArray[np.int8]:
    """High pulses of ``width`` s fired each time the integral of ``x`` gains ``threshold``."""
    fire = firings(x, dt, threshold)
    return from_edges(x.size, fire, fire + steps(width, dt))


def ticks_held(x: npt.NDArray[np.float64], dt: float, period: float) -> npt.NDArray[np.int8]:
    """First-order ΔΣ clocked every ``period`` s, each decision held until the next tick.

    The number of ones up to tick ``m`` is ``floor(S_m + 1/2)`` with ``S_m`` the running sum
    of the sampled input (induction on ``m`` for ``x`` in [0, 1]); ``u_m`` is its increment.
    """
    ticks = period_starts(x.size, dt, period)
    s = np.cumsum(x[ticks])
    ones = np.floor(s + 0.5 + EPS)
    u_tick = np.diff(ones, prepend=0.0).astype(np.int8)
    lengths = np.diff(np.append(ticks, x.size))
    return np.repeat(u_tick, lengths)
