"""The identified model's error on the dataset's own recordings, measured as a verification
measures its runs, for the verification's bands (:mod:`spa.plan.bands`).

A verification band holds what the identification's uncertainty moves a prediction by, and
the sensor noise on the measurement. Neither holds the model's own error: the valve spa
identified is a single-state fit of a physical plant, whose held-out FIT is some 95-98 %,
not 100. That error is measured here, on the identification's own modulated runs, each
replayed by the identified valve from its recorded valve command
(:func:`spa.closedloop.model_error.level_errors`): for every staircase, each level's mean
over its second half (as :func:`spa.plan.verify.level_means`) and the levels' FIT (as
:func:`spa.plan.verify.compare`); for every sine, its mean and the amplitude of its
fundamental over the second half (:func:`spa.plan.verify.sine_fit`).

Of each kind, the error's standard deviation is what a band adds (:func:`error_spread`):
the root mean square of the recorded errors less the share the sensor noise puts in them
(a recorded level's mean carries ``(noise**2 + q**2/12)/n``), times the identification's
held-out factor (its errors were measured on the runs it was fitted to,
:func:`spa.plan.bands.heldout_factor`), with the degrees of freedom of the levels it was
measured on (Kish's effective count over the settings' levels: replicates share a bias).
When the verified setting was recorded, its own runs measure its error; when it was not, the
worst recorded setting's error stands for it, and the band says "extrapolated".
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
import pandas as pd

from spa.model.params import ValveParams

__all__ = [
    "ERROR_KEYS",
    "error_spread",
    "no_model_error",
    "recorded_model_error",
    "sine_omega",
]

#: The model-error terms: each prediction kind, and its unit.
ERROR_KEYS = {
    "level": "bar",
    "fit": "points",
    "sine_mean": "bar",
    "sine_amplitude": "bar",
}


def no_model_error(why: str) -> dict[str, Any]:
    """Every term 0, with ``measured_on`` saying why none was measured."""
    zero = {"sd": 0.0, "dof": math.inf, "n": 0, "largest": 0.0}
    return {
        **{k: dict(zero) for k in ERROR_KEYS},
        "heldout_factor": 1.0,
        "setting": None,
        "extrapolated": False,
        "measured_on": f"not measured: {why}",
    }


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


def _staircase_errors(
    run: pd.DataFrame, params: ValveParams
) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """The levels' input fractions, errors (bar) and samples averaged, and the FIT's error
    (points), of one recorded staircase."""
    from spa.closedloop.model_error import level_errors
    from spa.plan.verdicts import _fit

    table = level_errors(run, params, settle=0.5)
    xi = table["xi"].to_numpy(np.float64)
    meas, model = table["p_meas"].to_numpy(np.float64), table["p_model"].to_numpy(np.float64)
    u = run["u"].to_numpy(np.float64)
    starts = np.concatenate(([0], np.flatnonzero(u[1:] != u[:-1]) + 1))
    lengths = np.diff(np.append(starts, u.size))
    counts = np.maximum(np.round(0.5 * lengths), 1.0)[: xi.size]
    fit = _fit(xi, meas) - _fit(xi, model) if xi.size >= 2 else math.nan
    return xi, meas - model, counts, fit


def _sine_errors(run: pd.DataFrame, params: ValveParams) -> tuple[float, float, int]:
    """The mean's and the amplitude's error (bar) of one recorded sine, and its samples."""
    from spa.model.plant import simulate
    from spa.plan.verdicts import sine_fit

    t = run["t"].to_numpy(np.float64)
    p = run["p"].to_numpy(np.float64)
    dt = float(np.median(np.diff(t)))
    model = simulate(run["valve"].to_numpy(np.int8), dt, params, p0=max(float(p[0]), 0.0))
    omega = sine_omega(t, run["u"].to_numpy(np.float64))
    start = float(t[0]) + 0.5 * (float(t[-1]) - float(t[0]))
    m_meas, a_meas, n = sine_fit(t, p, omega, start)
    m_model, a_model, _ = sine_fit(t, model, omega, start)
    return m_meas - m_model, a_meas - a_model, n


def error_spread(
    errors: Sequence[float], noise_var: Sequence[float], groups: Sequence[object], factor: float
) -> dict[str, Any]:
    """One kind's model error as a band takes it: ``sd`` (the errors' root mean square less
    the noise's expected share ``noise_var``, times ``factor``), ``dof`` (Kish's effective
    count over ``groups``, less 1), ``n`` (errors) and ``largest`` (the largest in-sample
    absolute error).

    Examples
    --------
    >>> out = error_spread([0.01, -0.01, 0.01, -0.01], [0.0] * 4, ["a", "b", "c", "d"], 1.0)
    >>> round(out["sd"], 4), out["dof"]
    (0.01, 3.0)
    >>> error_spread([0.001, -0.001], [1e-6, 1e-6], ["a", "b"], 1.0)["sd"]  # noise alone
    0.0
    """
    from spa.plan.bands import effective_count

    e = np.asarray(errors, dtype=np.float64)
    if e.size == 0:
        return {"sd": 0.0, "dof": math.inf, "n": 0, "largest": 0.0}
    bias = max(float(np.mean(e**2)) - float(np.mean(noise_var)), 0.0)
    n_eff = effective_count(e.tolist(), list(groups))
    return {
        "sd": float(factor * math.sqrt(bias)),
        "dof": float(max(n_eff - 1.0, 1.0)),
        "n": int(e.size),
        "largest": float(np.max(np.abs(e))),
    }


def recorded_model_error(
    runs: Mapping[str, pd.DataFrame],
    metas: Mapping[str, Mapping[str, Any]],
    params: ValveParams,
    where: str = "the dataset",
    *,
    noise: float = 0.0,
    quantum: float = 0.0,
    setting: str | None = None,
    factor: float = 1.0,
) -> dict[str, Any]:
    """The identified valve's error on the dataset's staircases and sines, as the
    verification's bands take it (:func:`error_spread`).

    Parameters
    ----------
    runs, metas : mapping
        Run id -> canonical run table (``t``, ``p``, ``valve``, ``u``) and metadata
        (:func:`spa.datasets.read_runs`); only ``staircase`` and ``sine`` runs are used.
    params : ValveParams
        The identified valve (its own laws, if it carries them).
    where : str, optional
        Where the runs were read, for ``measured_on``.
    noise, quantum : float, optional
        The sensor's noise (bar, standard deviation) and ADC step (bar): their share of each
        recorded error is taken out.
    setting : str, optional
        The verified setting's label: when some runs recorded it, only those measure the
        error; when none did, every setting's error is measured apart and the worst stands
        for it (``extrapolated``). All runs together without it.
    factor : float, default 1
        The held-out factor (:func:`spa.plan.bands.heldout_factor`).

    Returns
    -------
    dict
        Each of :data:`ERROR_KEYS` -> :func:`error_spread`'s ``sd``, ``dof``, ``n`` and
        ``largest``; ``heldout_factor``; ``setting`` (the settings measured on);
        ``extrapolated``; and ``measured_on``, a sentence naming the runs.

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
    >>> round(err["level"]["sd"], 4), err["measured_on"]
    (0.01, '1 staircase(s) and 0 sine(s) of the dataset, replayed by the identified valve')
    """
    from spa.model.modulators import Modulator

    per_sample = float(noise) ** 2 + float(quantum) ** 2 / 12.0
    # per setting: kind -> (errors, noise variances, groups)
    found: dict[str, dict[str, tuple[list[float], list[float], list[object]]]] = {}
    counts = {"staircase": 0, "sine": 0}
    for rid in sorted(runs):
        meta = metas.get(rid) or {}
        kind = meta.get("kind")
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
        mod = meta.get("modulator")
        label = Modulator.from_mapping(dict(mod)).label if isinstance(mod, Mapping) else rid
        kinds = found.setdefault(label, {k: ([], [], []) for k in ERROR_KEYS})
        counts[kind] += 1
        if kind == "staircase":
            xi, err, n, fit = _staircase_errors(run, params)
            ok = np.isfinite(err)
            kinds["level"][0].extend(err[ok].tolist())
            kinds["level"][1].extend((per_sample / n[ok]).tolist())
            kinds["level"][2].extend(f"{label} {x:.4f}" for x in xi[ok])
            if math.isfinite(fit):
                kinds["fit"][0].append(fit)
                kinds["fit"][1].append(0.0)
                kinds["fit"][2].append(rid)
        else:
            mean, amp, n_s = _sine_errors(run, params)
            for key, value, var in (
                ("sine_mean", mean, per_sample / max(n_s, 1)),
                ("sine_amplitude", amp, 2.0 * per_sample / max(n_s, 1)),
            ):
                kinds[key][0].append(value)
                kinds[key][1].append(var)
                kinds[key][2].append(rid)
    recorded = setting is not None and setting in found
    if setting is None or recorded:
        use = [setting] if recorded else sorted(found)
        pooled = {
            k: tuple([x for s in use for x in found[s][k][i]] for i in range(3)) for k in ERROR_KEYS
        }
        spread = {k: error_spread(*pooled[k], factor) for k in ERROR_KEYS}  # type: ignore[misc]
        on = [setting] if recorded else use
    else:  # extrapolated: the worst recorded setting's error stands for this one
        spread, on = {}, sorted(found)
        for k in ERROR_KEYS:
            each = [error_spread(*found[s][k], factor) for s in sorted(found)]
            each = [e for e in each if e["n"]] or [error_spread([], [], [], factor)]
            spread[k] = max(each, key=lambda e: e["sd"])
    said = f"{counts['staircase']} staircase(s) and {counts['sine']} sine(s) of {where}"
    if setting is not None:
        said += (
            f"; the verified setting {setting}'s own runs"
            if recorded
            else f"; {setting} was not recorded: the worst of {', '.join(on) or 'none'}"
        )
    return {
        **spread,
        "heldout_factor": float(factor),
        "setting": on,
        "extrapolated": bool(setting is not None and not recorded),
        "measured_on": said + ", replayed by the identified valve",
    }
