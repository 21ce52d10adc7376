"""Disturbances a bench has: a drop of the supply pressure, and the sensor's noise.

* **Supply drop** (:func:`supply_drop`): the set-point staircase, with ``k2`` falling by a
  fraction (10 %) in the middle of the hold of the middle rising level and staying there
  (:func:`spa.closedloop.loop.closed_loop_arrays`'s ``k2_change``), against the same run
  without the drop. Measured on the cycle-mean pressure
  (:func:`spa.closedloop.metrics.cycle_mean`), by its deviation from the undisturbed run's
  (so that what the loop was still doing before the drop does not count): the *recovery
  time*, from the drop to the last time the deviation exceeds 2 % of ``r`` before the level
  ends (0 when it never does; NaN when it still does at the end of the level), the *dip*
  (the largest deviation downwards, bar) and the steady-state error over the level's last
  quarter.
* **Sensor noise** (:func:`noise_ripple`): the same staircase with Gaussian noise of standard
  deviation ``sigma`` added to the pressure the controller reads (seeded: deterministic);
  the *added ripple* is the increase of the actuator pressure's RMS and peak-to-peak ripple
  over each level's last quarter, median over the levels of the staircase (bar).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import numpy.typing as npt

from spa import _checks as checks
from spa.closedloop.experiments import LoopUnderTest, Staircase, _settled
from spa.closedloop.loop import closed_loop_arrays
from spa.closedloop.metrics import cycle_mean, ripple, steps

__all__ = ["BAND", "DROP", "disturbances", "noise_ripple", "recovery_time", "supply_drop"]

#: The supply's drop, fraction of ``k2``.
DROP = 0.10

#: The recovery band, fraction of the set-point.
BAND = 0.02


def recovery_time(
    t: npt.ArrayLike, deviation: npt.ArrayLike, tolerance: float, t_drop: float
) -> float:
    """Time from ``t_drop`` to the last sample whose ``|deviation|`` exceeds ``tolerance``, s.

    Parameters
    ----------
    t, deviation : array_like
        Times (s) and the cycle-mean pressure's deviation from the undisturbed run's (bar),
        from the drop to the end of the level.
    tolerance : float
        The band's half-width, bar (:data:`BAND` times the set-point).
    t_drop : float
        When the disturbance struck, s.

    Returns
    -------
    float
        0 when the deviation never leaves the band, NaN when it is outside at the last sample.

    Examples
    --------
    >>> recovery_time([1.0, 1.1, 1.2, 1.3], [0.0, 0.05, 0.005, 0.0], 0.01, 1.0)
    0.10000000000000009
    """
    tt = np.asarray(t, dtype=np.float64)
    outside = np.abs(np.asarray(deviation, dtype=np.float64)) > tolerance
    if not outside.any():
        return 0.0
    if outside[-1]:
        return math.nan
    return float(tt[np.flatnonzero(outside)[-1]] - t_drop)


class _Setup:
    """The staircase, its start (settled at the first level) and cycle-mean window, once."""

    def __init__(self, loop: LoopUnderTest, stairs: Staircase) -> None:
        self.loop = loop
        self.stairs = stairs
        self.r = stairs.reference
        self.t = np.arange(self.r.size) * stairs.dt
        self.i0 = _settled(loop.modulator, loop.controller, loop.params, stairs.levels[0])
        self.period = stairs.periods(loop)

    def run(self, **disturbance: Any) -> tuple[np.ndarray, np.ndarray]:
        """``(p, valve)`` of the staircase, with ``k2_change`` or ``sensor_noise``."""
        loop, stairs = self.loop, self.stairs
        p, _, u = closed_loop_arrays(
            self.r,
            stairs.dt,
            loop.modulator,
            loop.controller,
            loop.params,
            stairs.levels[0],
            integral0=self.i0,
            **disturbance,
        )
        return p, u


def _drop_metrics(setup: _Setup, clean: np.ndarray, drop: float) -> dict[str, float]:
    if not 0.0 < drop < 1.0:
        raise ValueError(f"drop must be a fraction in (0, 1), got {drop}")
    stairs = setup.stairs
    mid = (len(stairs.levels) - 1) // 2
    k_drop = mid * stairs.n_hold + stairs.n_hold // 2
    level = stairs.levels[mid]
    p, _ = setup.run(k2_change=(k_drop, setup.loop.params.k2 * (1.0 - drop)))
    window = max(round(setup.period[level] / stairs.dt), 1)
    stop = (mid + 1) * stairs.n_hold
    deviation = cycle_mean(clean, window)[k_drop:stop] - cycle_mean(p, window)[k_drop:stop]
    tail = p[stop - max((stop - k_drop) // 4, 1) : stop]
    return {
        "drop_level": level,
        "recovery_time": recovery_time(
            setup.t[k_drop:stop], deviation, BAND * level, k_drop * stairs.dt
        ),
        "dip": float(max(deviation.max(), 0.0)),
        "steady_state_error": float(level - tail.mean()),
    }


def _ripple(setup: _Setup, p: np.ndarray) -> np.ndarray:
    """``(rms, pp)`` ripple over each level's last quarter."""
    return np.array(
        [ripple(p, a, b)[::-1] for a, b in steps(setup.r) if b - a >= 4], dtype=np.float64
    )


