"""The controller one step at a time, for bench loops written in Python.

:class:`ControllerStepper` holds the state of one PI (:class:`PIController`) and one
modulator setting and applies the law of docs/model.md section 8 at each call of
:meth:`~ControllerStepper.step`: the same operations as
:func:`spa.closedloop.loop.simulate_closed_loop` (the PI in Python, the modulator's compiled
per-step kernel of :mod:`spa.model.modulators.kernels`) and as the exported C header
(:mod:`spa.closedloop.export`); tests/test_export.py checks all three agree.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from spa import _checks as checks
from spa.closedloop.controller import PIController, interp
from spa.model.modulators import Modulator, check_settings
from spa.model.modulators.kernels import KERNELS
from spa.model.params import ValveParams

__all__ = ["ControllerStepper"]


class ControllerStepper:
    """A PI and a pulse modulator, stepped by the caller every ``dt`` seconds.

    Parameters
    ----------
    modulator : Modulator or mapping
        The modulator setting.
    controller : PIController
        Fixed, scheduled or with feed-forward.
    dt : float
        The step the caller keeps, s.
    integral0 : float, optional
        The integrator's initial state (input fraction).
    params : ValveParams, optional
        The valve the controller was designed for (as :func:`spa.closedloop.export.
        controller_header` takes it): LPWM inverts its laws.

    Raises
    ------
    ValueError
        For a bad step or controller, or a setting that does not fit the step.

    Notes
    -----
    The caller's loop, every ``dt`` s: read the pressure ``p`` (bar), call
    ``u, xi = stepper.step(r, p)`` and apply ``u`` to the valve at once, holding it until the
    next step. The law assumes a fixed step: a late step is a different loop.

    Examples
    --------
    >>> s = ControllerStepper({"type": "pwm", "f_w": 20.0}, PIController(2.0, 4.0), 1e-3)
    >>> s.step(0.4, 0.1)
    (1, 0.6000000000000001)
    """

    def __init__(
        self,
        modulator: Modulator | dict[str, Any],
        controller: PIController,
        dt: float,
        integral0: float = 0.0,
        params: ValveParams | None = None,
    ) -> None:
        if not isinstance(controller, PIController):
            raise ValueError(f"controller must be a PIController, got {controller!r}")
        self.dt = checks.positive("dt", dt, "s")
        self.modulator = Modulator.from_mapping(modulator)
        if self.modulator.kind not in KERNELS:
            raise ValueError(f"no per-step law for modulator kind {self.modulator.kind!r}")
        settings = dict(self.modulator.settings)
        check_settings(self.modulator.kind, self.dt, **settings)
        self.controller = controller
        self._kernel = KERNELS[self.modulator.kind]
        self._cfg = self._kernel.configure(settings, self.dt, params)
        self._tables = controller.arrays()
        self.reset(integral0)

    def reset(self, integral0: float = 0.0) -> None:
        """Back to step 0 with the integrator at ``integral0``."""
        self.k = 0
        self.integral = float(integral0)
        self._state = np.array(self._kernel.INITIAL, dtype=np.float64)
        self._r_prev = 0.0
        self._gains = (0.0, 0.0, 0.0)

    def step(self, r: float, p: float) -> tuple[int, float]:
        """One step: set-point ``r`` and measured pressure ``p`` (bar) at ``t_k``.

        Returns
        -------
        valve : int
            The command over ``[t_k, t_k + dt)`` (1: charge, 0: exhaust).
        xi : float
            The PI's output, the modulator's input fraction.
        """
        r, p = float(r), float(p)
        if self.k == 0 or r != self._r_prev:
            grid, kp, ki, ff_r, ff_xi = self._tables
            self._gains = (interp(r, grid, kp), interp(r, grid, ki), interp(r, ff_r, ff_xi))
            self._r_prev = r
        kp, ki, ff = self._gains
        e = r - p
        v = kp * e + self.integral + ff
        xi = min(max(v, 0.0), 1.0)
        if not ((v > 1.0 and e > 0.0) or (v < 0.0 and e < 0.0)):
            self.integral += ki * self.dt * e
        u = int(self._kernel.step(self.k, xi, self._cfg, self._state))
        self.k += 1
        return u, xi
