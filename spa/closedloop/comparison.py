"""The ``closed_loop`` stage of a dataset: design PI controllers for its identified valve,
simulate them exactly on the set-point experiments and measure them.

For every modulator setting (the paper's selected settings and the dataset's recommended one)
it designs a fixed PI, a gain-scheduled PI and the scheduled PI with the averaged model's
feed-forward (:func:`spa.closedloop.design.design_pi`), runs the staircase up and down, the
set of steps from rest and the sine (:mod:`spa.closedloop.experiments`) and tabulates the
metrics (:mod:`spa.closedloop.metrics`) with their spread over the operating points.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from spa.closedloop.choice import (
    SETTLED,
    TAU_C_FACTORS,
    _least_overshoot,
    _measured,
    _Staircases,
    closed_loop_sentence,
    end_error,
    held_clause,
    ranked_choices,
)
from spa.closedloop.design import DEFAULT_TAU_C, design_pi, operating_levels
from spa.closedloop.experiments import (
    LoopUnderTest,
    Staircase,
    cycle_period,
    run_sine,
    run_staircase,
    run_steps,
    sine_within,
    spread,
)
from spa.closedloop.levels import common_levels, held_range, wanted_levels
from spa.closedloop.metrics import STEP_METRICS, cycle_mean
from spa.io import dump_yaml
from spa.model.modulators import Modulator
from spa.model.params import ValveParams
from spa.model.plant import mode_time

__all__ = [
    "DEFAULTS",
    "ClosedLoopResult",
    "closed_loop",
    "write_controllers",
]

#: Defaults of the config's ``closed_loop:`` section.
DEFAULTS: dict[str, Any] = {
    "dt": 0.001,
    "tau_c": DEFAULT_TAU_C,
    "levels": None,
    "levels_fraction": [0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8],
    "hold": None,
    "hold_time_constants": 5.0,
    "min_hold": 1.0,
    "step_hold": 2.0,
    "sine": {"offset": 0.4, "amplitude": 0.2, "frequency": 0.5, "duration": 10.0, "skip": 2.0},
    "max_level_fraction": 0.95,
    "figure_decimate": 20,
    "max_overshoot": 10.0,
    "promise_step_fraction": 0.2,
}


def transit_time(levels: list[float], params: ValveParams) -> float:
    """The longest time the valve takes between adjacent levels of the staircase held fully
    open (up: ``tau2*ln((k2 - a)/(k2 - b))``, Eq. A2) or fully exhausting (down:
    ``2*c1*(sqrt(b) - sqrt(a))``, Eq. A1; a valve with its own laws: its time maps,
    :func:`spa.model.plant.mode_time`), s: the part of a large step no controller can
    shorten.

    Examples
    --------
    >>> p = ValveParams(c1=0.5, k2=1.0, tau2=1.0)
    >>> round(transit_time([0.25, 0.5], p), 4)  # up ln(0.75/0.5); down 0.7071 - 0.5
    0.4055
    """
    lv = np.sort(np.asarray(levels, dtype=np.float64))
    a, b = lv[:-1], lv[1:]
    if a.size == 0:
        return 0.0
    up, down = mode_time(True, a, b, params), mode_time(False, b, a, params)
    both = np.concatenate((up, down))
    both = both[np.isfinite(both)]
    return float(both.max()) if both.size else 0.0


def level_hold(
    mod: Modulator,
    params: ValveParams,
    levels: list[float],
    tau_c: float,
    c: Mapping[str, Any],
) -> float:
    """How long the staircase holds each level, s: ``closed_loop.hold`` when set, else the
    longest full-open transit between adjacent levels (:func:`transit_time`) plus
    ``hold_time_constants`` (5) closed-loop time constants, at least ``min_hold``, rounded up
    to 0.1 s. The closed-loop time constant is the slower of SIMC's target ``tau_c + theta``
    and the PI's integral time ``Ti = min(tau, 4*(tau_c + theta))`` (the tail an integrator
    leaves when it does not cancel the plant's pole), the largest over the levels
    (:func:`spa.closedloop.design.local_models`).

    Examples
    --------
    >>> level_hold(Modulator.from_mapping({"type": "pwm", "f_w": 20.0}), ValveParams(),
    ...            [0.2, 0.3], 0.2, DEFAULTS)  # 0.826*ln(0.637/0.537) + 5*min(tau, 0.926)
    4.8
    """
    if c.get("hold") is not None:
        return float(c["hold"])
    from spa.closedloop.design import _local_models

    m = _local_models(levels, mod, params)
    fast = tau_c + m.dead_time
    slow = np.minimum(m.tau, 4.0 * fast)
    t_cl = float(np.max(np.maximum(fast, np.where(np.isfinite(slow), slow, fast))))
    n = float(c.get("hold_time_constants", DEFAULTS["hold_time_constants"]))
    auto = transit_time(levels, params) + n * t_cl
    auto = max(auto, float(c.get("min_hold", DEFAULTS["min_hold"])))
    return math.ceil(round(auto * 10.0, 9)) / 10.0


@dataclass
class ClosedLoopResult:
    """What the stage writes.

    Attributes
    ----------
    table : pandas.DataFrame
        Long table: ``modulator``, ``description``, ``controller``, ``experiment``,
        ``metric``, ``median``, ``min``, ``max``, ``spread`` (over operating points).
    steps : pandas.DataFrame
        One row per step of the staircase and the step set (Fig. 11's data).
    traces : pandas.DataFrame
        Decimated staircase traces: set-point and cycle-mean pressure (Fig. 10's data).
    controllers : dict
        ``controllers.yaml``: the gains per setting, the sentence and the setting it names.
    skipped : dict
        Setting label -> why it was left out.
    """

    table: pd.DataFrame
    steps: pd.DataFrame
    traces: pd.DataFrame
    controllers: dict[str, Any]
    skipped: dict[str, str] = field(default_factory=dict)

    @property
    def sentence(self) -> str:
        """The one-sentence recommendation (:func:`closed_loop_sentence`)."""
        return str(self.controllers.get("sentence", ""))


def _settings(
    selected: Iterable[Mapping[str, Any] | Modulator],
    recommendation: Mapping[str, Any] | None,
    params: ValveParams,
) -> tuple[list[Modulator], Modulator | None]:
    """The settings to design, bound to the identified valve: an LPWM that omits the valve
    it inverts gets the dataset's identified constants (not the paper's nominal valve), so
    that its simulation, its ``controllers.yaml`` entry and its C header all invert the
    dataset's valve."""
    mods = [Modulator.from_mapping(m).bind(params) for m in selected]
    rec = None
    best = (recommendation or {}).get("recommended")
    if isinstance(best, Mapping) and best.get("setting"):
        rec = Modulator.from_mapping(best["setting"]).bind(params)
        if rec.label not in {m.label for m in mods}:
            mods.append(rec)
    return mods, rec


def _summary(frame: pd.DataFrame, metrics: Iterable[str]) -> list[dict[str, Any]]:
    rows = []
    for metric in metrics:
        v = frame[metric].to_numpy(np.float64)
        finite = v[np.isfinite(v)]
        rows.append(
            {
                "metric": metric,
                "median": float(np.median(finite)) if finite.size else math.nan,
                "min": float(finite.min()) if finite.size else math.nan,
                "max": float(finite.max()) if finite.size else math.nan,
                "spread": spread(v),
                "n": int(v.size),
                "n_missing": int(v.size - finite.size),
            }
        )
    return rows


def _evaluate(
    mod: Modulator,
    name: str,
    ctrl: Any,
    params: ValveParams,
    levels: list[float],
    c: Mapping[str, Any],
    hold: float,
) -> tuple[list[dict[str, Any]], list[pd.DataFrame], pd.DataFrame]:
    """One setting and controller: table rows, per-step rows and the Fig. 10 trace."""
    dt = float(c["dt"])
    loop = LoopUnderTest(mod, ctrl, params)
    run, stair = run_staircase(loop, Staircase(levels, hold, dt))
    step_set = run_steps(loop, Staircase(levels, float(c["step_hold"]), dt))
    _, sine = run_sine(loop, sine_within(c["sine"], min(levels), max(levels)), dt)
    base = {"modulator": mod.label, "description": mod.description, "controller": name}
    rows: list[dict[str, Any]] = []
    step_rows = []
    for experiment, frame in (("staircase", stair), ("steps", step_set)):
        measured = frame.assign(end_error=end_error(frame))
        for row in _summary(measured, (*STEP_METRICS, "end_error")):
            rows.append({**base, "experiment": experiment, **row})
        step_rows.append(frame.assign(experiment=experiment, **base))
    for metric, value in sine.items():
        rows.append(
            {
                **base,
                "experiment": "sine",
                "metric": metric,
                **dict.fromkeys(("median", "min", "max"), value),
                "spread": 0.0,
                "n": 1,
                "n_missing": int(not math.isfinite(value)),
            }
        )
    k = int(c["figure_decimate"])
    period = cycle_period(mod, params, float(np.median(levels)), dt)
    pm = cycle_mean(run["p"].to_numpy(), max(round(period / dt), 1))
    trace = pd.DataFrame(
        {
            "modulator": mod.label,
            "controller": name,
            "t": run["t"].to_numpy()[::k],
            "r": run["r"].to_numpy()[::k],
            "p_mean": pm[::k],
        }
    )
    return rows, step_rows, trace


def setting_levels(
    mods: list[Modulator], params: ValveParams, c: Mapping[str, Any]
) -> tuple[dict[str, list[float]], dict[str, str], dict[str, Any]]:
    """The set-points each setting is checked on, the settings that hold none, and the
    ranges (:mod:`spa.closedloop.levels`).

    Returns
    -------
    levels : dict
        Label -> set-points, bar: the common ones (:func:`~spa.closedloop.levels.common_levels`)
        for the settings that hold them, each other setting's own
        (:func:`~spa.closedloop.design.operating_levels`).
    skipped : dict
        Label -> why it holds none.
    info : dict
        ``wanted`` (bar), ``common`` (bar), ``group`` (labels compared on them) and
        ``held`` (label -> ``[lo, hi]`` bar it holds).
    """
    maxf = float(c["max_level_fraction"])
    wanted = wanted_levels(c.get("levels"), c.get("levels_fraction"), params.k2)
    ranges = {m.label: held_range(m, params, maxf) for m in mods}
    common, group = common_levels(wanted, ranges)
    levels: dict[str, list[float]] = {}
    skipped: dict[str, str] = {}
    for mod in mods:
        if mod.label in group and len(common) >= 2:
            levels[mod.label] = list(common)
            continue
        own, why = operating_levels(wanted, mod, params, maxf, spread=True)
        if why is not None:
            skipped[mod.label] = why
        else:
            levels[mod.label] = own
    info = {
        "wanted": wanted,
        "common": list(common),
        "group": [g for g in group if g in levels],
        "held": {k: [float(v[0]), float(v[1])] for k, v in ranges.items() if v is not None},
    }
    return levels, skipped, info


def _design_all(
    mods: list[Modulator],
    params: ValveParams,
    c: Mapping[str, Any],
    tau_c: float,
    levels_of: Mapping[str, list[float]],
    skipped_before: Mapping[str, str],
) -> tuple[list[dict[str, Any]], list[pd.DataFrame], list[pd.DataFrame], dict[str, Any], dict]:
    """Design and evaluate every setting at one ``tau_c``; settings that cannot be designed
    are returned in ``skipped`` with their reason."""
    rows: list[dict[str, Any]] = []
    step_rows: list[pd.DataFrame] = []
    traces: list[pd.DataFrame] = []
    gains: dict[str, Any] = {}
    skipped: dict[str, str] = dict(skipped_before)
    for mod in mods:
        if mod.label not in levels_of:
            continue
        levels = levels_of[mod.label]
        try:
            hold = level_hold(mod, params, levels, tau_c, c)
            designs = design_pi(mod, params, levels=levels, tau_c=tau_c)
            done = [
                _evaluate(mod, name, ctrl, params, levels, c, hold)
                for name, ctrl in designs.items()
            ]
        except ValueError as exc:  # no local model, or no closed-loop law for the setting
            skipped[mod.label] = f"{mod.label}: {exc}" if mod.label not in str(exc) else str(exc)
            continue
        gains[mod.label] = {
            "setting": mod.to_mapping(),
            "levels": levels,
            "hold": hold,
            **{name: ctrl.to_mapping() for name, ctrl in designs.items()},
        }
        for more_rows, more_steps, trace in done:
            rows += more_rows
            step_rows += more_steps
            traces.append(trace)
    return rows, step_rows, traces, gains, skipped


def closed_loop(
    params: ValveParams,
    selected: Iterable[Mapping[str, Any] | Modulator],
    recommendation: Mapping[str, Any] | None = None,
    cfg: Mapping[str, Any] | None = None,
) -> ClosedLoopResult:
    """Design, simulate and measure the closed loop for one valve.

    Parameters
    ----------
    params : ValveParams
        The identified valve.
    selected : iterable of mappings or Modulator
        The settings to close the loop with (the config's ``analytic.selected``).
    recommendation : mapping, optional
        The tuning stage's ``recommendation.yaml``; its recommended setting is added.
    cfg : mapping, optional
        The config's ``closed_loop:`` section (:data:`DEFAULTS` fill what it omits).

    Returns
    -------
    ClosedLoopResult
        A setting that cannot work on the valve, or holds fewer than two of the levels
        (:func:`spa.closedloop.design.operating_levels`), is left out by name with its
        reason (``skipped``); no valve makes this function raise for that.

    Notes
    -----
    The choice (the first of :func:`~spa.closedloop.choice.ranked_choices`) needs a loop
    within ``max_overshoot`` over the staircase.
    When no designed loop meets it at ``tau_c``, every setting is designed again with
    ``tau_c`` lengthened by the factors of :data:`TAU_C_FACTORS` until one does; the tables
    are then those of the lengthened ``tau_c`` and ``controllers.yaml`` says so. When none
    does even then, nothing is chosen and the sentence says so plainly.
    """
    c = {**DEFAULTS, **dict(cfg or {})}
    dt, tau_c = float(c["dt"]), float(c["tau_c"])
    limit = float(c["max_overshoot"])
    mods, rec = _settings(selected, recommendation, params)
    measured = _measured(recommendation)
    levels_of, unheld, info = setting_levels(mods, params, c)
    tried: list[dict[str, Any]] = []
    first = None
    # every loop that ends each level within 2 %, at any tau_c tried: (overshoot, loop, tau_c)
    settled: list[tuple[float, str, str, float]] = []
    for factor in (1.0, *TAU_C_FACTORS):
        used = tau_c * factor
        rows, step_rows, traces, gains, skipped = _design_all(
            mods, params, c, used, levels_of, unheld
        )
        table = pd.DataFrame(rows)
        stairs = _Staircases(table)
        ranked = ranked_choices(table, rec, limit, measured)
        choice = ranked[0] if ranked else None
        met = choice is not None and stairs.meets(*choice, limit)
        settled += [
            (stairs.worst(*loop, "overshoot"), *loop, used)
            for loop in ranked
            if stairs.settled(*loop)
        ]
        tried.append(
            {
                "tau_c": used,
                "least_worst_overshoot": _least_overshoot(table),
                "met": bool(met),
            }
        )
        if first is None:
            first = (used, rows, step_rows, traces, gains, skipped, table, stairs, ranked, choice)
        if met or not gains:
            break
    if not met:
        # Lengthening did not help: report the loops at the requested tau_c, as designed first.
        used, rows, step_rows, traces, gains, skipped, table, stairs, ranked, choice = first
    steps = pd.concat(step_rows, ignore_index=True) if step_rows else pd.DataFrame()
    controllers: dict[str, Any] = {
        "tau_c": used,
        "tau_c_requested": tau_c,
        "dt": dt,
        "levels": info["common"],
        "levels_wanted": info["wanted"],
        "compared_on_common_levels": info["group"],
        "held_range": info["held"],
        "max_overshoot": limit,
        "rule": "SIMC: Kp = tau/(K*(tau_c + theta)), Ki = Kp/min(tau, 4*(tau_c + theta))",
        "controllers": gains,
        "skipped": skipped,
    }
    if len(tried) > 1:
        controllers["tau_c_tried"] = tried
    if met:
        controllers["setting"] = gains[choice[0]]["setting"]
        controllers["controller"] = choice[1]
        controllers["meeting"] = [
            [label, name] for label, name in ranked if stairs.meets(label, name, limit)
        ]
        # every designed loop, best first: the promise tries the verifiable ones that do not
        # meet the design at this tau_c too (the box lengthens tau_c for them)
        controllers["ranked"] = [[label, name] for label, name in ranked]
        sentence = closed_loop_sentence(table, gains, *choice)
        held = info["held"].get(choice[0])
        if held is not None:
            sentence += " " + held_clause(
                gains[choice[0]]["setting"], params, held, float(c["max_level_fraction"])
            )
        if used != tau_c:
            sentence += (
                f" No loop kept the overshoot within {limit:.3g} % at tau_c = {tau_c:g} s, so "
                f"tau_c was lengthened to {used:g} s."
            )
        controllers["sentence"] = sentence
    elif choice is not None and not settled:
        controllers["sentence"] = unsettled_sentence(stairs, ranked, tau_c, tried[-1]["tau_c"])
    elif choice is not None:
        over, label, name, at = min(settled, key=lambda s: (not math.isfinite(s[0]), s[0]))
        longest = tried[-1]["tau_c"]
        controllers["sentence"] = (
            f"Closed loop: no designed controller keeps the overshoot within {limit:.3g} % "
            "with every level settled within 2 % on "
            f"this valve, even with tau_c lengthened to {longest:g} s; of the loops that "
            f"settle, the least overshoot is {over:.0f} % ({label}, {name} PI at "
            f"tau_c = {at:g} s). None is recommended: widen closed_loop.max_overshoot or "
            "design the loop by hand."
        )
    else:
        controllers["sentence"] = (
            "Closed loop: no modulator setting could be designed for this valve"
            + (f" ({'; '.join(skipped.values())})." if skipped else ".")
        )
    return ClosedLoopResult(
        table,
        steps,
        pd.concat(traces, ignore_index=True) if traces else pd.DataFrame(),
        controllers,
        skipped,
    )


def write_controllers(result: ClosedLoopResult, path: str | Path) -> None:
    """Write ``controllers.yaml`` (plain floats and lists, key order kept)."""
    with open(path, "w", encoding="utf-8") as fh:
        dump_yaml(result.controllers, fh, sort_keys=False, allow_unicode=True)


def unsettled_sentence(
    stairs: _Staircases, ranked: list[tuple[str, str]], tau_c: float, longest: float
) -> str:
    """The stage's sentence when no designed loop ends every level of the staircase within
    2 % of its step at any ``tau_c`` tried: the loop that comes closest at ``tau_c`` (its
    worst end error and its ripple), and that a wider ``max_overshoot`` would not help.

    Examples
    --------
    >>> t = pd.DataFrame({"experiment": "staircase", "modulator": "pwm-20Hz",
    ...                   "controller": "fixed", "metric": ["end_error", "ripple_pp"],
    ...                   "max": [3.5, 0.9], "n_missing": 0})
    >>> said = unsettled_sentence(_Staircases(t), [("pwm-20Hz", "fixed")], 0.2, 1.6)
    >>> said[said.index("; the closest"):]  # doctest: +NORMALIZE_WHITESPACE
    '; the closest, pwm-20Hz (fixed PI at tau_c = 0.2 s), still ends one level 3.5 % of its
    step away, with a ripple of 0.9 bar peak to peak. None is recommended: a wider
    closed_loop.max_overshoot would not change that; design the loop by hand.'
    """
    end = {loop: stairs.worst(*loop, "end_error") for loop in ranked}
    closest = min(ranked, key=lambda loop: (not math.isfinite(end[loop]), end[loop]))
    ripple = stairs.worst(*closest, "ripple_pp")
    worst = f"{end[closest]:.1f} %" if math.isfinite(end[closest]) else "an unknown share"
    ripple_text = ""
    if math.isfinite(ripple):
        ripple_text = f", with a ripple of {ripple:.3g} bar peak to peak"
    return (
        f"Closed loop: no designed controller ends every level within {SETTLED:g} % of its "
        f"step on this valve, even with tau_c lengthened to {longest:g} s (the mean pressure "
        f"over the last quarter of each step); the closest, {closest[0]} ({closest[1]} PI at "
        f"tau_c = {tau_c:g} s), still ends one level {worst} of its step away{ripple_text}. "
        "None is recommended: a wider closed_loop.max_overshoot would not change that; design "
        "the loop by hand."
    )
