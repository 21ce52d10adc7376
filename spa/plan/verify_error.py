"""The identified model's error on the dataset's own recordings, measured as a verification
measures its runs, to widen the verification's bands (:mod:`spa.plan.verify`).

A verification band holds what the identification's 95 % box moves a prediction by, and
the sensor noise on the measurement. Neither holds the model's own error: the valve spa
identified is a single-state fit of a physical plant, whose held-out FIT is some 95-98 %,
not 100. That error is measured here, on the identification's own modulated runs, each
replayed by the identified valve from its recorded valve command
(:func:`spa.closedloop.model_error.level_errors`): for every staircase, each level's mean
over its second half (as :func:`spa.plan.verify.level_means`) and the levels' FIT (as
:func:`spa.plan.verify.compare`); for every sine, its mean and the amplitude of its
fundamental over the second half (:func:`spa.plan.verify.sine_fit`). The largest error of
each kind is the model-error term of the bands of that kind.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np
import pandas as pd

from spa.model.params import ValveParams

__all__ = ["ERROR_KEYS", "no_model_error", "recorded_model_error", "sine_omega"]

#: The model-error terms: each band's kind, and its unit.
ERROR_KEYS = {
    "level_bar": "bar",
    "fit_points": "points",
    "sine_mean_bar": "bar",
    "sine_amplitude_bar": "bar",
}


def no_model_error(why: str) -> dict[str, Any]:
    """Every term 0, with ``measured_on`` saying why none was measured."""
    return {**dict.fromkeys(ERROR_KEYS, 0.0), "measured_on": f"not measured: {why}"}


def sine_omega(t: np.ndarray, u: np.ndarray) -> float:
    """The angular frequency (rad/s) of a recorded sine's input fraction ``u``: the
    periodogram's peak, refined by a parabola through its neighbours.

    Examples
    --------
    >>> t = np.arange(20000) * 0.002
    >>> round(sine_omega(t, 0.5 + 0.4 * np.sin(1.1 * t)), 2)
    1.1
    """
    dt = float(np.median(np.diff(t)))
    x = np.asarray(u, dtype=np.float64) - float(np.mean(u))
    n = 8 * x.size  # zero padding: a finer grid for the peak
    power = np.abs(np.fft.rfft(x, n)) ** 2
    k = int(np.argmax(power[1:])) + 1
    shift = 0.0
    if 1 <= k < power.size - 1:
        a, b, c = np.log(power[k - 1 : k + 2] + 1e-300)
        den = a - 2 * b + c
        shift = 0.5 * (a - c) / den if den != 0 else 0.0
    return float(2.0 * math.pi * (k + shift) / (n * dt))


def _staircase_errors(run: pd.DataFrame, params: ValveParams) -> tuple[np.ndarray, float]:
    """The levels' errors (bar) and the FIT's (points) of one recorded staircase."""
    from spa.closedloop.model_error import level_errors
    from spa.plan.verify import _fit

    table = level_errors(run, params, settle=0.5)
    xi = table["xi"].to_numpy(np.float64)
    meas, model = table["p_meas"].to_numpy(np.float64), table["p_model"].to_numpy(np.float64)
    fit = _fit(xi, meas) - _fit(xi, model) if xi.size >= 2 else math.nan
    return meas - model, fit


def _sine_errors(run: pd.DataFrame, params: ValveParams) -> tuple[float, float]:
    """The mean's and the amplitude's error (bar) of one recorded sine."""
    from spa.model.plant import simulate
    from spa.plan.verify import sine_fit

    t = run["t"].to_numpy(np.float64)
    p = run["p"].to_numpy(np.float64)
    dt = float(np.median(np.diff(t)))
    model = simulate(run["valve"].to_numpy(np.int8), dt, params, p0=max(float(p[0]), 0.0))
    omega = sine_omega(t, run["u"].to_numpy(np.float64))
    start = float(t[0]) + 0.5 * (float(t[-1]) - float(t[0]))
    m_meas, a_meas, _ = sine_fit(t, p, omega, start)
    m_model, a_model, _ = sine_fit(t, model, omega, start)
    return m_meas - m_model, a_meas - a_model


def recorded_model_error(
    runs: Mapping[str, pd.DataFrame],
    metas: Mapping[str, Mapping[str, Any]],
    params: ValveParams,
    where: str = "the dataset",
) -> dict[str, Any]:
    """The identified valve's largest error on the dataset's staircases and sines.

    Parameters
    ----------
    runs, metas : mapping
        Run id -> canonical run table (``t``, ``p``, ``valve``, ``u``) and metadata
        (:func:`spa.datasets.read_runs`); only ``staircase`` and ``sine`` runs are used.
    params : ValveParams
        The identified valve (its own laws, if it carries them).
    where : str, optional
        Where the runs were read, for ``measured_on``.

    Returns
    -------
    dict
        :data:`ERROR_KEYS`, each the largest absolute error over the runs of its kind
        (0 when there is none), and ``measured_on``, a sentence naming the runs.

    Raises
    ------
    ValueError
        When a staircase or sine run lacks one of ``t``, ``p``, ``valve`` and ``u``; named.

    Examples
    --------
    >>> from spa.model.plant import simulate
    >>> dt = 0.002
    >>> u = np.repeat([0.3, 0.6], 2000)
    >>> valve = (np.arange(u.size) % 25 < 25 * u).astype(np.int8)
    >>> p = simulate(valve, dt, ValveParams()) + 0.01  # the plant holds every level 10 mbar higher
    >>> run = pd.DataFrame({"t": np.arange(u.size) * dt, "p": p, "valve": valve, "u": u})
    >>> err = recorded_model_error({"s": run}, {"s": {"kind": "staircase"}}, ValveParams())
    >>> round(err["level_bar"], 4), err["measured_on"]
    (0.01, '1 staircase(s) and 0 sine(s) of the dataset, replayed by the identified valve')
    """
    levels: list[float] = [0.0]
    fits: list[float] = [0.0]
    means: list[float] = [0.0]
    amps: list[float] = [0.0]
    counts = {"staircase": 0, "sine": 0}
    for rid in sorted(runs):
        kind = (metas.get(rid) or {}).get("kind")
        if kind not in counts:
            continue
        run = runs[rid]
        missing = sorted({"t", "p", "valve", "u"} - set(run.columns))
        if missing:
            raise ValueError(
                f"{where}: run {rid!r} ({kind}) has no column(s) {missing}; expected t, p, "
                "valve and u to measure the model's error on it"
            )
        if len(run) < 4:
            continue
        counts[kind] += 1
        if kind == "staircase":
            err, fit = _staircase_errors(run, params)
            levels += np.abs(err[np.isfinite(err)]).tolist()
            if math.isfinite(fit):
                fits.append(abs(fit))
        else:
            mean, amp = _sine_errors(run, params)
            means.append(abs(mean))
            amps.append(abs(amp))
    return {
        "level_bar": max(levels),
        "fit_points": max(fits),
        "sine_mean_bar": max(means),
        "sine_amplitude_bar": max(amps),
        "measured_on": f"{counts['staircase']} staircase(s) and {counts['sine']} sine(s) of "
        f"{where}, replayed by the identified valve",
    }
