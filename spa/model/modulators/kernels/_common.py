"""What every modulator kernel shares."""

from __future__ import annotations

import math

import numpy as np
from numba import njit

#: The relative tolerance of :mod:`spa.model.modulators` for event times (the same value:
#: tests/test_closed_loop.py checks it).
EPS = 1e-9


def pulse_steps(width: float, dt: float) -> int:
    """Steps a pulse of ``width`` s lasts, at least one (the open-loop modulators' rule)."""
    return max(1, math.floor(width / dt + 0.5))


@njit(cache=True)
def next_start(j: float, period: float, dt: float, k: int) -> tuple[float, int]:  # pragma: no cover
    """The first period index after ``j`` whose start ``ceil(j*period/dt - eps)`` lies after
    step ``k``, and that start (PWM's periods, ΔΣM's ticks)."""
    j += 1.0
    nxt = math.ceil(j * period / dt - EPS)
    while nxt <= k:  # a start that falls on this step again (never for period >= 2*dt)
        j += 1.0
        nxt = math.ceil(j * period / dt - EPS)
    return j, nxt


def c_next_start(j: str) -> str:
    """:func:`next_start` in C99, inline in a kernel's step, with the index variable ``j``:
    sets ``st[0]`` and ``st[1]`` (the caller declares ``j`` and ``nxt``)."""
    return f"""\
        {j} = st[0] + 1.0;
        nxt = ceil({j} * period / dt - ${{eps}});
        while (nxt <= (double)k) {{
            {j} += 1.0;
            nxt = ceil({j} * period / dt - ${{eps}});
        }}
        st[0] = {j};
        st[1] = nxt;
"""


def fire_config(gain: float, width: float, dt: float) -> np.ndarray:
    """Constants of an integrate-and-fire kernel (IPFM, IIPFM) firing pulses of ``width`` s:
    ``[threshold gain*width in steps, pulse width in steps]``."""
    return np.array([gain * width / dt, float(pulse_steps(width, dt))])


@njit(cache=True)
def integrate_and_fire(  # pragma: no cover
    k: int, x: float, threshold_steps: float, width: float, st
) -> int:
    """One step of an integrator of ``x`` with reset by subtraction that fires pulses.

    ``st = [integral up to t_k in steps, index of the next threshold multiple, end of the
    pulse]``. It fires at step ``k`` when the integral up to ``t_k`` has crossed
    ``(m - eps)*threshold_steps`` (the law of ``spa.model.modulators._firings``); a firing
    starts (or extends) a pulse of ``width`` steps. Returns 1 while the pulse runs.
    """
    while st[0] >= (st[1] - EPS) * threshold_steps:
        st[1] += 1.0
        st[2] = k + width
    st[0] += x
    return 1 if k < st[2] else 0


#: :func:`integrate_and_fire` in C99 (:mod:`spa.closedloop.export` fills ``${p}``, the name
#: prefix, and ``${eps}``, :data:`EPS`): the same operations in the same order.
C_INTEGRATE_AND_FIRE = """
static int ${p}_fire(long long k, double x, double threshold_steps, double width, double *st)
{
    while (st[0] >= (st[1] - ${eps}) * threshold_steps) {
        st[1] += 1.0;
        st[2] = (double)k + width;
    }
    st[0] += x;
    return (double)k < st[2] ? 1 : 0;
}
"""
