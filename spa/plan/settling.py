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
from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np
import pandas as pd

if TYPE_CHECKING:  # pragma: no cover
    from spa.closedloop.controller import PIController
    from spa.model.params import ValveParams

__all__ = [
    "BAND",
    "noise_range_quantile",
    "settling_allowance",
    "settling_times",
    "staircase_reference",
]

#: The settling band, a fraction of the step (as :mod:`spa.closedloop.metrics`).
BAND = 0.02


def staircase_reference(
    levels: Sequence[float], hold: float, dt: float
) -> tuple[np.ndarray, np.ndarray, float]:
    """The verification's closed-loop set-point (:func:`spa.plan.verify.closed_loop_runs`):
    one hold at the first level, then the levels up and back down, each ``hold`` s; its
    set-point ``r`` (bar) and times ``t`` (s) at every step ``dt``, and the lead (s) at the
    first level that is not measured.

    Examples
    --------
    >>> r, t, lead = staircase_reference([0.2, 0.4], 0.002, 0.001)
    >>> r.tolist(), lead
    ([0.2, 0.2, 0.2, 0.2, 0.4, 0.4, 0.2, 0.2], 0.002)
    """
    lv = [float(v) for v in levels]
    ticks = max(2, round(float(hold) / dt))
    r = np.repeat([lv[0], *lv, *lv[-2::-1]], ticks)
    return r, np.arange(r.size) * dt, ticks * dt


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


def settling_allowance(
    params: ValveParams,
    setting: Mapping[str, Any],
    controller: PIController,
    levels: Sequence[float],
    hold: float,
    dt: float,
    noise: float,
    quantum: float = 0.0,
    *,
    draws: int = 20,
    seed: int = 0,
) -> float:
    """What the sensor's noise adds to a closed-loop staircase's worst settling time, s.

    The promise's settling time is its design's, on noiseless runs. On the bench the
    controller closes on a noisy reading, so the actuator's own pressure wanders too, and
    the logged one more: the verification's staircase (one hold at the first level, then
    the levels up and back down, :func:`spa.plan.verify.closed_loop_runs`) is simulated on
    ``params`` with the controller reading ``p`` plus the sensor's noise, logged with the
    noise and the ADC's step, and measured as a recording is (:func:`settling_times`). The
    allowance is the 95th percentile, over ``draws`` noise draws, of the worst step's
    settling time less the noiseless run's (0 when the noise does not slow it).

    Parameters
    ----------
    params : ValveParams
        The valve the promise was made on (the estimate).
    setting : mapping
        The controller's modulator setting.
    controller : PIController
        The exported PI.
    levels : sequence of float
        The promise's set-points, bar.
    hold : float
        Seconds at each level.
    dt : float
        The controller's step, s.
    noise : float
        The sensor's noise, bar (standard deviation).
    quantum : float, optional
        The ADC's step, bar (0: none).
    draws : int, optional
        Noise draws.
    seed : int, optional
        Seed of the draws.

    Returns
    -------
    float
        Seconds, >= 0; 0 without noise or when the noiseless run does not settle; ``inf``
        when more than one draw in twenty does not settle.
    """
    from spa.closedloop.experiments import _settled, step_periods
    from spa.closedloop.loop import closed_loop_arrays
    from spa.model.modulators import Modulator

    mod = Modulator.from_mapping(dict(setting))
    lv = [float(v) for v in levels]
    r, t, lead = staircase_reference(lv, hold, dt)
    integral0 = _settled(mod, controller, params, lv[0])
    periods = step_periods(mod, params, lv, dt)

    def worst(reading: np.ndarray | None) -> float:
        p, _, _ = closed_loop_arrays(
            r, dt, mod, controller, params, lv[0], integral0=integral0, sensor_noise=reading
        )
        if reading is not None:
            p = p + reading  # the log is the reading
            if quantum > 0.0:
                p = np.round(p / quantum) * quantum
        run = pd.DataFrame({"t": t, "p": p, "r": r})
        return max(settling_times(run, periods, lv[0], lead), default=0.0)

    clean = worst(None)
    if not (noise > 0.0 and math.isfinite(clean)):
        return 0.0
    rng = np.random.default_rng(seed)
    noisy = [worst(rng.normal(0.0, noise, r.size)) for _ in range(max(int(draws), 1))]
    # an unsettled draw is inf: more than one in twenty, and the noise may keep the loop
    # from settling within 2 % at all (an infinite allowance)
    q = float(np.quantile(np.asarray(noisy), 0.95, method="higher"))
    return max(q - clean, 0.0)


def noise_range_quantile(n: int, q: float = 0.95) -> float:
    """The ``q`` quantile of the range (maximum less minimum) of ``n`` independent standard
    normal samples: what a sensor's Gaussian noise alone adds to a logged peak-to-peak over
    ``n`` samples, in noise standard deviations.

    The range's distribution is ``F(r) = n int phi(x) (Phi(x + r) - Phi(x))^(n - 1) dx``
    (the smallest sample at ``x``, the others within ``r`` above it), integrated on a grid
    and solved for ``F(r) = q``. A fixed multiple does not do: the peak-to-peak of noise
    alone exceeds ``6.6`` standard deviations in 37 % of 1 000-sample windows and 94 % of
    4 000-sample ones (issue 58), so a band of ``ripple + 6.6 noise`` read a kept ripple
    as broken.

    Parameters
    ----------
    n : int
        Samples in the window (at least 2).
    q : float, default 0.95
        The quantile, in (0, 1).

    Returns
    -------
    float
        The quantile, in standard deviations.

    Raises
    ------
    ValueError
        When ``n < 2`` or ``q`` is not in (0, 1).

    Examples
    --------
    Two samples' range is ``sqrt(2) |z|``, whose 95 % quantile is ``sqrt(2) 1.96``:

    >>> round(noise_range_quantile(2), 3), round(math.sqrt(2) * 1.959964, 3)
    (2.772, 2.772)
    >>> noise_range_quantile(1000) > 6.6
    True
    """
    from scipy import optimize, special, stats

    n = int(n)
    if n < 2:
        raise ValueError(f"noise_range_quantile: n must be at least 2 samples, got {n}")
    if not 0.0 < q < 1.0:
        raise ValueError(f"noise_range_quantile: q must lie in (0, 1), got {q}")
    x = np.linspace(-9.0, 9.0, 7201)
    phi = stats.norm.pdf(x)

    def cdf(r: float) -> float:
        inside = np.clip(special.ndtr(x + r) - special.ndtr(x), 1e-300, 1.0)
        return float(n * np.trapezoid(phi * np.exp((n - 1) * np.log(inside)), x))

    return float(optimize.brentq(lambda r: cdf(r) - q, 1e-6, 20.0, xtol=1e-9))
