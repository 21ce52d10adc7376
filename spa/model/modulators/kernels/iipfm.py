"""Inverse IPFM as a per-step state machine: integrate ``1 - xi``, fire LOW pulses of ``t_l``.

The same integrate-and-fire law as IPFM on ``1 - xi``, with the output inverted (high by
default), as :func:`spa.model.modulators.modulate` does.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from spa.model.modulators.kernels import ipfm
from spa.model.modulators.kernels._common import C_INTEGRATE_AND_FIRE, fire_config

#: State: IPFM's, of ``1 - xi``: [integral of 1 - xi up to t_k in steps, next threshold
#: index, end of the pulse].
INITIAL = ipfm.INITIAL

_ipfm_step = ipfm.step


def configure(settings: dict[str, float], dt: float, params: object = None) -> np.ndarray:
    """Constants of the kernel: ``[threshold in steps, pulse width in steps]`` for
    ``t_l`` (``params``, the valve, unused)."""
    return fire_config(settings["gain"], settings["t_l"], dt)


@njit(cache=True)
def step(k: int, xi: float, cfg: np.ndarray, st: np.ndarray) -> int:  # pragma: no cover
    """Command ``u[k]``: IPFM's step on ``1 - xi`` (sampled at step ``k``), inverted."""
    return 1 - _ipfm_step(k, 1.0 - xi, cfg, st)


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
