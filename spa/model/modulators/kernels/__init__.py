"""Per-step laws of the pulse modulators, one module per kind, for the closed loop.

Each module defines

* ``INITIAL``: the kernel's state at ``t = 0`` (a tuple of floats);
* ``configure(settings, dt, params=None) -> numpy.ndarray``: its constants, from the
  modulator's complete settings (:func:`spa.model.modulators.check_settings`), the step and
  the valve the loop runs with (a :class:`~spa.model.params.ValveParams`; only LPWM reads
  it: the laws it inverts);
* ``step(k, xi, cfg, state) -> int``: a numba-compiled state machine that returns the valve
  command ``u[k]`` over ``[k*dt, (k+1)*dt)`` for the input fraction ``xi`` at ``t_k`` and
  updates ``state`` in place;
* ``C_STEP``: the same law in C99, ``static int ${p}_mod_step(long long k, double xi, const
  double *cfg, double *st)`` with the same operations in the same order (a
  :class:`string.Template` whose ``${p}`` is a name prefix and ``${eps}`` the event tolerance;
  :mod:`spa.closedloop.export` writes it into a controller's header).

Fed the same input sequence, each kernel gives :func:`spa.model.modulators.modulate`'s
output sample for sample (tests/test_closed_loop.py). Adding a kind is one module here, its
entry in :data:`KERNELS` and its line in :func:`step` (the compiled loop calls that one
function with the kind's code: numba caches a loop that calls a known function on disk, not
one that receives the kernel as an argument).
"""

from __future__ import annotations

from types import ModuleType

import numpy as np
from numba import njit

from spa.model.modulators.kernels import dsm, iipfm, ipfm, lpwm, pwm

__all__ = ["KERNELS", "code", "step"]

#: Modulator kind -> the module holding its per-step law; a kind's code is its position.
KERNELS: dict[str, ModuleType] = {
    "pwm": pwm,
    "ipfm": ipfm,
    "iipfm": iipfm,
    "dsm": dsm,
    "lpwm": lpwm,  # model-inverse PWM (a modulator kind where spa.model.modulators has it)
}


def code(kind: str) -> int:
    """The integer :func:`step` dispatches on for ``kind``."""
    return list(KERNELS).index(kind)


@njit(cache=True, inline="always")
def step(kind: int, k: int, xi: float, cfg: np.ndarray, st: np.ndarray) -> int:  # pragma: no cover
    """Command ``u[k]`` of the kernel number ``kind`` (:func:`code`)."""
    if kind == 0:
        return pwm.step(k, xi, cfg, st)
    if kind == 1:
        return ipfm.step(k, xi, cfg, st)
    if kind == 2:
        return iipfm.step(k, xi, cfg, st)
    if kind == 3:
        return dsm.step(k, xi, cfg, st)
    return lpwm.step(k, xi, cfg, st)
