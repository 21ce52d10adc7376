"""PWM as a per-step state machine (the law of :func:`spa.model.modulators.modulate`).

Periods start at the steps ``ceil(j*period/dt - eps)``; at each start the input fraction is
sampled and the output is high until ``ceil((j*period + xi*period)/dt - eps)`` (never past
the next start, where the next sample overwrites it).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from spa.model.modulators.kernels._common import EPS

#: State: [period index j of the next start, step of the next start, end of the high part].
INITIAL = (0.0, 0.0, 0.0)


def configure(settings: dict[str, float], dt: float) -> np.ndarray:
    """Constants of the kernel: ``[period, dt]``."""
    return np.array([1.0 / settings["f_w"], dt])


@njit(cache=True)
def step(k: int, xi: float, cfg: np.ndarray, st: np.ndarray) -> int:  # pragma: no cover
    """Command ``u[k]`` for the input ``xi`` sampled at step ``k`` (updates ``st``)."""
    period = cfg[0]
    dt = cfg[1]
    if k >= st[1]:
        t_start = st[0] * period
        st[2] = math.ceil((t_start + xi * period) / dt - EPS)
        j = st[0] + 1.0
        nxt = math.ceil(j * period / dt - EPS)
        while nxt <= k:  # a start that falls on this step again (never for period >= 2*dt)
            j += 1.0
            nxt = math.ceil(j * period / dt - EPS)
        st[0] = j
        st[1] = nxt
    return 1 if k < st[2] else 0
