"""A recorded closed-loop staircase's settling time, measured so that the sensor does not
decide it (:func:`spa.plan.verify.compare_promise`).

spa measures its promise's settling time on the model's staircase (no noise): the last time
the cycle-mean pressure lies outside 2 % of the step (:mod:`spa.closedloop.metrics`). On a
bench log two things the model's run does not have move that time:

* **the next step.** The cycle-mean is centred, so over the last half window of a step it
  averages samples of the next one, whose pressure already moves: a step that had settled
  reads unsettled at its very end (phys-choked, same plant: the cycle-mean's last sample of
  the 0.8 -> 1.6 bar step 28 mbar off, its 2 % band 16 mbar).
* **the sensor.** Noise and the ADC's step leave the cycle-mean fluctuating by a few mbar
  (phys-choked: 4-7 mbar standard deviation over a level's last quarter, 12 mbar ADC
  steps), against a 2 % band of 16 mbar: one excursion at the end of a settled level moves
  the measured time by seconds.

:func:`settling_times` therefore measures each step on its own samples (the cycle-mean's
window shrinks at the step's ends) and counts a sample outside only when it lies beyond the
2 % band widened by ``1.96`` times the cycle-mean's standard deviation about its straight
line over the step's last quarter (what the sensor adds, as the levels' bands add ``1.96``
noise on a mean; the line takes out a response still creeping towards its level).
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np
import pandas as pd

__all__ = ["BAND", "settling_times"]

#: The settling band, a fraction of the step (as :mod:`spa.closedloop.metrics`).
BAND = 0.02


def _fluctuation(y: np.ndarray) -> float:
    """The standard deviation of ``y`` about its least-squares line (a response still
    creeping towards its level is drift, not what the sensor adds)."""
    if y.size < 3:
        return 0.0
    x = np.arange(y.size, dtype=np.float64)
    coef = np.polyfit(x, y, 1)
    return float(np.std(y - np.polyval(coef, x)))


def settling_times(
    run: pd.DataFrame, periods: Mapping[float, float], r_initial: float, skip: float = 0.0
) -> list[float]:
    """Each step's settling time (s; ``inf`` when outside its band at the step's end).

    Parameters
    ----------
    run : pandas.DataFrame
        ``t`` (s, uniform), ``p`` (bar) and the set-point ``r`` (bar).
    periods : mapping
        ``set-point -> window`` of the cycle-mean, s
        (:func:`spa.closedloop.experiments.step_periods`).
    r_initial : float
        The pressure before the first measured step, bar.
    skip : float, default 0
        Seconds left out at the start (the lead the staircase starts settled in).

    Returns
    -------
    list of float
        One per step with a set-point change, in order.

    Raises
    ------
    ValueError
        When the run lacks ``t``, ``p`` or ``r``.

    Examples
    --------
    >>> t = np.arange(4000) * 0.001
    >>> r = np.where(t < 2.0, 0.5, 1.0)
    >>> p = np.where(t < 2.0, 0.5, 1.0 - 0.5 * np.exp(-(t - 2.0) / 0.2))
    >>> [round(s, 2) for s in settling_times(pd.DataFrame({"t": t, "p": p, "r": r}), {}, 0.5, 1.0)]
    [0.78]
    """
    from spa.closedloop.metrics import cycle_mean, steps

    missing = sorted({"t", "p", "r"} - set(run.columns))
    if missing:
        raise ValueError(f"closed-loop run has no column(s) {missing}; expected t, p and r")
    t = run["t"].to_numpy(np.float64)
    keep = t >= t[0] + skip - 1e-12
    t, p, r = t[keep], run["p"].to_numpy(np.float64)[keep], run["r"].to_numpy(np.float64)[keep]
    if t.size < 2:
        return []
    dt = float(np.median(np.diff(t)))
    longest = max(periods.values(), default=dt)
    out = []
    prev = float(r_initial)
    for a, b in steps(r):
        r1 = float(r[a])
        r0, prev = prev, r1
        delta = r1 - r0
        if delta == 0.0 or b - a < 4:
            continue
        window = max(round(float(periods.get(r1, longest)) / dt), 1)
        pm = cycle_mean(p[a:b], window)  # this step's samples alone
        y = (pm - r0) / delta  # 0 -> 1 whatever the direction
        band = BAND + 1.96 * _fluctuation(y[3 * y.size // 4 :])
        outside = np.flatnonzero(np.abs(y - 1.0) > band)
        if outside.size == 0:
            out.append(0.0)
        elif outside[-1] == y.size - 1:
            out.append(math.inf)
        else:
            out.append(float((outside[-1] + 1) * dt))
    return out