def _noise_metrics(
    setup: _Setup, clean: tuple[np.ndarray, np.ndarray], sigma: float, seed: int
) -> dict[str, float]:
    sigma = checks.nonnegative("sigma", sigma, "bar")
    noise = np.random.default_rng(seed).normal(0.0, sigma, setup.r.size)
    noisy = setup.run(sensor_noise=noise) if sigma > 0 else clean
    added = np.median(_ripple(setup, noisy[0]) - _ripple(setup, clean[0]), axis=0)
    return {"noise": sigma, "added_ripple_rms": float(added[0]), "added_ripple_pp": float(added[1])}


def supply_drop(loop: LoopUnderTest, stairs: Staircase, drop: float = DROP) -> dict[str, float]:
    """The staircase with the supply pressure dropping by ``drop`` mid-way.

    Parameters
    ----------
    loop : LoopUnderTest
        The loop, started settled at the first level (as
        :func:`spa.closedloop.experiments.run_staircase`).
    stairs : Staircase
        The staircase.
    drop : float, optional
        Fraction of ``k2`` lost, in (0, 1).

    Returns
    -------
    dict
        ``drop_level`` (the set-point during the drop, bar), ``recovery_time`` (s),
        ``dip`` (bar) and ``steady_state_error`` after the drop (bar), as the module says;
        the cycle-mean window is the modulator's period at the level of the drop.
    """
    setup = _Setup(loop, stairs)
    return _drop_metrics(setup, setup.run()[0], drop)


def noise_ripple(
    loop: LoopUnderTest, stairs: Staircase, sigma: float, seed: int = 0
) -> dict[str, float]:
    """Ripple the sensor's noise adds to the actuator pressure over the staircase.

    Parameters
    ----------
    loop, stairs
        As :func:`supply_drop`.
    sigma : float
        The noise's standard deviation, bar (>= 0).
    seed : int, optional
        Seed of the noise (numpy's default generator).

    Returns
    -------
    dict
        ``noise`` (sigma), ``added_ripple_rms`` and ``added_ripple_pp``: the median over the
        levels of the noisy run's ripple minus the noise-free run's (bar).

    Examples
    --------
    >>> from spa.closedloop.design import design_pi
    >>> from spa.model.modulators import Modulator
    >>> from spa.model.params import ValveParams
    >>> mod = Modulator.from_mapping({"type": "pwm", "f_w": 20.0})
    >>> loop = LoopUnderTest(mod, design_pi(mod, levels=[0.2, 0.4])["fixed"], ValveParams())
    >>> noise_ripple(loop, Staircase([0.2, 0.4], 1.0, 1e-3), 0.0)["added_ripple_rms"]
    0.0
    """
    setup = _Setup(loop, stairs)
    return _noise_metrics(setup, setup.run(), sigma, seed)


def disturbances(
    loop: LoopUnderTest, stairs: Staircase, sigma: float, *, seed: int = 0, drop: float = DROP
) -> dict[str, float]:
    """:func:`supply_drop` and :func:`noise_ripple` together, sharing the undisturbed run.

    Parameters
    ----------
    loop, stairs, drop
        As :func:`supply_drop`.
    sigma, seed
        As :func:`noise_ripple`.

    Returns
    -------
    dict
        Both functions' keys; the same values as calling each.
    """
    setup = _Setup(loop, stairs)
    clean = setup.run()
    return {**_drop_metrics(setup, clean[0], drop), **_noise_metrics(setup, clean, sigma, seed)}
