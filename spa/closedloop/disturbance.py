"""Disturbances a bench has: a drop of the supply pressure, and the sensor's noise.

* **Supply drop** (:func:`supply_drop`): the set-point staircase, with ``k2`` falling by a
  fraction (10 %) in the middle of the hold of the middle rising level and staying there
  (:func:`spa.closedloop.loop.closed_loop_arrays`'s ``k2_change``). Measured on the
  cycle-mean pressure (:func:`spa.closedloop.metrics.cycle_mean`): the *recovery time*, from
  the drop to the last time the cycle-mean lies outside ``r ± 2 % r`` before the level ends
  (0 when it never leaves; NaN when it is still outside at the end of the level), the *dip*
  (largest shortfall below ``r`` after the drop, bar) and the steady-state error over the
  level's last quarter.
* **Sensor noise** (:func:`noise_ripple`): the same staircase with Gaussian noise of standard
  deviation ``sigma`` added to the pressure the controller reads (seeded: deterministic);
  the *added ripple* is the increase of the actuator pressure's RMS and peak-to-peak ripple
  over each step's last quarter, median over the steps (bar).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
import numpy.typing as npt

from spa import _checks as checks
from spa.closedloop.controller import PIController
from spa.closedloop.experiments import _settled, cycle_period, staircase_reference
from spa.closedloop.loop import closed_loop_arrays
from spa.closedloop.metrics import cycle_mean, step_rows
from spa.model.modulators import Modulator
from spa.model.params import ValveParams

__all__ = ["BAND", "DROP", "noise_ripple", "recovery_time", "supply_drop"]

#: The supply's drop, fraction of ``k2``.
DROP = 0.10

#: The recovery band, fraction of the set-point.
BAND = 0.02


def recovery_time(
    t: npt.ArrayLike, p_mean: npt.ArrayLike, r: float, t_drop: float, band: float = BAND
) -> float:
    """Time from ``t_drop`` to the last sample outside ``r ± band*r``, s.

    Parameters
    ----------
    t, p_mean : array_like
        Times (s) and cycle-mean pressure (bar) from the drop to the end of the level.
    r : float
        The set-point, bar.
    t_drop : float
        When the disturbance struck, s.
    band : float, optional
        Half-width of the band, fraction of ``r``.

    Returns
    -------
    float
        0 when the pressure never leaves the band, NaN when it is outside at the last sample.

    Examples
    --------
    >>> recovery_time([1.0, 1.1, 1.2, 1.3], [0.5, 0.45, 0.495, 0.5], 0.5, 1.0)
    0.10000000000000009
    """
    tt = np.asarray(t, dtype=np.float64)
    pm = np.asarray(p_mean, dtype=np.float64)
    outside = np.abs(pm - r) > band * abs(r)
    if not outside.any():
        return 0.0
    if outside[-1]:
        return math.nan
    return float(tt[np.flatnonzero(outside)[-1]] - t_drop)


def supply_drop(
    modulator: Modulator,
    controller: PIController,
    params: ValveParams,
    levels: Sequence[float],
    hold: float,
    dt: float,
    drop: float = DROP,
) -> dict[str, float]:
    """The staircase with the supply pressure dropping by ``drop`` mid-way.

    Parameters
    ----------
    modulator, controller, params, levels, hold, dt
        As :func:`spa.closedloop.experiments.run_staircase` (started settled at the first
        level).
    drop : float, optional
        Fraction of ``k2`` lost, in (0, 1).

    Returns
    -------
    dict
        ``drop_level`` (the set-point during the drop, bar), ``recovery_time`` (s),
        ``dip`` (bar) and ``steady_state_error`` after the drop (bar), as the module says.
    """
    if not 0.0 < drop < 1.0:
        raise ValueError(f"drop must be a fraction in (0, 1), got {drop}")
    r = staircase_reference(levels, hold, dt)
    n_hold = round(hold / dt)
    mid = (len(levels) - 1) // 2
    k_drop = mid * n_hold + n_hold // 2
    level = float(levels[mid])
    p, _, _ = closed_loop_arrays(
        r,
        dt,
        modulator,
        controller,
        params,
        float(levels[0]),
        integral0=_settled(modulator, controller, params, float(levels[0])),
        k2_change=(k_drop, params.k2 * (1.0 - drop)),
    )
    period = cycle_period(modulator, params, float(np.median(levels)), dt)
    pm = cycle_mean(p, max(round(period / dt), 1))
    stop = (mid + 1) * n_hold
    t = np.arange(k_drop, stop) * dt
    after = pm[k_drop:stop]
    tail = p[stop - max((stop - k_drop) // 4, 1) : stop]
    return {
        "drop_level": level,
        "recovery_time": recovery_time(t, after, level, k_drop * dt),
        "dip": float(max(level - after.min(), 0.0)),
        "steady_state_error": float(level - tail.mean()),
    }


def noise_ripple(
    modulator: Modulator,
    controller: PIController,
    params: ValveParams,
    levels: Sequence[float],
    hold: float,
    dt: float,
    sigma: float,
    seed: int = 0,
) -> dict[str, float]:
    """Ripple the sensor's noise adds to the actuator pressure over the staircase.

    Parameters
    ----------
    modulator, controller, params, levels, hold, dt
        As :func:`supply_drop`.
    sigma : float
        The noise's standard deviation, bar (>= 0).
    seed : int, optional
        Seed of the noise (numpy's default generator).

    Returns
    -------
    dict
        ``noise`` (sigma), ``added_ripple_rms`` and ``added_ripple_pp``: the median over the
        steps of the noisy run's ripple minus the noise-free run's (bar).

    Examples
    --------
    >>> from spa.closedloop.design import design_pi
    >>> mod = Modulator.from_mapping({"type": "pwm", "f_w": 20.0})
    >>> c = design_pi(mod, levels=[0.2, 0.4])["fixed"]
    >>> noise_ripple(mod, c, ValveParams(), [0.2, 0.4], 1.0, 1e-3, 0.0)["added_ripple_rms"]
    0.0
    """
    sigma = checks.nonnegative("sigma", sigma, "bar")
    r = staircase_reference(levels, hold, dt)
    t = np.arange(r.size) * dt
    period = cycle_period(modulator, params, float(np.median(levels)), dt)
    noise = np.random.default_rng(seed).normal(0.0, sigma, r.size) if sigma > 0 else None
    ripple = []
    for extra in (None, noise):
        p, _, u = closed_loop_arrays(
            r,
            dt,
            modulator,
            controller,
            params,
            float(levels[0]),
            integral0=_settled(modulator, controller, params, float(levels[0])),
            sensor_noise=extra,
        )
        rows = step_rows(t, r, p, u, period, r_initial=float(levels[0]))
        ripple.append(
            np.array([[row["ripple_rms"], row["ripple_pp"]] for row in rows], dtype=np.float64)
        )
    added = np.median(ripple[1] - ripple[0], axis=0)
    return {
        "noise": sigma,
        "added_ripple_rms": float(added[0]),
        "added_ripple_pp": float(added[1]),
    }
