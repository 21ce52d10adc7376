"""PWM as a per-step state machine (the law of :func:`spa.model.modulators.modulate`).

Periods start at the steps ``ceil(j*period/dt - eps)``; at each start the input fraction is
sampled and the output is high until ``ceil((j*period + xi*period)/dt - eps)`` (never past
the next start, where the next sample overwrites it).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from spa.model.modulators.kernels._common import EPS, c_next_start, next_start

#: State: [period index j of the next start, step of the next start, end of the high part].
INITIAL = (0.0, 0.0, 0.0)


def configure(settings: dict[str, float], dt: float, params: object = None) -> np.ndarray:
    """Constants of the kernel (``params``, the valve, unused): ``[period, dt]``."""
    return np.array([1.0 / settings["f_w"], dt])


@njit(cache=True)
def step(k: int, xi: float, cfg: np.ndarray, st: np.ndarray) -> int:  # pragma: no cover
    """Command ``u[k]`` for the input ``xi`` sampled at step ``k`` (updates ``st``)."""
    period = cfg[0]
    dt = cfg[1]
    if k >= st[1]:
        t_start = st[0] * period
        st[2] = math.ceil((t_start + xi * period) / dt - EPS)
        st[0], st[1] = next_start(st[0], period, dt, k)
    return 1 if k < st[2] else 0


#: :func:`step` in C99 as ``${p}_pwm`` (and ``${p}_mod_step``), the same operations in the
#: same order (:mod:`spa.closedloop.export` fills ``${p}`` and ``${eps}``).
C_PWM = (
    """
static int ${p}_pwm(long long k, double xi, const double *cfg, double *st)
{
    const double period = cfg[0];
    const double dt = cfg[1];
    if ((double)k >= st[1]) {
        const double t_start = st[0] * period;
        double j, nxt;
        st[2] = ceil((t_start + xi * period) / dt - ${eps});
"""
    + c_next_start("j")
    + """\
    }
    return (double)k < st[2] ? 1 : 0;
}
"""
)

#: The kind's per-step law in C99: ``int ${p}_mod_step(k, xi, cfg, st)``.
C_STEP = (
    C_PWM
    + """
static int ${p}_mod_step(long long k, double xi, const double *cfg, double *st)
{
    return ${p}_pwm(k, xi, cfg, st);
}
"""
)
