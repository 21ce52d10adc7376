"""Closed-loop metrics: step responses over a set-point sequence, and sine tracking.

Definitions (docs/model.md section 8). Step metrics are computed per step of the set-point,
on the *cycle-mean* pressure (a centred moving mean over one modulator period, so that the
chattering neither hides nor fakes settling) except the ripple, IAE and ITAE, which use the
pressure itself:

* rise time: from the first crossing of ``r0 + 0.1*(r1 - r0)`` to the first crossing of
  ``r0 + 0.9*(r1 - r0)``, s (NaN when never reached);
* overshoot: largest excursion of the cycle-mean beyond ``r1`` in the direction of the
  step, less the excursion it still makes over the last quarter of the step (the band its
  limit cycle keeps, where the one-period mean does not remove a modulator's slower idle
  tones: that ripple is the ripple's, not the transient's), in % of ``|r1 - r0|`` (0 when
  none);
* settling time (2 %): from the step to the last time the cycle-mean lies outside
  ``r1 ± 0.02*|r1 - r0|``, s (NaN when it is still outside at the end of the step);
* steady-state error: ``r1`` minus the mean pressure over the last quarter of the step, bar;
* ripple: peak-to-peak and RMS of the pressure about its mean over the last quarter, bar;
* IAE and ITAE: ``sum |e|*dt`` and ``sum (t - t0)*|e|*dt`` over the step;
* switching rate: valve command edges per second over the step.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np
import numpy.typing as npt
import pandas as pd

from spa import _checks as checks

__all__ = [
    "STEP_METRICS",
    "cycle_mean",
    "ripple",
    "sine_metrics",
    "step_metrics",
    "step_rows",
    "steps",
]

#: The step metrics, in the order of the tables.
STEP_METRICS = (
    "rise_time",
    "overshoot",
    "settling_time",
    "steady_state_error",
    "ripple_pp",
    "ripple_rms",
    "iae",
    "itae",
    "switching_rate",
)


def cycle_mean(p: npt.ArrayLike, window: int) -> np.ndarray:
    """Centred moving mean of ``p`` over ``window`` samples (shrinking at the ends).

    Examples
    --------
    >>> cycle_mean([0.0, 1.0, 0.0, 1.0, 0.0, 1.0], 2).tolist()
    [0.5, 0.5, 0.5, 0.5, 0.5, 0.5]
    """
    x = np.asarray(p, dtype=np.float64)
    w = max(int(window), 1)
    c = np.concatenate(([0.0], np.cumsum(x)))
    idx = np.arange(x.size)
    lo = np.clip(idx - w // 2, 0, x.size)
    hi = np.clip(lo + w, 0, x.size)
    lo = np.maximum(hi - w, 0)
    return (c[hi] - c[lo]) / (hi - lo)


def steps(r: npt.ArrayLike) -> list[tuple[int, int]]:
    """``(start, stop)`` sample ranges of constant set-point (each change starts a step)."""
    x = np.asarray(r, dtype=np.float64)
    if x.size == 0:
        return []
    starts = np.concatenate(([0], np.flatnonzero(x[1:] != x[:-1]) + 1))
    stops = np.append(starts[1:], x.size)
    return list(zip(starts.tolist(), stops.tolist(), strict=True))


def _first(mask: np.ndarray) -> int:
    hit = np.flatnonzero(mask)
    return int(hit[0]) if hit.size else -1


def step_metrics(
    run: pd.DataFrame, period: float | Mapping[float, float], *, r_initial: float | None = None
) -> pd.DataFrame:
    """The step metrics of every change of set-point in a closed-loop run.

    Parameters
    ----------
    run : pandas.DataFrame
        Columns ``t``, ``r``, ``p`` and ``valve``, uniformly sampled (a
        :func:`spa.closedloop.loop.simulate_closed_loop` table, or a bench recording).
    period : float or mapping
        Window of the cycle-mean, s: the modulator's pulse period (a few samples at least);
        or ``set-point -> window``, each step measured with the window of the level it goes
        to (a modulator whose period changes with the level:
        :func:`spa.closedloop.experiments.step_periods`; a level missing from it gets the
        longest window).
    r_initial : float, optional
        The level before the first step; the pressure at ``t = 0`` by default. The first
        segment counts as a step only if it differs from this level.

    Returns
    -------
    pandas.DataFrame
        One row per step: ``r0``, ``r1`` (bar), ``t0`` (s) and :data:`STEP_METRICS`.

    Raises
    ------
    ValueError
        If a column is missing or the run has fewer than two samples.

    Examples
    --------
    >>> t = np.arange(2000) * 1e-3
    >>> r = np.where(t < 1.0, 0.0, 1.0)
    >>> p = np.where(t < 1.0, 0.0, 1.0 - np.exp(-(t - 1.0) / 0.1))
    >>> run = pd.DataFrame({"t": t, "r": r, "p": p, "valve": 0})
    >>> m = step_metrics(run, 0.001).iloc[-1]
    >>> round(float(m.rise_time), 2)  # ln(9)*tau
    0.22
    """
    for col in ("t", "r", "p", "valve"):
        if col not in run:
            raise ValueError(f"closed-loop run has no column {col!r}")
    t = run["t"].to_numpy(np.float64)
    if t.size < 2:
        raise ValueError("closed-loop run needs at least two samples")
    rows = step_rows(
        t,
        run["r"].to_numpy(np.float64),
        run["p"].to_numpy(np.float64),
        run["valve"].to_numpy(),
        period,
        r_initial=r_initial,
    )
    return pd.DataFrame(rows, columns=["r0", "r1", "t0", *STEP_METRICS])


def sine_metrics(run: pd.DataFrame, frequency: float, skip: float = 0.0) -> dict[str, float]:
    """Tracking of a sine set-point: RMS error, gain and phase at the sine's frequency.

    Parameters
    ----------
    run : pandas.DataFrame
        Columns ``t``, ``r``, ``p``.
    frequency : float
        The set-point's frequency, Hz.
    skip : float, optional
        Initial transient left out, s.

    Returns
    -------
    dict
        ``rms_error`` (bar), ``gain`` (amplitude of ``p`` over that of ``r`` at the
        frequency, by least squares on sine and cosine) and ``phase`` (deg, of ``p`` relative
        to ``r``; negative = lag).

    Examples
    --------
    >>> t = np.arange(5000) * 1e-3
    >>> run = pd.DataFrame({"t": t, "r": 0.4 + 0.1 * np.sin(2 * np.pi * t),
    ...                     "p": 0.4 + 0.05 * np.sin(2 * np.pi * t - np.pi / 4)})
    >>> m = sine_metrics(run, 1.0)
    >>> round(m["gain"], 3), round(m["phase"], 1)
    (0.5, -45.0)
    """
    f = checks.positive("frequency", frequency, "Hz")
    t = run["t"].to_numpy(np.float64)
    keep = t >= t[0] + skip
    t, r, p = t[keep], run["r"].to_numpy(np.float64)[keep], run["p"].to_numpy(np.float64)[keep]
    basis = np.column_stack([np.sin(2 * np.pi * f * t), np.cos(2 * np.pi * f * t), np.ones_like(t)])
    cr = np.linalg.lstsq(basis, r, rcond=None)[0]
    cp = np.linalg.lstsq(basis, p, rcond=None)[0]
    zr, zp = complex(cr[0], cr[1]), complex(cp[0], cp[1])
    phase = math.degrees(math.atan2((zp / zr).imag, (zp / zr).real)) if abs(zr) > 0 else math.nan
    # sin(wt + phi) = sin(wt)cos(phi) + cos(wt)sin(phi): the pair (a, b) is e^{i phi} * amp.
    return {
        "rms_error": float(np.sqrt(np.mean((r - p) ** 2))),
        "gain": abs(zp) / abs(zr) if abs(zr) > 0 else math.nan,
        "phase": phase,
    }


def ripple(p: np.ndarray, start: int, stop: int) -> tuple[float, float]:
    """Peak-to-peak and RMS ripple of ``p`` over the last quarter of ``[start, stop)``, bar.

    Examples
    --------
    >>> ripple(np.array([0.0, 0.0, 0.0, 1.0, 0.0, 1.0, 0.0, 1.0]), 0, 8)
    (1.0, 0.5)
    """
    tail = p[start + 3 * (stop - start) // 4 : stop]
    return float(tail.max() - tail.min()), float(np.sqrt(np.mean((tail - tail.mean()) ** 2)))


def step_rows(
    t: np.ndarray,
    r: np.ndarray,
    p: np.ndarray,
    u: np.ndarray,
    period: float | Mapping[float, float],
    *,
    r_initial: float | None = None,
) -> list[dict[str, float]]:
    """:func:`step_metrics` on arrays (``t`` uniformly sampled), one dict per step."""
    dt = float(np.median(np.diff(t)))
    if isinstance(period, Mapping):
        windows = {float(k): checks.positive("period", v, "s") for k, v in period.items()}
        if not windows:
            raise ValueError("period: an empty mapping of set-point -> window")
        longest = max(windows.values())
    else:
        windows, longest = {}, checks.positive("period", period, "s")
    means: dict[int, np.ndarray] = {}

    def smoothed(level: float) -> np.ndarray:
        n = max(round(windows.get(level, longest) / dt), 1)
        if n not in means:
            means[n] = cycle_mean(p, n)
        return means[n]

    edges = np.concatenate(([0], np.abs(np.diff(u.astype(np.int16)))))
    prev = float(p[0]) if r_initial is None else float(r_initial)
    rows = []
    for a, b in steps(r):
        r1 = float(r[a])
        r0, prev = prev, r1
        delta = r1 - r0
        if delta == 0.0 or b - a < 4:
            continue
        sgn = math.copysign(1.0, delta)
        pm = smoothed(r1)
        y = (pm[a:b] - r0) * sgn / abs(delta)  # 0 -> 1 whatever the direction
        i10, i90 = _first(y >= 0.1), _first(y >= 0.9)
        rise = (i90 - i10) * dt if i10 >= 0 and i90 >= 0 else math.nan
        band = max(float(np.max(y[3 * y.size // 4 :])), 1.0)
        over = max(float(np.max(y)) - band, 0.0) * 100.0
        out = np.flatnonzero(np.abs(y - 1.0) > 0.02)
        if out.size == 0:
            settle = 0.0
        elif out[-1] == b - a - 1:
            settle = math.nan
        else:
            settle = (out[-1] + 1) * dt
        tail = p[a + 3 * (b - a) // 4 : b]
        pp, rms = ripple(p, a, b)
        e = r1 - p[a:b]
        tt = t[a:b] - t[a]
        rows.append(
            {
                "r0": r0,
                "r1": r1,
                "t0": float(t[a]),
                "rise_time": rise,
                "overshoot": over,
                "settling_time": settle,
                "steady_state_error": float(r1 - tail.mean()),
                "ripple_pp": pp,
                "ripple_rms": rms,
                "iae": float(np.sum(np.abs(e)) * dt),
                "itae": float(np.sum(tt * np.abs(e)) * dt),
                "switching_rate": float(edges[a + 1 : b].sum() / ((b - a) * dt)),
            }
        )
    return rows
