"""The identified model's error on the closed loop's measures, from the dataset's recorded
open-loop staircases of the loop's own setting (:mod:`spa.plan.loop_bands`).

A closed loop rejects the model's level errors but not the rest: its ripple, its response
time and the command that holds each level are the plant's. Each is measured on the
recorded staircases of the loop's setting against the identified valve's replay of the same
valve command, level by level, as a log ratio (the ripple's peak-to-peak,
:func:`ripple_error`; the settling time, :func:`settling_error`) or a log-odds difference
(the duty that holds a pressure, :func:`duty_error`), and
:func:`spa.plan.loop_bands.with_model_error` carries it to the loop's prediction.
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Mapping, Sequence
from typing import Any

import numpy as np
import pandas as pd
from scipy.special import expit, logit

from spa.closedloop.metrics import steps
from spa.model.params import ValveParams

__all__ = [
    "DUTY_RANGE",
    "HELD",
    "RIPPLE_MIN_LEVELS",
    "SETTLED",
    "duty_error",
    "hold_odds",
    "ripple_error",
    "settling_error",
]

#: Fewest recorded levels with switching whose ripple the model's error is taken from.
RIPPLE_MIN_LEVELS = 3


def _setting_staircases(
    runs: Mapping[str, pd.DataFrame],
    metas: Mapping[str, Mapping[str, Any]],
    params: ValveParams,
    setting: str,
) -> Iterator[tuple[str, Any, tuple[np.ndarray, np.ndarray, np.ndarray, float, np.ndarray]]]:
    """The recorded open-loop staircases of ``setting``, in run order: each run's id, its
    modulator, and its pressure, valve command, input fraction, logging step and the
    identified valve's replay of that command (runs without ``t``, ``p``, ``valve`` and ``u``,
    or under 8 samples, are passed over)."""
    from spa.model.modulators import Modulator
    from spa.model.plant import simulate

    for rid in sorted(runs):
        meta = metas.get(rid) or {}
        mod = meta.get("modulator")
        if meta.get("kind") != "staircase" or not isinstance(mod, Mapping):
            continue
        modulator = Modulator.from_mapping(dict(mod))
        if modulator.label != setting:
            continue
        run = runs[rid]
        if not {"t", "p", "valve", "u"} <= set(run.columns) or len(run) < 8:
            continue
        t = run["t"].to_numpy(np.float64)
        p = run["p"].to_numpy(np.float64)
        valve = run["valve"].to_numpy(np.int8)
        u = run["u"].to_numpy(np.float64)
        dt = float(np.median(np.diff(t)))
        model = simulate(valve, dt, params, p0=max(float(p[0]), 0.0))
        yield rid, modulator, (p, valve, u, dt, model)


def _log_ratios(logs: Sequence[float], used: Sequence[str], space: str = "log") -> dict[str, Any]:
    """A measure's model error as :func:`spa.plan.loop_bands.with_model_error` takes it:
    ``n`` and ``runs``, and with at least :data:`RIPPLE_MIN_LEVELS` errors their ``dof`` and,
    for log ratios (``space="log"``), their geometric mean ``factor`` and ``log_sd``, for
    log-odds differences (``"logit"``) their mean ``shift`` and ``logit_sd``."""
    out: dict[str, Any] = {"n": len(logs), "runs": list(used)}
    if len(logs) >= RIPPLE_MIN_LEVELS:
        mean, sd = float(np.mean(logs)), float(np.std(logs, ddof=1))
        if space == "logit":
            out.update(shift=mean, logit_sd=sd)
        else:
            out.update(factor=float(math.exp(mean)), log_sd=sd)
        out["dof"] = float(len(logs) - 1)
    return out


def ripple_error(
    runs: Mapping[str, pd.DataFrame],
    metas: Mapping[str, Mapping[str, Any]],
    params: ValveParams,
    setting: str,
    noise: float = 0.0,
    quantum: float = 0.0,
    seed: int = 0,
) -> dict[str, Any]:
    """The identified valve's error on the ripple of the recorded open-loop staircases of one
    setting: each level's peak-to-peak over its last quarter, measured against the valve's
    replay of the same valve command with the sensor's noise and ADC step (like with like),
    as a log ratio.

    Parameters
    ----------
    runs, metas : mapping
        Run id -> canonical run table (``t``, ``p``, ``valve``, ``u``) and metadata; the
        ``staircase`` runs of ``setting`` are used.
    params : ValveParams
        The identified valve (its own laws, if it carries them).
    setting : str
        The setting's label (:attr:`spa.model.modulators.Modulator.label`), e.g. the closed
        loop's.
    noise, quantum : float, optional
        The sensor's noise (bar, standard deviation) and ADC step (bar), put on the replay.
    seed : int, default 0
        Seed of the replay's noise.

    Returns
    -------
    dict
        ``n`` (levels whose valve switched over their last quarter), and with at least
        :data:`RIPPLE_MIN_LEVELS` of them ``factor`` (the geometric mean of measured over
        replayed peak-to-peak), ``log_sd`` (the log ratios' standard deviation) and ``dof``;
        ``runs``, the runs read.

    Examples
    --------
    >>> from spa.model.plant import simulate
    >>> dt = 0.002
    >>> u = np.repeat([0.3, 0.5, 0.7], 2000)
    >>> valve = (np.arange(u.size) % 25 < 25 * u).astype(np.int8)
    >>> p = 1.2 * simulate(valve, dt, ValveParams())  # ripple (and levels) 20 % larger
    >>> run = pd.DataFrame({"t": np.arange(u.size) * dt, "p": p, "valve": valve, "u": u})
    >>> meta = {"kind": "staircase", "modulator": {"type": "pwm", "f_w": 20.0}}
    >>> err = ripple_error({"s": run}, {"s": meta}, ValveParams(), "pwm-20Hz")
    >>> err["n"], round(err["factor"], 3)
    (3, 1.2)
    """

    rng = np.random.default_rng(seed)
    logs: list[float] = []
    used: list[str] = []
    for rid, _, (p, valve, u, _, model) in _setting_staircases(runs, metas, params, setting):
        for a, b in steps(u):
            q = slice(b - (b - a) // 4, b)
            if b - a < 16 or np.all(valve[q] == valve[q][0]):
                continue  # no switching over the last quarter: no ripple to compare
            logged = model[q] + (rng.normal(0.0, noise, b - q.start) if noise > 0 else 0.0)
            if quantum > 0:
                logged = np.round(logged / quantum) * quantum
            measured, replayed = float(np.ptp(p[q])), float(np.ptp(logged))
            if measured > 0 and replayed > 0:
                logs.append(math.log(measured / replayed))
        used.append(rid)
    return _log_ratios(logs, used)


def _open_settling(y: np.ndarray, a0: int, a: int, b: int, window: int, dt: float) -> float:
    """An open-loop staircase level's settling time (s) within 2 % of its step, as
    :func:`spa.plan.settling.settling_times` measures a closed loop's: the cycle-mean of the
    level's own samples, from the previous level's last quarter's mean to its own's, a sample
    outside only beyond the 2 % band widened by ``1.96`` times the fluctuation over its last
    quarter. NaN for a step under ten noise-free samples or one still outside at the end."""
    from spa.closedloop.metrics import cycle_mean
    from spa.plan.settling import BAND, _fluctuation

    before, level = cycle_mean(y[a0:a], window), cycle_mean(y[a:b], window)
    r0 = float(np.mean(before[3 * before.size // 4 :]))
    r1 = float(np.mean(level[3 * level.size // 4 :]))
    if r1 == r0:
        return math.nan
    z = (level - r0) / (r1 - r0)
    band = BAND + 1.96 * _fluctuation(z[3 * z.size // 4 :])
    outside = np.flatnonzero(np.abs(z - 1.0) > band)
    if outside.size and outside[-1] >= 3 * z.size // 4:
        return math.nan  # not settled before its last quarter: no time to compare
    return float((outside[-1] + 1) * dt) if outside.size else 0.0


def settling_error(
    runs: Mapping[str, pd.DataFrame],
    metas: Mapping[str, Mapping[str, Any]],
    params: ValveParams,
    setting: str,
    noise: float = 0.0,
    quantum: float = 0.0,
    seed: int = 0,
    min_step: float = 0.05,
) -> dict[str, Any]:
    """The identified valve's error on the settling time of the recorded open-loop staircases
    of one setting: each level step's time to settle within 2 % of the step, measured against
    the valve's replay of the same valve command with the sensor's noise and ADC step, as a
    log ratio (as :func:`ripple_error` measures the ripple's).

    A closed loop's settling time is the plant's response time through the controller: a plant
    whose steps settle 20 % later open loop than the model's settles later closed loop too,
    and no draw from the identification's intervals holds that error (a lag or a slow second
    state the model lacks). The ratios' geometric mean and spread carry it to the closed
    loop's prediction (:func:`spa.plan.loop_bands.with_model_error`).

    Parameters
    ----------
    runs, metas, params, setting, noise, quantum, seed
        As :func:`ripple_error`.
    min_step : float, default 0.05
        Smallest step between levels, as a fraction of the recorded range of level means,
        whose settling time is compared: a smaller step's 2 % band is within the sensor's
        noise.

    Returns
    -------
    dict
        ``n`` (level steps compared), and with at least :data:`RIPPLE_MIN_LEVELS` of them
        ``factor`` (the geometric mean of measured over replayed settling time), ``log_sd``
        and ``dof``; ``runs``, the runs read.

    Examples
    --------
    >>> from spa.model.plant import simulate
    >>> import dataclasses
    >>> dt = 0.002
    >>> u = np.repeat([0.2, 0.5, 0.8, 0.5, 0.2], 4000)  # 8 s a level
    >>> valve = (np.arange(u.size) % 25 < 25 * u).astype(np.int8)
    >>> slow = dataclasses.replace(ValveParams(), c1=ValveParams().c1 * 1.3,
    ...                            tau2=ValveParams().tau2 * 1.3)  # 30 % slower both ways
    >>> run = pd.DataFrame({"t": np.arange(u.size) * dt, "p": simulate(valve, dt, slow),
    ...                     "valve": valve, "u": u})
    >>> meta = {"kind": "staircase", "modulator": {"type": "pwm", "f_w": 20.0}}
    >>> err = settling_error({"s": run}, {"s": meta}, ValveParams(), "pwm-20Hz")
    >>> err["n"], 1.2 < err["factor"] < 1.4
    (4, True)
    """
    from spa.closedloop.design import MAX_PERIOD
    from spa.model.modulators import get_kind
    from spa.model.modulators.core import settings_arrays

    rng = np.random.default_rng(seed)
    logs: list[float] = []
    used: list[str] = []
    for rid, modulator, (p, _, u, dt, model) in _setting_staircases(runs, metas, params, setting):
        if noise > 0:
            model = model + rng.normal(0.0, noise, model.size)
        if quantum > 0:
            model = np.round(model / quantum) * quantum
        levels = steps(u)
        means = [float(np.mean(p[b - (b - a) // 4 : b])) for a, b in levels]
        span = max(np.ptp(means), 1e-12) if len(means) > 1 else 1e-12
        kind, settings = (
            get_kind(modulator.kind),
            settings_arrays(modulator.kind, dict(modulator.settings)),
        )
        for k in range(1, len(levels)):
            (a0, _), (a, b) = levels[k - 1], levels[k]
            if b - a < 16 or a - a0 < 16 or abs(means[k] - means[k - 1]) < min_step * span:
                continue
            period = float(np.asarray(kind.cycle(np.float64(u[a]), settings, params)))
            window = max(round(float(np.clip(period, 2.0 * dt, MAX_PERIOD)) / dt), 1)
            measured = _open_settling(p, a0, a, b, window, dt)
            replayed = _open_settling(model, a0, a, b, window, dt)
            if measured > 0 and replayed > 0:  # NaN fails both
                logs.append(math.log(measured / replayed))
        used.append(rid)
    return _log_ratios(logs, used)


#: The duties (the valve's mean opening over a level's last quarter) whose log-odds are
#: compared: a level held with the valve all but always open or closed has none to speak of.
DUTY_RANGE = (0.02, 0.98)


#: A level is compared only when it has settled: its mean over the second half of its last
#: quarter within this share of ``k2`` of its mean over the first half, recorded and replayed.
SETTLED = 0.01


#: The pressures (shares of ``k2``) whose levels are compared: near 0 or the supply a level's
#: ripple is as large as its distance from either, and the averaged model's odds
#: (:func:`hold_odds`) turn steep.
HELD = (0.05, 0.95)


def _level_means(
    p: np.ndarray, valve: np.ndarray, u: np.ndarray, model: np.ndarray, dt: float
) -> np.ndarray:
    """Each level (a run of one input fraction ``u``, 16 samples or more) of a staircase, over
    its last quarter: the duty, the recorded and the replayed pressure's means, how much each
    moved from the quarter's first half to its second, and the valve's rising edges per
    second; rows of six."""
    rows = []
    for a, b in steps(u):
        if b - a < 16:
            continue
        q = b - (b - a) // 4
        mid = (q + b) // 2
        rises = int(np.count_nonzero(np.diff(valve[q:b]) > 0))
        rows.append(
            (
                float(np.mean(valve[q:b])),
                float(np.mean(p[q:b])),
                float(np.mean(model[q:b])),
                float(np.mean(p[mid:b]) - np.mean(p[q:mid])),
                float(np.mean(model[mid:b]) - np.mean(model[q:mid])),
                rises / ((b - q) * dt),
            )
        )
    return np.asarray(rows, dtype=np.float64).reshape(-1, 6)


def hold_odds(p: np.ndarray, params: ValveParams) -> np.ndarray:
    """The log-odds of the valve's open share ``alpha`` that holds ``p`` on the averaged model:
    with ``alpha f_open(p) + (1 - alpha) f_closed(p) = 0`` the odds are ``-f_closed /
    f_open``; NaN outside ``(0, k2)``.

    Examples
    --------
    >>> v = ValveParams()  # the paper's laws: (sqrt(p) / c1) / ((k2 - p) / tau2)
    >>> p = np.array([0.2, 0.5])
    >>> np.allclose(hold_odds(p, v), np.log(np.sqrt(p) / v.c1 / ((v.k2 - p) / v.tau2)))
    True
    """
    from spa.model.laws.rates import closed_rate, open_rate

    x = np.asarray(p, dtype=np.float64)
    inside = (x > 0.0) & (x < params.k2)
    y = np.where(inside, x, 0.5 * params.k2)
    out = np.log(-closed_rate(y, params)) - np.log(open_rate(y, params))
    return np.where(inside, out, np.nan)


def duty_error(
    runs: Mapping[str, pd.DataFrame],
    metas: Mapping[str, Mapping[str, Any]],
    params: ValveParams,
    setting: str,
    noise: float = 0.0,
    quantum: float = 0.0,
    seed: int = 0,
) -> dict[str, Any]:
    """The identified valve's error on the command that holds a pressure, from the recorded
    open-loop staircases of one setting, as a log-odds difference: at each settled level,
    the log-odds of the duty the bench holds the level's recorded pressure with, less that
    of the duty the identified valve holds it with.

    A closed loop's integral finds whatever command holds its set-point, so the loop's
    levels cannot show a plant that charges slower or vents faster than the model: its
    command does. The valve's open share ``alpha`` that holds ``p`` has the odds
    ``-f_closed(p) / f_open(p)`` (with the paper's laws ``(sqrt(p) / c1) / ((k2 - p) /
    tau2)``), so a conductance's error moves every level's log-odds alike and a supply's
    most at the top. At a level the replay of the recorded command holds ``p_model`` where
    the bench held ``p``; the identified valve holds ``p`` with an open share whose log-odds
    are larger by ``hold_odds(p) - hold_odds(p_model)`` (:func:`hold_odds`), and so with the
    duty less the delays' share (they open it ``t_off - t_on`` longer per pulse: ``alpha = d
    + rises * (t_off - t_on)``). The error is the log-odds of the recorded duty less that
    duty's (a level whose pressure the identified valve cannot hold, at or above its ``k2``,
    is left out). :func:`spa.plan.loop_bands.with_model_error` moves
    the loop's predicted duty by the errors' mean and widens its band by their spread.

    Parameters
    ----------
    runs, metas, params, setting
        As :func:`ripple_error`.
    noise, quantum, seed
        Taken as the other measures take them and not used: a level's mean over its last
        quarter averages the sensor's noise and the ADC's step out.

    Returns
    -------
    dict
        ``n`` (levels compared: duty within :data:`DUTY_RANGE`, settled within
        :data:`SETTLED` of ``k2`` and within :data:`HELD` of it, recorded and replayed),
        and with at least :data:`RIPPLE_MIN_LEVELS` of them ``shift`` (the mean log-odds
        difference), ``logit_sd`` and ``dof``; ``runs``, the runs read.

    Examples
    --------
    >>> from spa.model.plant import simulate
    >>> import dataclasses
    >>> dt = 0.002
    >>> u = np.repeat([0.2, 0.35, 0.5, 0.65, 0.8], 3000)
    >>> valve = (np.arange(u.size) % 25 < 25 * u).astype(np.int8)
    >>> vent = dataclasses.replace(ValveParams(), c1=2 * ValveParams().c1)  # vents slower
    >>> run = pd.DataFrame({"t": np.arange(u.size) * dt, "p": simulate(valve, dt, vent),
    ...                     "valve": valve, "u": u})
    >>> meta = {"kind": "staircase", "modulator": {"type": "pwm", "f_w": 20.0}}
    >>> err = duty_error({"s": run}, {"s": meta}, ValveParams(), "pwm-20Hz")
    >>> err["n"] >= 3, err["shift"] < -0.3  # the bench holds each pressure with less duty
    (True, True)
    """
    logs: list[float] = []
    used: list[str] = []
    lo, hi = DUTY_RANGE
    lag = float(params.t_off) - float(params.t_on)
    for rid, _, (p, valve, u, dt, model) in _setting_staircases(runs, metas, params, setting):
        used.append(rid)
        rows = _level_means(p, valve.astype(np.float64), u, model, dt)
        duty, p_bench, p_model, drift_bench, drift_model, rises = rows.T
        alpha = duty + rises * lag
        keep = (
            (duty > lo)
            & (duty < hi)
            & (alpha > lo)
            & (alpha < hi)
            & (np.abs(drift_bench) <= SETTLED * params.k2)
            & (np.abs(drift_model) <= SETTLED * params.k2)
            & (np.minimum(p_bench, p_model) > HELD[0] * params.k2)
            & (np.maximum(p_bench, p_model) < HELD[1] * params.k2)
        )
        if not keep.any():
            continue
        # the open share the identified valve needs for the recorded pressure, then its duty
        a = alpha[keep]
        need = logit(a) + hold_odds(p_bench[keep], params) - hold_odds(p_model[keep], params)
        d_need = expit(need) - rises[keep] * lag
        with np.errstate(invalid="ignore", divide="ignore"):
            err = logit(duty[keep]) - logit(np.clip(d_need, 1e-9, 1.0 - 1e-9))
        logs.extend(float(e) for e in err if math.isfinite(e))
    return _log_ratios(logs, used, space="logit")
