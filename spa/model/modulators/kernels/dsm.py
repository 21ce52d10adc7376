"""First-order ΔΣ as a per-step state machine.

At each clock tick (the steps ``ceil(m*period/dt - eps)``) the running sum ``S`` of the
sampled inputs grows by ``xi``; the number of ones so far is ``floor(S + 1/2 + eps)`` and the
output over the tick's period is its increment (the closed form of
:func:`spa.model.modulators.modulate`, equal to ``v_k = v_{k-1} + xi_k - u_{k-1}``,
``u_k = [v_k >= 1/2]``).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from spa.model.modulators.kernels._common import EPS, c_next_start, next_start

#: State: [index m of the next tick, step of the next tick, S, ones so far, output].
INITIAL = (0.0, 0.0, 0.0, 0.0, 0.0)


def configure(settings: dict[str, float], dt: float, params: object = None) -> np.ndarray:
    """Constants of the kernel (``params``, the valve, unused): ``[period, dt]``."""
    return np.array([settings["period"], dt])


@njit(cache=True)
def step(k: int, xi: float, cfg: np.ndarray, st: np.ndarray) -> int:  # pragma: no cover
    """Command ``u[k]``; ``xi`` is sampled only at the ticks."""
    period = cfg[0]
    dt = cfg[1]
    if k >= st[1]:
        st[2] += xi
        ones = math.floor(st[2] + 0.5 + EPS)
        st[4] = ones - st[3]
        st[3] = ones
        # ticks closer than one step share it (np.unique in the closed form)
        st[0], st[1] = next_start(st[0], period, dt, k)
    return int(st[4])


#: :func:`step` in C99: ``int ${p}_mod_step(k, xi, cfg, st)`` (see :mod:`.pwm`).
C_STEP = (
    """
static int ${p}_mod_step(long long k, double xi, const double *cfg, double *st)
{
    const double period = cfg[0];
    const double dt = cfg[1];
    if ((double)k >= st[1]) {
        double ones, m, nxt;
        st[2] += xi;
        ones = floor(st[2] + 0.5 + ${eps});
        st[4] = ones - st[3];
        st[3] = ones;
"""
    + c_next_start("m")
    + """\
    }
    return (int)st[4];
}
"""
)
