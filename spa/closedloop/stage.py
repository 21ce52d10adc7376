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

from spa.closedloop.design import DEFAULT_TAU_C, design_pi, operating_levels
from spa.closedloop.experiments import (
    cycle_period,
    run_sine,
    run_staircase,
    run_steps,
    sine_within,
    spread,
)
from spa.closedloop.levels import common_levels, held_range, idle_duty, wanted_levels
from spa.closedloop.metrics import STEP_METRICS, cycle_mean
from spa.io import dump_yaml
from spa.model.modulators import Modulator
from spa.model.params import ValveParams

__all__ = [
    "CONTROLLERS",
    "ClosedLoopResult",
    "closed_loop",
    "closed_loop_sentence",
    "recorded_runs",
    "write_controllers",
]

#: The controllers designed for every setting, in the order of the tables.
CONTROLLERS = ("fixed", "scheduled", "scheduled_ff")

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
}


def transit_time(levels: list[float], params: ValveParams) -> float:
    """The longest time the valve takes between adjacent levels of the staircase held fully
    open (up: ``tau2*ln((k2 - a)/(k2 - b))``, Eq. A2) or fully exhausting (down:
    ``2*c1*(sqrt(b) - sqrt(a))``, Eq. A1), s: the part of a large step no controller can
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
    with np.errstate(divide="ignore", invalid="ignore"):
        up = params.tau2 * np.log((params.k2 - a) / np.maximum(params.k2 - b, 1e-12))
    down = 2.0 * params.c1 * (np.sqrt(b) - np.sqrt(a))
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
    from spa.closedloop.design import local_models

    m = local_models(levels, mod, params)
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
    run, stair = run_staircase(mod, ctrl, params, levels, hold, dt)
    step_set = run_steps(mod, ctrl, params, levels, float(c["step_hold"]), dt)
    _, sine = run_sine(mod, ctrl, params, sine_within(c["sine"], min(levels), max(levels)), dt)
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
    The choice (:func:`_choice`) needs a loop within ``max_overshoot`` over the staircase.
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
    for factor in (1.0, *TAU_C_FACTORS):
        used = tau_c * factor
        rows, step_rows, traces, gains, skipped = _design_all(
            mods, params, c, used, levels_of, unheld
        )
        table = pd.DataFrame(rows)
        choice = _choice(table, rec, limit, measured)
        met = choice is not None and _meets(table, *choice, limit)
        tried.append(
            {
                "tau_c": used,
                "least_worst_overshoot": _least_overshoot(table),
                "met": bool(met),
            }
        )
        if first is None:
            first = (used, rows, step_rows, traces, gains, skipped, table, choice)
        if met or not gains:
            break
    if not met:
        # Lengthening did not help: report the loops at the requested tau_c, as designed first.
        used, rows, step_rows, traces, gains, skipped, table, choice = first
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
    elif choice is not None:
        over = _worst(table, *choice, "overshoot")
        longest = tried[-1]["tau_c"]
        controllers["sentence"] = (
            f"Closed loop: no designed controller keeps the overshoot within {limit:.3g} % "
            "with every level settled within 2 % on "
            f"this valve, even with tau_c lengthened to {longest:g} s; the least is "
            f"{over:.0f} % ({choice[0]}, {choice[1]} PI at "
            f"tau_c = {tau_c:g} s). None is recommended: widen closed_loop.max_overshoot or "
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


#: Worst-case overshoot (%) over the staircase that a chosen loop may have (default of the
#: config's ``closed_loop.max_overshoot``).
MAX_OVERSHOOT = 10.0

#: Factors by which ``tau_c`` is lengthened, in turn, when no loop meets ``max_overshoot``.
TAU_C_FACTORS = (2.0, 4.0, 8.0)


def _least_overshoot(table: pd.DataFrame) -> float | None:
    if table.empty:
        return None
    sel = table[(table.experiment == "staircase") & (table.metric == "overshoot")]
    values = sel["max"].to_numpy(np.float64)
    values = values[np.isfinite(values)]
    return float(values.min()) if values.size else None


def _worst(table: pd.DataFrame, label: str, controller: str, metric: str) -> float:
    sel = table[
        (table.modulator == label)
        & (table.controller == controller)
        & (table.experiment == "staircase")
        & (table.metric == metric)
    ]
    return float(sel["max"].iloc[0]) if len(sel) else math.nan


#: A step is settled when its mean pressure over the last quarter of the step is within
#: this share of the step, %.
SETTLED = 2.0


def end_error(steps: pd.DataFrame) -> np.ndarray:
    """Each step's steady-state error in % of its size: ``100*|sse|/|r1 - r0|``.

    Examples
    --------
    >>> e = end_error(pd.DataFrame({"r0": [0.1, 0.4], "r1": [0.4, 0.1],
    ...                             "steady_state_error": [0.003, -0.0015]}))
    >>> e.round(9).tolist()
    [1.0, 0.5]
    """
    size = np.abs(steps["r1"].to_numpy(np.float64) - steps["r0"].to_numpy(np.float64))
    sse = np.abs(steps["steady_state_error"].to_numpy(np.float64))
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(size > 0.0, 100.0 * sse / size, np.nan)


def _settled(table: pd.DataFrame, label: str, controller: str) -> bool:
    """Every staircase step of the loop ends within :data:`SETTLED` % of its size (the mean
    pressure over the last quarter of the step, as a bench measures it)."""
    sel = table[
        (table.modulator == label)
        & (table.controller == controller)
        & (table.experiment == "staircase")
        & (table.metric == "end_error")
    ]
    if not len(sel) or int(sel["n_missing"].iloc[0]) != 0:
        return False
    return bool(float(sel["max"].iloc[0]) <= SETTLED)


def _meets(table: pd.DataFrame, label: str, controller: str, limit: float) -> bool:
    """The loop overshoots at most ``limit`` % over the staircase AND every step ends within
    2 % of its size (:func:`_settled`): a longer ``tau_c`` that trades overshoot for a loop
    that never settles does not meet."""
    over = _worst(table, label, controller, "overshoot")
    return bool(math.isfinite(over) and over <= limit and _settled(table, label, controller))


def _measured(recommendation: Mapping[str, Any] | None) -> frozenset[str] | None:
    """The modulator types a loop can be verified with: run on this bench and described by
    the model there (the recommendation's ``adequacy``,
    :meth:`spa.identification.adequacy.Adequacy.modulator_adequate`); None when not assessed.

    Examples
    --------
    >>> sorted(_measured({"adequacy": {"measured_modulators": ["pwm", "dsm"]}}))
    ['dsm', 'pwm']
    >>> _measured({}) is None
    True
    """
    from spa.identification.adequacy import Adequacy

    adequacy = (recommendation or {}).get("adequacy")
    kinds = adequacy.get("measured_modulators") if isinstance(adequacy, Mapping) else None
    if not kinds:
        return None
    a = Adequacy.from_mapping(adequacy)
    return frozenset(str(k) for k in kinds if a.modulator_adequate(str(k)))


def _choice(
    table: pd.DataFrame,
    rec: Modulator | None,
    limit: float = 10.0,
    measured: frozenset[str] | None = None,
) -> tuple[str, str] | None:
    """The setting and controller to use: over every designed setting and controller, the
    smallest worst-case rise time among those overshooting at most ``limit`` % over the
    staircase with every step settled (:func:`_meets`); else, among those that settle, the
    smallest worst-case overshoot; else the smallest worst-case overshoot. Ties go to the
    tuning's recommended setting, then to the order of the table. When ``measured`` (the
    modulator types run on this bench and described there by the model, :func:`_measured`)
    is given, a loop of such a modulator goes before one of another, among those that meet
    the design: only such a loop can be verified.

    The open-loop recommendation ranks linearity; a loop also needs speed without overshoot,
    so the closed loop chooses on its own metrics (its sentence names the setting).
    """
    if table.empty:
        return None
    designed = list(dict.fromkeys(table.modulator))
    recommended = rec.label if rec is not None else None
    scores = []
    for order, label in enumerate(designed):
        for name in CONTROLLERS:
            rise = _worst(table, label, name, "rise_time")
            over = _worst(table, label, name, "overshoot")
            if not (math.isfinite(rise) and math.isfinite(over)):
                continue
            ok = _meets(table, label, name, limit)
            settled = _settled(table, label, name)
            key = rise if ok else over
            kind = label.split("-", 1)[0]  # Modulator.label: "<type>-<setting>"
            unmeasured = measured is not None and kind not in measured
            scores.append(
                (not ok, not settled, unmeasured, key, label != recommended, order, label, name)
            )
    if not scores:
        return None
    best = min(scores)
    return best[6], best[7]


def closed_loop_sentence(
    table: pd.DataFrame, gains: Mapping[str, Any], label: str, controller: str
) -> str:
    """The recommendation: ``use <setting> with the <controller> PI (Kp, Ki): rise <= ...``."""
    g = gains[label][controller]
    desc = table.loc[table.modulator == label, "description"].iloc[0]

    def fmt(v: Any) -> str:
        if isinstance(v, list):
            return f"{min(v):.3g}–{max(v):.3g}"
        return f"{v:.3g}"

    kind = {"fixed": "fixed", "scheduled": "gain-scheduled", "scheduled_ff": "gain-scheduled"}
    ff = " with the averaged-model feed-forward" if controller == "scheduled_ff" else ""
    rise = _worst(table, label, controller, "rise_time")
    over = _worst(table, label, controller, "overshoot")
    sse = table[
        (table.modulator == label)
        & (table.controller == controller)
        & (table.experiment == "staircase")
        & (table.metric == "steady_state_error")
    ]
    err = max(abs(float(sse["min"].iloc[0])), abs(float(sse["max"].iloc[0])))
    settle = _worst(table, label, controller, "settling_time")
    levels = gains[label].get("levels") or []
    where = f" {min(levels):.3g}–{max(levels):.3g} bar" if levels else ""
    rise_text = (
        f"rise time (10–90 %) ≤ {rise:.2f} s"
        if math.isfinite(rise)
        else "a step that does not reach 90 %"
    )
    settle_text = (
        f", settling (2 %) ≤ {settle:.2f} s" if math.isfinite(settle) else ", a level not settled"
    )
    err_text = f"{err * 1e3:.1f} mbar" if math.isfinite(err) else "unknown"
    return (
        f"Closed loop: use {desc} with the {kind[controller]} PI{ff} "
        f"(Kp = {fmt(g['kp'])} /bar, Ki = {fmt(g['ki'])} /(bar·s), controllers.yaml): over the "
        f"set-point staircase{where}, {rise_text}, overshoot ≤ {over:.0f} %{settle_text} "
        f"and steady-state error ≤ {err_text} in the exact simulation of the identified model."
    )


def held_clause(
    setting: Mapping[str, Any] | Modulator,
    params: ValveParams,
    held: tuple[float, float] | list[float],
    max_fraction: float = 1.0,
) -> str:
    """Which pressures the setting cannot hold on the valve, in one sentence.

    Examples
    --------
    >>> held_clause({"type": "iipfm", "t_l": 0.02, "gain": 1.15}, ValveParams(k2=5.5),
    ...             (1.07, 5.2), 0.95)[:62]
    'It holds 1.07–5.2 bar on this valve and cannot hold below 1.07'
    """
    lo, hi = float(held[0]), float(held[1])
    text = f"It holds {lo:.3g}–{hi:.3g} bar on this valve"
    low = lo > 0.02 * params.k2
    idle = idle_duty(setting, params)
    if low:
        text += f" and cannot hold below {lo:.3g} bar"
        if idle > 0.005:
            text += f" (at ξ = 0 it still opens the valve {idle * 100:.0f} % of the time)"
    if hi < 0.98 * max_fraction * params.k2:
        text += f", nor above {hi:.3g} bar" if low else f" and cannot hold above {hi:.3g} bar"
    return text + "."


#: Columns of ``runs.csv`` (recorded closed-loop runs against their replay).
RUN_COLUMNS = (
    "run",
    "origin",
    "modulator",
    "kp",
    "ki",
    "dt",
    "n_steps",
    "fit",
    "rmse",
    "max_error",
    "rise_time_max",
    "rise_time_max_model",
    "overshoot_max",
    "overshoot_max_model",
    "steady_state_error_max",
    "steady_state_error_max_model",
)


def recorded_runs(
    runs: Mapping[str, pd.DataFrame], metas: Mapping[str, Mapping[str, Any]], params: ValveParams
) -> pd.DataFrame:
    """The dataset's ``closed_loop`` runs: measured metrics and the replay on the model.

    Parameters
    ----------
    runs, metas : mapping
        Run id -> run table and metadata (:func:`spa.datasets.read_runs`); runs of other kinds
        are ignored.
    params : ValveParams
        The identified valve.

    Returns
    -------
    pandas.DataFrame
        One row per run, :data:`RUN_COLUMNS`: the recording's worst rise time, overshoot and
        steady-state error over its set-point steps beside the replay's (``*_model``), and
        the replay's FIT %, RMSE and largest error (bar). The replay starts from the recorded
        first pressure with the integrator at 0 (a run that starts from rest).
    """
    from spa.closedloop.controller import PIController
    from spa.closedloop.replay import replay_closed_loop

    rows = []
    for rid, meta in metas.items():
        if meta.get("kind") != "closed_loop":
            continue
        spec = dict(meta["controller"])
        ctrl = PIController.from_mapping(spec)
        res = replay_closed_loop(runs[rid], meta["modulator"], ctrl, params, float(spec["dt"]))
        worst = {}
        for metric in ("rise_time", "overshoot", "steady_state_error"):
            for suffix, frame in (("", res.measured), ("_model", res.predicted)):
                v = frame[metric].abs().to_numpy(np.float64)
                worst[f"{metric}_max{suffix}"] = (
                    float(np.nanmax(v)) if np.isfinite(v).any() else math.nan
                )
        rows.append(
            {
                "run": rid,
                "origin": meta.get("origin", ""),
                "modulator": Modulator.from_mapping(meta["modulator"]).label,
                "kp": fmt_gain(spec["kp"]),
                "ki": fmt_gain(spec.get("ki", 0.0)),
                "dt": float(spec["dt"]),
                "n_steps": len(res.measured),
                "fit": res.fit,
                "rmse": res.rmse,
                "max_error": res.max_error,
                **worst,
            }
        )
    return pd.DataFrame(rows, columns=list(RUN_COLUMNS))


def fmt_gain(value: Any) -> str:
    """A gain or a schedule of gains as text (``4.1`` or ``3.9-4.5``)."""
    if isinstance(value, list | tuple):
        return f"{min(value):.4g}-{max(value):.4g}"
    return f"{float(value):.4g}"


def write_controllers(result: ClosedLoopResult, path: str | Path) -> None:
    """Write ``controllers.yaml`` (plain floats and lists, key order kept)."""
    with open(path, "w", encoding="utf-8") as fh:
        dump_yaml(result.controllers, fh, sort_keys=False, allow_unicode=True)
