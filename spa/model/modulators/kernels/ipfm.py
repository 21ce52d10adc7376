"""IPFM as a per-step state machine: integrate ``xi``, fire high pulses of width ``t_h``.

The integral up to ``t_k`` (the running sum of ``xi`` in steps) is compared with the
multiples of the threshold ``gain*t_h/dt``; each crossing starts (or extends) a high pulse of
``round(t_h/dt)`` steps, as :func:`spa.model.modulators.modulate` does with cumulative sums.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from spa.model.modulators.kernels._common import (
    C_INTEGRATE_AND_FIRE,
    fire_config,
    integrate_and_fire,
)

#: State: [integral up to t_k in steps, next threshold index, end of the pulse].
INITIAL = (0.0, 1.0, 0.0)


def configure(settings: dict[str, float], dt: float, params: object = None) -> np.ndarray:
    """Constants of the kernel: ``[threshold in steps, pulse width in steps]``
    (``params``, the valve, unused)."""
    return fire_config(settings["gain"], settings["t_h"], dt)


@njit(cache=True)
def step(k: int, xi: float, cfg: np.ndarray, st: np.ndarray) -> int:  # pragma: no cover
    """Command ``u[k]``; ``xi`` (sampled at step ``k``) enters the integral after it."""
    return integrate_and_fire(k, xi, cfg[0], cfg[1], st)


#: :func:`step` in C99: ``int ${p}_mod_step(k, xi, cfg, st)`` (see :mod:`.pwm`).
C_STEP = (
    C_INTEGRATE_AND_FIRE
    + """
static int ${p}_mod_step(long long k, double xi, const double *cfg, double *st)
{
    return ${p}_fire(k, xi, cfg[0], cfg[1], st);
}
"""
)
