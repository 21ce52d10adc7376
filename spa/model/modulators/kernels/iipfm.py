"""Inverse IPFM as a per-step state machine: integrate ``1 - xi``, fire LOW pulses of ``t_l``.

The same integrate-and-fire law as IPFM on ``1 - xi``, with the output inverted (high by
default), as :func:`spa.model.modulators.modulate` does.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from spa.model.modulators.kernels._common import (
    C_INTEGRATE_AND_FIRE,
    fire_config,
    integrate_and_fire,
)

#: State: [integral of 1 - xi up to t_k in steps, next threshold index, end of the pulse].
INITIAL = (0.0, 1.0, 0.0)


def configure(settings: dict[str, float], dt: float) -> np.ndarray:
    """Constants of the kernel: ``[threshold in steps, pulse width in steps]``."""
    return fire_config(settings["gain"], settings["t_l"], dt)


@njit(cache=True)
def step(k: int, xi: float, cfg: np.ndarray, st: np.ndarray) -> int:  # pragma: no cover
    """Command ``u[k]``; ``1 - xi`` (sampled at step ``k``) enters the integral after it."""
    return 1 - integrate_and_fire(k, 1.0 - xi, cfg[0], cfg[1], st)


#: :func:`step` in C99: ``int ${p}_mod_step(k, xi, cfg, st)`` (see :mod:`.pwm`).
C_STEP = (
    C_INTEGRATE_AND_FIRE
    + """
static int ${p}_mod_step(long long k, double xi, const double *cfg, double *st)
{
    return 1 - ${p}_fire(k, 1.0 - xi, cfg[0], cfg[1], st);
}
"""
)
