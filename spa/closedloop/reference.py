"""A plain-Python closed loop built from the open-loop functions, for the tests.

At every step it calls :func:`spa.model.modulators.modulate` on the whole input history and
:func:`spa.model.plant.simulate` on the whole command history, so it shares no code with the
compiled loop beyond those two functions: it is quadratic in the number of samples and meant
for a few thousand samples. It follows the convention of docs/model.md section 8.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from spa.closedloop.controller import PIController
from spa.model.modulators import Modulator
from spa.model.params import ValveParams
from spa.model.plant import simulate

__all__ = ["closed_loop_reference"]


def closed_loop_reference(
    reference: npt.ArrayLike,
    dt: float,
    modulator: Modulator,
    controller: PIController,
    params: ValveParams,
    p0: float = 0.0,
    integral0: float = 0.0,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(p, xi, valve)`` of the closed loop, one Python step per sample.

    ``p[k]`` is the pressure the commands ``u[0..k-1]`` leave at ``t_k`` (the open-loop
    simulation of that history with the last command held through ``t_k``); ``xi[k]`` the PI
    law on ``r[k] - p[k]``; ``u[k]`` the modulator's command for the inputs ``xi[0..k]``.
    """
    r = np.asarray(reference, dtype=np.float64)
    n = r.size
    p, xi, u = np.zeros(n), np.zeros(n), np.zeros(n, dtype=np.int8)
    integ = float(integral0)
    for k in range(n):
        p[k] = p0 if k == 0 else simulate(np.append(u[:k], u[k - 1]), dt, params, p0)[k]
        kp, ki, ff = controller.gains(float(r[k]))
        e = r[k] - p[k]
        v = kp * e + integ + ff
        xi[k] = min(max(v, 0.0), 1.0)
        if not ((v > 1.0 and e > 0.0) or (v < 0.0 and e < 0.0)):
            integ += ki * dt * e
        u[k] = modulator.modulate(xi[: k + 1], dt)[k]
    return p, xi, u
