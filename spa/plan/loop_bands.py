"""The closed loop's verification predictions: what the bench will measure when the exported
controller plays the promise's staircase, with 95 % bands that both ends can break.

The closed_loop stage promises a worst case over the 95 % box (``bench.promise``): an upper
bound that a bench keeps whenever it does better, however much better. As a verification
band, ``0`` to that bound plus a margin kept a tripled overshoot and a slower valve's lower
ripple (issues 61 and 63). A verification instead predicts the measurement: the staircase
(one hold at the first level, then the levels up and back down,
:func:`spa.plan.verify.closed_loop_runs`) is simulated through the exported PI and
modulator (:func:`spa.closedloop.loop.closed_loop_arrays`) on valves drawn from the
identification's uncertainty (:func:`spa.plan.bands.parameter_draws`), each with its own
sensor noise in the loop and in the log and the ADC's step, and measured as a recording is
(:func:`measure_loop_run`). Each measure's band is the draws' mean ± ``t(D - 1) sd
sqrt(1 + 1/D)`` (a prediction interval for one more draw of the same distribution), its lower
end no lower than 0; the ripple's, a whole number of ADC steps, half a step wider at each end
(the continuity correction: on a 2.4 mbar ADC, all three of an unchanged physical finger's
ripples fell one step under a band that ended between two steps).

The model's level errors are not in these bands: a closed loop rejects them. Its ripple is
not rejected: where the dataset recorded the loop's setting open loop, the model's error on
those staircases' ripple (:func:`spa.plan.loop_error.ripple_error`, measured against the
replay with the same noise and ADC step) scales the ripple's prediction and widens its band
(:func:`with_model_error`); on an unchanged physical plant the ripple had read 10-30 %
under the model's. Nor is its response time: the model's error on the time those open-loop
steps take to settle within 2 % (:func:`spa.plan.loop_error.settling_error`) scales and
widens the settling time's band alike (an unchanged physical finger settled 1.06-1.19 s
closed loop against a band of 0.82-0.98 s from the draws alone). A settling time is
predicted only when at most one draw in twenty fails to settle within 2 % of its step by
the end of a level.

Nor is the command that holds a level: a closed loop's integral finds the duty that holds
its set-point on the plant it runs on, so a supply 20 % lower keeps the loop's levels and
moves its command. The duty over the highest and the lowest level's last quarter
(:func:`level_duties`) is predicted on the identified valve and moved by the model's error
on the duty that holds a pressure on the recorded open-loop staircases of the loop's
setting, on the log-odds scale (:func:`spa.plan.loop_error.duty_error`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
import pandas as pd
from scipy import stats
from scipy.special import expit, logit

from spa.closedloop.metrics import steps
from spa.model.params import ValveParams

__all__ = [
    "DUTIES",
    "LOOP_DRAWS",
    "MEASURES",
    "level_duties",
    "loop_predictions",
    "measure_loop_run",
    "with_model_error",
]

#: Valves (each with its noise) the closed-loop staircase is simulated on.
LOOP_DRAWS = 48

#: The closed loop's measures: unit and what they are.
MEASURES = {
    "overshoot": ("%", "the worst step's overshoot of the cycle-mean pressure"),
    "settling_time": ("s", "the worst step's settling time within 2 %, past the sensor's share"),
    "ripple_pp": ("bar", "the worst step's peak-to-peak logged pressure over its last quarter"),
    "duty_top": ("fraction", "the valve command's mean over the highest level's last quarter"),
    "duty_bottom": ("fraction", "the valve command's mean over the lowest level's last quarter"),
}

#: The measures that are the command holding a level: predicted only with the model's error
#: on it measured (:func:`spa.plan.loop_error.duty_error`).
DUTIES = ("duty_top", "duty_bottom")


def level_duties(run: pd.DataFrame, lead: float) -> dict[str, float]:
    """The valve command's mean (``valve``, 0/1) over the last quarter of the highest and of
    the lowest set-point's steps (``r``) of a closed-loop staircase, a quarter of the lead's
    length (one hold), past the ``lead`` s at the first level, and each one's step: the
    share of that window one pulse holds (its mean on-time over the window's length; where
    the window cuts the pulses moves the mean by up to one). NaN without a ``valve`` column.

    Examples
    --------
    >>> r = np.repeat([0.2, 0.2, 0.4, 0.2], 16)  # a lead of 16 samples, then 0.2, 0.4, 0.2
    >>> valve = np.where(r > 0.3, np.tile([1, 1, 1, 0], 16), np.tile([1, 0, 0, 0], 16))
    >>> run = pd.DataFrame({"t": np.arange(64) * 0.1, "r": r, "valve": valve})
    >>> level_duties(run, 1.6)
    {'duty_top': 0.75, 'duty_bottom': 0.25, 'duty_top_step': 0.75, 'duty_bottom_step': 0.25}
    """
    keys = (*DUTIES, *(n + "_step" for n in DUTIES))
    if "valve" not in run:
        return dict.fromkeys(keys, math.nan)
    r = run["r"].to_numpy(np.float64)
    valve = run["valve"].to_numpy(np.float64)
    t = run["t"].to_numpy(np.float64)
    dt = float(t[1] - t[0]) if t.size > 1 else 1.0
    quarter = max(round(float(lead) / dt) // 4, 1)
    start = int(np.searchsorted(t, float(lead) - 1e-9 * dt))
    out: dict[str, float] = {}
    for name, level in zip(DUTIES, (float(np.max(r)), float(np.min(r))), strict=True):
        picked = [
            valve[max(b - quarter, a, start) : b]
            for a, b in steps(r)
            if r[a] == level and b > start
        ]
        picked = [x for x in picked if x.size]
        if not picked:
            out[name], out[name + "_step"] = math.nan, math.nan
            continue
        on = np.concatenate(picked)
        pulses = sum(int(np.count_nonzero(np.diff(np.r_[0.0, x]) > 0)) for x in picked)
        out[name] = float(np.mean(on))
        window = float(np.mean([x.size for x in picked]))
        out[name + "_step"] = float(on.sum() / pulses / window) if pulses else 0.0
    return {k: out[k] for k in keys}


def measure_loop_run(
    run: pd.DataFrame, setting: Mapping[str, Any], params: ValveParams, lead: float
) -> dict[str, float]:
    """A closed-loop staircase (``t``, ``p``, ``r``, ``valve``) measured as spa measures its
    own (:func:`spa.synthetic.physical.measure_staircase`), the settling time each step on
    its own samples and past what the sensor adds (:func:`spa.plan.settling.settling_times`;
    ``inf`` when a step does not settle).

    ``setting``: the controller's modulator (the cycle-mean's window, at ``params``);
    ``lead``: the seconds at the first level left out.
    """
    from spa.closedloop.experiments import step_periods
    from spa.model.modulators import Modulator
    from spa.plan.settling import settling_times
    from spa.synthetic.physical import measure_staircase

    levels = sorted({float(v) for v in run["r"]})
    dt = float(run["t"].iloc[1] - run["t"].iloc[0])
    periods = step_periods(Modulator.from_mapping(dict(setting)), params, levels, dt)
    first = float(run["r"].iloc[0])
    _, summary = measure_staircase(run, periods, r_initial=first, skip=lead)
    settle = max(settling_times(run, periods, first, lead), default=0.0)
    return {
        "overshoot": float(summary["worst_overshoot"]),
        "settling_time": float(settle),
        "ripple_pp": float(summary["worst_ripple_pp"]),
        **level_duties(run, lead),
    }


def loop_predictions(
    params: ValveParams,
    setting: Mapping[str, Any],
    controller: Any,
    levels: Sequence[float],
    hold: float,
    dt: float,
    noise: float,
    quantum: float,
    intervals: Mapping[str, tuple[float, float]] | None = None,
    correlation: Mapping[str, Any] | None = None,
    *,
    draws: int = LOOP_DRAWS,
    seed: int = 0,
) -> dict[str, dict[str, Any]]:
    """The closed-loop staircase's measures predicted with 95 % bands.

    Parameters
    ----------
    params : ValveParams
        The identified valve.
    setting : mapping
        The controller's modulator setting (``controller.h``'s).
    controller : PIController
        The exported PI (``bench.promise.controller``).
    levels : sequence of float
        The promise's set-points, bar.
    hold : float
        Seconds at each level.
    dt : float
        The controller's step, s.
    noise, quantum : float
        The sensor's noise (standard deviation) and ADC step, bar.
    intervals, correlation : mapping, optional
        The identification's 95 % intervals and how their errors move together
        (:func:`spa.plan.bands.parameter_draws`); the noise alone without them.
    draws : int, default :data:`LOOP_DRAWS`
    seed : int, default 0

    Returns
    -------
    dict
        Each of :data:`MEASURES` predicted: ``value`` (the draws' mean), ``sd``, ``dof``
        (draws less 1), ``scale`` (``sqrt(1 + 1/draws)``), ``lo``, ``hi`` and ``unit``;
        ``ripple_pp``'s band is wider by ``pad``, half the ADC step, at each end (a logged
        peak-to-peak is a whole number of steps: the continuity correction);
        ``settling_time`` only when at most one draw in twenty left a step unsettled, else
        ``unsettled`` (the share that did). The duties (:data:`DUTIES`) are predicted on the
        identified valve itself, ``draws // 3`` runs each with its own noise (``draws`` says
        so), their band wider at each end by ``pad``, the share of the window one pulse holds
        (where the window cuts the pulses moves a duty by up to that). The parameters'
        uncertainty moves them by what the dataset's recorded levels measure directly
        (:func:`spa.plan.loop_error.duty_error`, added by :func:`with_model_error`), and the
        box's draws would count it twice (on an unseen physical plant their spread was
        0.047 of duty against a recorded error of 0.004).

    Examples
    --------
    >>> from spa.closedloop.controller import PIController
    >>> pi = PIController(kp=0.3, ki=2.0)
    >>> out = loop_predictions(ValveParams(), {"type": "pwm", "f_w": 20.0}, pi, [0.3, 0.5],
    ...                        4.0, 0.002, 0.003, 0.001, draws=8)
    >>> out["overshoot"]["lo"] <= out["overshoot"]["value"] <= out["overshoot"]["hi"]
    True
    >>> out["ripple_pp"]["lo"] > 0  # the noise alone has a peak-to-peak
    True
    """
    from spa.closedloop.experiments import _settled
    from spa.closedloop.loop import closed_loop_arrays
    from spa.model.modulators import Modulator
    from spa.plan.bands import parameter_draws
    from spa.plan.settling import staircase_reference

    mod = Modulator.from_mapping(dict(setting))
    lv = [float(v) for v in levels]
    r, t, lead = staircase_reference(lv, hold, dt)
    valves = parameter_draws(params, intervals, n=draws, seed=seed, correlation=correlation)
    valves = valves or [params] * max(int(draws), 2)
    rng = np.random.default_rng(seed + 7)

    def measured(valve: ValveParams) -> dict[str, float]:
        reading = rng.normal(0.0, noise, r.size) if noise > 0 else None
        p, _, u = closed_loop_arrays(
            r,
            dt,
            mod,
            controller,
            valve,
            lv[0],
            integral0=_settled(mod, controller, valve, lv[0]),
            sensor_noise=reading,
        )
        logged = p + reading if reading is not None else p
        if quantum > 0.0:
            logged = np.round(logged / quantum) * quantum
        run = pd.DataFrame({"t": t, "p": logged, "r": r, "valve": u})
        return measure_loop_run(run, setting, params, lead)

    table = pd.DataFrame([measured(valve) for valve in valves])
    # the duties on the identified valve itself, each run with its own noise: the recorded
    # levels measure what the parameters' uncertainty moves them by (loop_error.duty_error)
    nominal = pd.DataFrame([measured(params) for _ in range(max(int(draws) // 3, 2))])
    out: dict[str, dict[str, Any]] = {}
    for key, (unit, _) in MEASURES.items():
        values = (nominal if key in DUTIES else table)[key].to_numpy(np.float64)
        unsettled = float(np.mean(~np.isfinite(values)))
        if key == "settling_time" and unsettled > 0.05:
            out[key] = {"unsettled": unsettled, "unit": unit}
            continue
        values = values[np.isfinite(values)]
        n = values.size
        if n < 2:
            out[key] = {"unmeasured": True, "unit": unit}
            continue
        widen = float(stats.t.ppf(0.975, n - 1)) * math.sqrt(1.0 + 1.0 / n)
        mean, sd = float(np.mean(values)), float(np.std(values, ddof=1))
        # a logged peak-to-peak is a whole number of ADC steps: the band of a discrete
        # measure takes half a step at each end (the continuity correction); a duty over a
        # window moves by up to one pulse's share with where the window cuts the pulses
        pad = 0.5 * float(quantum) if key == "ripple_pp" else 0.0
        if key in DUTIES:
            step = nominal[key + "_step"].to_numpy(np.float64)
            pad = float(np.mean(step[np.isfinite(step)])) if np.isfinite(step).any() else 0.0
        out[key] = {
            "value": mean,
            "sd": sd,
            "dof": float(n - 1),
            "scale": math.sqrt(1.0 + 1.0 / n),
            "lo": max(mean - widen * sd - pad, 0.0),
            "hi": mean + widen * sd + pad,
            "unit": unit,
            **({"pad": pad} if pad else {}),
            **({"draws": "the identified valve, noise only"} if key in DUTIES else {}),
        }
    return out


def with_model_error(band: Mapping[str, Any], error: Mapping[str, Any]) -> dict[str, Any]:
    """A loop measure's band with the model's error on the same measure of the recorded
    open-loop staircases of the same setting (:mod:`spa.plan.loop_error`).

    The error is a log ratio (the ripple's and the settling time's: ``factor`` and
    ``log_sd``) or, for a duty, a log-odds difference (``shift`` and ``logit_sd``). The
    prediction moves by its mean on that scale (times ``factor``; the duty's log-odds plus
    ``shift``), and the band's standard deviation is the draws' (carried to the moved value
    on the same scale) and the errors' spread for one more level (``spread * sqrt(1 + 1/n)``
    on that scale, carried back by its slope) in quadrature, with Welch–Satterthwaite's
    degrees of freedom; a duty's band ends within 0 and 1. ``band`` unchanged (but for
    ``model_error`` saying so) when fewer than three levels measured the error, or when it
    has no standard deviation (a promise's own worst case, not a prediction).

    Examples
    --------
    >>> band = {"value": 0.03, "sd": 0.001, "dof": 47.0, "scale": 1.0, "lo": 0.028,
    ...         "hi": 0.032, "unit": "bar", "pad": 0.0}
    >>> out = with_model_error(band, {"n": 12, "factor": 0.8, "log_sd": 0.1, "dof": 11.0})
    >>> round(out["value"], 4), out["lo"] < 0.024 < out["hi"]
    (0.024, True)
    >>> with_model_error(band, {"n": 1})["value"]
    0.03
    >>> duty = {"value": 0.5, "sd": 0.01, "dof": 47.0, "scale": 1.0, "lo": 0.48, "hi": 0.52,
    ...         "unit": "fraction"}
    >>> out = with_model_error(duty, {"n": 8, "shift": math.log(3.0), "logit_sd": 0.05,
    ...                               "dof": 7.0})
    >>> round(out["value"], 4), out["lo"] < 0.75 < out["hi"] <= 1.0
    (0.75, True)
    """
    out = dict(band)
    odds = "shift" in error
    if not ("factor" in error or odds) or "value" not in band or "sd" not in band:
        # too few levels measured the error, or a promise's own number (no draws to widen)
        out["model_error"] = {"n": int(error.get("n", 0)), "applied": False}
        return out
    n, v = int(error["n"]), float(band["value"])
    draws = float(band["sd"]) * float(band.get("scale", 1.0))
    if odds:
        v = min(max(v, 1e-6), 1.0 - 1e-6)
        value = float(expit(logit(v) + float(error["shift"])))
        slope = value * (1.0 - value)  # d value / d log-odds
        draws *= slope / (v * (1.0 - v))
        spread, noted = float(error["logit_sd"]), {"shift": float(error["shift"])}
    else:
        f = float(error["factor"])
        value, slope, draws = f * v, f * v, f * draws
        spread, noted = float(error["log_sd"]), {"factor": f}
    model = slope * spread * math.sqrt(1.0 + 1.0 / n)
    sd = math.hypot(draws, model)
    parts = (draws**4 / float(band["dof"]) if draws > 0 else 0.0) + (
        model**4 / float(error["dof"]) if model > 0 else 0.0
    )
    dof = sd**4 / parts if parts > 0 else math.inf
    half = float(stats.t.ppf(0.975, dof if math.isfinite(dof) else 1e12)) * sd
    pad = float(band.get("pad", 0.0))
    out.update(
        value=value,
        sd=sd,
        dof=dof,
        scale=1.0,
        lo=max(value - half - pad, 0.0),
        hi=min(value + half + pad, 1.0) if odds else value + half + pad,
        model_error={
            "n": n,
            **noted,
            ("logit_sd" if odds else "log_sd"): spread,
            "applied": True,
        },
    )
    return out
