"""What the ``closed_loop`` stage adds for the bench: the chosen controller as C, its worst
case over the identification's box and the disturbances a bench has.

:func:`bench_outputs` takes the stage's result (:func:`spa.closedloop.comparison.closed_loop`) and

* writes the chosen setting and controller as a C99 header and an Arduino-style sketch
  (:mod:`spa.closedloop.export`);
* evaluates the chosen controller with the plant at the corners of the 95 % box and finds
  the robust ``tau_c`` (:func:`spa.closedloop.robust.robust_design`);
* runs, for every designed setting with the chosen kind of controller, the staircase with a
  10 % supply drop and with the sensor's noise (:mod:`spa.closedloop.disturbance`).

The numbers go to ``robust.csv`` (one row per setting, :data:`ROBUST_COLUMNS`; table.csv
keeps its shape) and, for the chosen one, to ``controllers.yaml`` (key ``bench``) and one
more sentence of the recommendation (:func:`apply_bench`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pandas as pd

from spa.closedloop.bench_text import bench_sentence, laws_envelope
from spa.closedloop.box import PromiseBox, box_hold, box_levels, promise_levels, three_levels
from spa.closedloop.choice import MAX_OVERSHOOT
from spa.closedloop.comparison import DEFAULTS, ClosedLoopResult
from spa.closedloop.controller import PIController
from spa.closedloop.delays import unresolved_sentence
from spa.closedloop.disturbance import disturbances
from spa.closedloop.experiments import LoopUnderTest, Staircase
from spa.closedloop.export import arduino_sketch, controller_header
from spa.closedloop.noise import NOISE_FALLBACK, SensorNoise, sensor_noise
from spa.closedloop.pulses import RecordedPulses, loop_pulses, pulse_clause
from spa.closedloop.robust import robust_design
from spa.closedloop.shipped import ShippedLoop, ship_lengthened, shipped_loop
from spa.model.modulators import Modulator
from spa.model.params import ValveParams

__all__ = [
    "NOISE_FALLBACK",
    "ROBUST_COLUMNS",
    "BenchOutputs",
    "SensorNoise",
    "apply_bench",
    "bench_outputs",
    "sensor_noise",
]

#: Seed of the sensor noise of the disturbance runs.
NOISE_SEED = 0

#: Columns of ``robust.csv``.
ROBUST_COLUMNS = (
    "modulator",
    "description",
    "controller",
    "chosen",
    "drop_level",
    "recovery_time",
    "dip",
    "steady_state_error_after_drop",
    "noise",
    "added_ripple_rms",
    "added_ripple_pp",
    "n_corners",
    "tau_c",
    "worst_rise_time",
    "worst_overshoot",
    "worst_settling_time",
    "worst_steady_state_error",
    "worst_ripple_pp",
    "worst_ripple_rms",
    "tau_c_robust",
    "robust_rise_time",
    "robust_overshoot",
)

_NO_DESIGN = '#error "spa: no modulator setting could be designed for this valve"\n'


@dataclass
class BenchOutputs:
    """What :func:`bench_outputs` gives.

    Attributes
    ----------
    robust : pandas.DataFrame
        ``robust.csv``, :data:`ROBUST_COLUMNS`.
    header, sketch : str
        ``controller.h`` and ``controller.ino`` (an ``#error`` when nothing was designed).
    summary : dict
        The chosen loop's numbers for ``controllers.yaml`` (empty when nothing was chosen).
    sentence : str
        One sentence for the recommendation (empty when nothing was chosen).
    shipped : ShippedLoop or None
        The loop the header ships, evaluated as the stage evaluates its designs, when the
        promise lengthened ``tau_c`` past the stage's (None when the header ships the stage's
        own design): :func:`apply_bench` makes ``controllers.yaml``, the sentence and the
        tables name it.
    """

    robust: pd.DataFrame
    header: str
    sketch: str
    summary: dict[str, Any] = field(default_factory=dict)
    sentence: str = ""
    shipped: ShippedLoop | None = None


def _chosen(controllers: Mapping[str, Any]) -> tuple[str, str] | None:
    setting, name = controllers.get("setting"), controllers.get("controller")
    if not setting or not name:
        return None
    return Modulator.from_mapping(setting).label, str(name)


def adequacy_of(identified: Mapping[str, Any] | None) -> dict[str, Any] | None:
    """``params.yaml``'s ``adequacy`` mapping, or None when the identification did not
    assess it."""
    found = (identified or {}).get("adequacy")
    return dict(found) if isinstance(found, Mapping) else None


def adequacy_clause(adequacy: Mapping[str, Any] | None, modulator_type: str) -> str:
    """The plain clause for an inadequate model or an unmeasured modulator ("" when the model
    is adequate and the modulator was run on the bench; "adequacy not assessed" when
    ``params.yaml`` has no ``adequacy``).

    Uses :func:`spa.identification.adequacy.adequacy_clause` when that module is installed,
    else the same wording from the mapping's ``adequate``, ``worst_run`` and
    ``measured_modulators``.

    Examples
    --------
    >>> adequacy_clause(None, "pwm")
    'adequacy not assessed'
    >>> adequacy_clause({"adequate": True, "measured_modulators": ["dsm"]}, "pwm")
    'not measured with this modulator on this bench'
    """
    if adequacy is None:
        return "adequacy not assessed"
    try:
        from spa.identification.adequacy import Adequacy
        from spa.identification.adequacy import adequacy_clause as clause
    except ImportError:
        pass
    else:
        try:
            return str(clause(Adequacy.from_mapping(adequacy), modulator_type))
        except (KeyError, TypeError, ValueError):
            pass
    parts = []
    if not bool(adequacy.get("adequate", True)):
        worst = adequacy.get("worst_run") or {}
        fit = worst.get("fit") if isinstance(worst, Mapping) else None
        where = ""
        if fit is not None and math.isfinite(float(fit)):
            where = f" (held-out FIT {float(fit):.0f} % on run {worst.get('run', '?')})"
        parts.append(f"the model does not describe this valve well enough{where}")
    measured = adequacy.get("measured_modulators")
    if isinstance(measured, list) and modulator_type not in measured:
        parts.append("not measured with this modulator on this bench")
    return "; ".join(parts)


def _margins(
    mod: Modulator, ctrl: PIController, params: ValveParams, levels: list[float]
) -> tuple[float, float]:
    """The smallest gain margin and delay margin (s) over the levels
    (:func:`spa.closedloop.margins.loop_margins` on the averaged model at each level)."""
    from spa.closedloop.controller import interp
    from spa.closedloop.design import _local_models
    from spa.closedloop.margins import loop_margins

    m = _local_models(levels, mod, params)
    grid, kp, ki, _, _ = ctrl.arrays()
    gms, dms = [], []
    for r, k, tau, theta in zip(m.r, m.gain, m.tau, m.dead_time, strict=True):
        g, d = loop_margins(
            float(k),
            float(tau),
            float(theta),
            interp(float(r), grid, kp),
            interp(float(r), grid, ki),
        )
        gms.append(g)
        dms.append(d)
    return float(min(gms)), float(min(dms))


def bench_outputs(
    result: ClosedLoopResult,
    params: ValveParams,
    intervals: Mapping[str, tuple[float, float]] | None,
    cfg: Mapping[str, Any] | None = None,
    noise: float | SensorNoise = NOISE_FALLBACK,
    *,
    model_error: Mapping[str, tuple[float, float]] | None = None,
    adequacy: Mapping[str, Any] | None = None,
    choice: tuple[str, str] | None = None,
    unresolved: Mapping[str, tuple[float, float]] | None = None,
    recorded: RecordedPulses | None = None,
    below: Mapping[str, Any] | None = None,
) -> BenchOutputs:
    """The header of the chosen loop, its promise over the box and the model error, and the
    disturbances.

    Parameters
    ----------
    result : ClosedLoopResult
        The ``closed_loop`` stage's result for ``params``.
    params : ValveParams
        The identified valve (the estimate the PIs were designed at).
    intervals : mapping or None
        The 95 % intervals, ``name -> (lo, hi)``.
    cfg : mapping, optional
        The config's ``closed_loop:`` section, as the stage had it.
    noise : float or SensorNoise, optional
        The sensor's noise, bar (:func:`spa.closedloop.noise.sensor_noise`: measured, an
        upper bound, or unknown and bounded by the model residual; the sentence says which).
    model_error : mapping, optional
        Parameter ranges covering the model error measured on the dataset
        (:func:`spa.closedloop.model_error.error_intervals`); merged with ``intervals``
        (:func:`spa.closedloop.model_error.widen`): the promise is the worst over both.
    adequacy : mapping, optional
        ``params.yaml``'s ``adequacy`` (None: not assessed).
    choice : (str, str), optional
        The (setting label, controller) to check and export instead of the stage's choice
        (one of the designed loops, :func:`spa.closedloop.promise.design_for_dataset`).
    unresolved : mapping, optional
        The delays the data do not resolve, ``name -> (lo, hi)`` s
        (:func:`spa.closedloop.delays.unresolved_delays`): the header's comment and the
        sentence say so, with what to record (:func:`spa.closedloop.delays.unresolved_sentence`).
    recorded : RecordedPulses, optional
        The shortest valve pulses the dataset's runs contain: a shipped loop whose pulses on
        the model are mostly shorter is not verified (:func:`spa.closedloop.pulses.pulse_clause`).
    below : mapping, optional
        ``{"lowest": bar, "laws_envelope": {...}}``: the promise leaves out the set-points
        below ``lowest`` (``intervals`` are then the box over the pressures it visits,
        :func:`spa.closedloop.box.laws_box_above`), and ``laws_envelope`` is the laws'
        envelope over every pressure, for the sentence.

    Returns
    -------
    BenchOutputs

    Notes
    -----
    The promise: the chosen loop is run on the staircase with the plant at the estimate and
    at every corner of the merged box; ``tau_c`` is lengthened (x1.5) until the worst
    overshoot is within ``max_overshoot`` with every step of every corner settled
    (:func:`spa.closedloop.robust.robust_design`), each level held for the transit plus
    five closed-loop time constants of that ``tau_c``. The header ships the loop designed at
    that ``tau_c``; its worst overshoot and settling time are the promise. When no ``tau_c``
    holds, the header ships the stage's loop, the sentence says there is no promise, and
    ``verified`` is false. ``verified`` is also false when the model is inadequate or the
    setting's modulator was not run on this bench, or when the shipped loop's valve pulses
    on the model, over the promise's staircase, are shorter than the bench recorded.
    """
    from spa.closedloop.design import design_pi
    from spa.closedloop.model_error import widen

    c = {**DEFAULTS, **dict(cfg or {})}
    said = noise if isinstance(noise, SensorNoise) else SensorNoise(float(noise))
    noise = said.value
    ctl = result.controllers
    dt = float(ctl.get("dt", c["dt"]))
    levels = [float(v) for v in ctl.get("levels", [])]
    limit = float(ctl.get("max_overshoot", c.get("max_overshoot", MAX_OVERSHOOT)))
    chosen = choice if choice is not None else _chosen(ctl)
    rows: list[dict[str, Any]] = []
    if chosen is None:
        return BenchOutputs(pd.DataFrame(columns=list(ROBUST_COLUMNS)), _NO_DESIGN, _NO_DESIGN)
    label, name = chosen
    for mod_label, designs in ctl["controllers"].items():
        mod = Modulator.from_mapping(designs["setting"])
        ctrl = PIController.from_mapping(designs[name])
        own = [float(v) for v in designs.get("levels", levels)]  # the levels it holds
        hold = float(designs.get("hold", c["hold"] if c["hold"] is not None else 3.0))
        d = disturbances(
            LoopUnderTest(mod, ctrl, params), Staircase(own, hold, dt), noise, seed=NOISE_SEED
        )
        d["steady_state_error_after_drop"] = d.pop("steady_state_error")
        rows.append(
            {
                "modulator": mod_label,
                "description": mod.description,
                "controller": name,
                "chosen": mod_label == label,
                **d,
            }
        )
    entry = ctl["controllers"][label]
    mod = Modulator.from_mapping(entry["setting"])
    own = [float(v) for v in entry.get("levels", levels)]
    tau_c = float(ctl.get("tau_c", c["tau_c"]))
    error = dict(model_error or {})
    gain = error.pop("gain", None)
    gains = (1.0,) if gain is None else (1.0, float(gain[0]), float(gain[1]))
    box = widen(intervals, error)
    # Set-points at most the highest fraction of the estimate's supply the stage asks for
    # (levels_fraction; a corner of lower supply is asked for the same pressures, within
    # its own max_level_fraction), or max_level_fraction when the levels are absolute.
    top = float(c["max_level_fraction"])
    if c.get("levels") is None and c.get("levels_fraction"):
        k2_lo = min(float(box.get("k2", (params.k2, params.k2))[0]), params.k2)
        asked = max(float(v) for v in c["levels_fraction"]) * params.k2 / k2_lo
        top = min(top, asked * 1.005)  # the levels are rounded to 3 significant digits
    plants = PromiseBox(mod, params, box)
    own = box_levels(plants, own, top)
    stairs = promise_levels(own, params.k2, float(c["promise_step_fraction"]))
    if below is not None:
        stairs = three_levels([v for v in stairs if v >= float(below["lowest"]) * (1.0 - 1e-9)])
    rd = robust_design(
        mod,
        name,
        params,
        box,
        levels=stairs,
        schedule=own,
        hold=float(entry.get("hold", 3.0)),
        dt=dt,
        tau_c=tau_c,
        limit=limit,
        hold_of=lambda tau: box_hold(plants, stairs, tau, c, min(gains)),
        gains=gains,
    )
    shipped_tau = rd.tau_c_robust if rd.tau_c_robust is not None else tau_c
    worst = rd.worst_robust if rd.tau_c_robust is not None else rd.worst
    ctrl = (
        PIController.from_mapping(entry[name])
        if shipped_tau == tau_c
        else design_pi(mod, params, levels=own, tau_c=shipped_tau)[name]
    )
    gm, dm = _margins(mod, ctrl, params, own)
    clause = adequacy_clause(adequacy, mod.kind)
    hold_promised = box_hold(plants, stairs, shipped_tau, c, min(gains))
    pulses = pulse_clause(*loop_pulses(mod, ctrl, params, stairs, hold_promised, dt), recorded)
    verified = rd.tau_c_robust is not None and (adequacy is None or clause == "") and not pulses
    clause = "; ".join(x for x in (clause, pulses) if x)
    lengthened = shipped_tau != tau_c
    info = {
        "n_corners": rd.n_corners,
        # the chosen row is the shipped loop's: at the stage's tau_c only when it is shipped
        "tau_c": shipped_tau,
        **{f"worst_{k}": v for k, v in worst.items() if f"worst_{k}" in ROBUST_COLUMNS},
        "tau_c_robust": math.nan if rd.tau_c_robust is None else rd.tau_c_robust,
        "robust_rise_time": rd.worst_robust.get("rise_time", math.nan),
        "robust_overshoot": rd.worst_robust.get("overshoot", math.nan),
    }
    for row in rows:
        row.update(info if row["chosen"] else dict.fromkeys(info, math.nan))
    chosen_row = next(r for r in rows if r["chosen"])
    shipped = None
    if lengthened:
        # the disturbances of the loop the header ships, not of the stage's design
        entry_hold = float(entry.get("hold", c["hold"] if c["hold"] is not None else 3.0))
        own_levels = [float(v) for v in entry.get("levels", levels)]
        d = disturbances(
            LoopUnderTest(mod, ctrl, params),
            Staircase(own_levels, entry_hold, dt),
            noise,
            seed=NOISE_SEED,
        )
        d["steady_state_error_after_drop"] = d.pop("steady_state_error")
        chosen_row.update(d)
        shipped = shipped_loop(mod, name, ctrl, params, own_levels, c, shipped_tau, tau_c)
    summary = {k: chosen_row[k] for k in ROBUST_COLUMNS[4:]}
    if lengthened:
        summary["design"] = {
            "tau_c": tau_c,
            "controller": PIController.from_mapping(entry[name]).to_mapping(),
            **{f"worst_{k}": v for k, v in rd.worst.items() if f"worst_{k}" in ROBUST_COLUMNS},
            "note": (
                f"the {name} PI designed at the stage's tau_c = {tau_c:g} s, shown for "
                "comparison: not shipped (its worst case over the box breaks the promise)"
            ),
        }
    summary["sensor_noise"] = said.to_mapping()
    summary["tau_c_tried"] = [[t, o] for t, o in rd.tried]
    summary["max_overshoot"] = limit
    summary["box"] = {k: [float(v[0]), float(v[1])] for k, v in box.items()}
    envelope = laws_envelope(params, intervals)
    if envelope:
        summary["laws_envelope"] = envelope
    summary["model_error"] = {k: [float(v[0]), float(v[1])] for k, v in (model_error or {}).items()}
    if recorded is not None:
        summary["recorded_pulses"] = recorded.to_mapping()
    if below is not None:
        summary["below"] = {
            "lowest": float(below["lowest"]),
            "laws_envelope": dict(below.get("laws_envelope") or {}),
        }
    summary["promise"] = {
        "kept": rd.tau_c_robust is not None,
        "tau_c": shipped_tau,
        "controller": ctrl.to_mapping(),
        "levels": stairs,
        "hold": hold_promised,
        "overshoot": worst.get("overshoot", math.nan),
        "settling_time": worst.get("settling_time", math.nan),
        "end_error": worst.get("end_error", math.nan),
        "rise_time": worst.get("rise_time", math.nan),
        "ripple_pp": worst.get("ripple_pp", math.nan),
        "steady_state_error": worst.get("steady_state_error", math.nan),
        "plants": "the estimate and every corner of the 95 % box merged with the model error",
    }
    summary["margins"] = {
        "gain_margin": gm,
        "delay_margin": dm,
        "how": (
            "smallest over the levels; the averaged model linearised at each level "
            "(K = dP_eq/dxi, tau_m, theta = (t_on + t_off)/2 + half the pulse period: the "
            "modulator as a gain and a delay) under the shipped PI, at the estimate"
        ),
    }
    settle = worst.get("settling_time", math.nan)
    if rd.tau_c_robust is not None:
        stairs_said = ", ".join(f"{v:.4g}" for v in stairs)
        note = (
            f"The closed_loop stage's choice (controllers.yaml), shipped at tau_c = "
            f"{shipped_tau:g} s; promise over the 95 % box and the measured model error "
            f"({rd.n_corners} corners), staircase {stairs_said} bar up then down, each level held "
            f"{summary['promise']['hold']:.1f} s: overshoot <= {worst['overshoot']:.1f} %, "
            "every level within 2 % of its step by the end of its hold, ripple <= "
            f"{worst['ripple_pp'] * 1e3:.1f} mbar peak-to-peak"
            + (f", settling <= {settle:.2f} s." if math.isfinite(settle) else ".")
        )
    else:
        note = (
            f"The closed_loop stage's choice (controllers.yaml), tau_c = {shipped_tau:g} s; "
            "no promise: no tau_c tried kept the overshoot and settling over the box."
        )
    unresolved_said = unresolved_sentence(unresolved or {})
    if unresolved_said:
        note += " " + unresolved_said
        summary["unresolved_delays"] = {
            "delays": {k: [float(lo), float(hi)] for k, (lo, hi) in (unresolved or {}).items()},
            "sentence": unresolved_said,
        }
    header = controller_header(
        mod, ctrl, dt, note=note, precision=str(c.get("precision", "double")), params=params
    )
    plain = _plain(summary)
    plain["verified"] = bool(verified)
    plain["adequacy"] = dict(adequacy) if adequacy is not None else None
    plain["adequacy_clause"] = clause
    held = (ctl.get("held_range") or {}).get(label)
    mid = float(np.median(own))
    if held:
        mid = min(max(mid, float(held[0])), float(held[1]))
    return BenchOutputs(
        pd.DataFrame(rows, columns=list(ROBUST_COLUMNS)),
        header,
        arduino_sketch(setpoint=float(f"{mid:.3g}")),
        plain,
        bench_sentence(plain),
        shipped,
    )


def _plain(summary: dict[str, Any]) -> dict[str, Any]:
    """Plain floats (YAML-ready), NaN and infinities as None."""

    def one(v: Any) -> Any:
        if isinstance(v, dict):
            return {k: one(x) for k, x in v.items()}
        if isinstance(v, list | tuple):
            return [one(x) for x in v]
        if isinstance(v, bool | np.bool_):
            return bool(v)
        if isinstance(v, int | float | np.integer | np.floating):
            f = float(v)
            return None if not math.isfinite(f) else (int(v) if isinstance(v, int) else f)
        return v

    return {k: one(v) for k, v in summary.items()}


#: ``robust.csv`` columns as rows of ``table.csv``: experiment -> (column, metric) pairs.
TABLE_ROWS: dict[str, tuple[tuple[str, str], ...]] = {
    "box_95": (
        ("worst_rise_time", "rise_time"),
        ("worst_overshoot", "overshoot"),
        ("worst_settling_time", "settling_time"),
        ("worst_steady_state_error", "steady_state_error"),
        ("worst_ripple_pp", "ripple_pp"),
        ("worst_ripple_rms", "ripple_rms"),
        ("tau_c_robust", "tau_c_robust"),
    ),
    "supply_drop": (
        ("recovery_time", "recovery_time"),
        ("dip", "dip"),
        ("steady_state_error_after_drop", "steady_state_error"),
    ),
    "sensor_noise": (
        ("added_ripple_rms", "added_ripple_rms"),
        ("added_ripple_pp", "added_ripple_pp"),
    ),
}


def table_rows(robust: pd.DataFrame) -> pd.DataFrame:
    """``robust.csv`` as rows of ``table.csv`` (one value each: median = min = max).

    Parameters
    ----------
    robust : pandas.DataFrame
        :data:`ROBUST_COLUMNS`, one row per setting.

    Returns
    -------
    pandas.DataFrame
        ``modulator``, ``description``, ``controller``, ``experiment`` (``box_95``: the worst
        case over the 95 % box, chosen loop only; ``supply_drop``; ``sensor_noise``),
        ``metric``, ``median``, ``min``, ``max``, ``spread`` (0), ``n`` (1), ``n_missing``;
        a value that is NaN (not computed for that setting) gives no row.

    Examples
    --------
    >>> rows = table_rows(pd.DataFrame([{"modulator": "pwm-20Hz", "description": "PWM",
    ...     "controller": "fixed", "recovery_time": 0.4, "dip": 0.01}]))
    >>> rows[["experiment", "metric", "median"]].values.tolist()
    [['supply_drop', 'recovery_time', 0.4], ['supply_drop', 'dip', 0.01]]
    """
    out = []
    for _, row in robust.iterrows():
        base = {k: row[k] for k in ("modulator", "description", "controller")}
        for experiment, pairs in TABLE_ROWS.items():
            for column, metric in pairs:
                value = row.get(column, math.nan)
                if value is None or not math.isfinite(float(value)):
                    continue
                out.append(
                    {
                        **base,
                        "experiment": experiment,
                        "metric": metric,
                        **dict.fromkeys(("median", "min", "max"), float(value)),
                        "spread": 0.0,
                        "n": 1,
                        "n_missing": 0,
                    }
                )
    return pd.DataFrame(out)


def apply_bench(result: ClosedLoopResult, bench: BenchOutputs) -> None:
    """Add the bench numbers to ``controllers.yaml`` (key ``bench``; ``verified`` and
    ``adequacy`` also at the top level), its sentence and ``table.csv`` (:func:`table_rows`:
    the box's worst case and the disturbances). When the header ships a loop at a longer
    ``tau_c`` than the stage's (``bench.shipped``), the chosen entry, the sentence and the
    tables name that loop first (:func:`spa.closedloop.shipped.ship_lengthened`)."""
    if not bench.summary:
        return
    if bench.shipped is not None:
        ship_lengthened(result, bench.shipped)
    result.controllers["bench"] = bench.summary
    result.controllers["verified"] = bool(bench.summary.get("verified", False))
    result.controllers["adequacy"] = bench.summary.get("adequacy")
    result.controllers["sentence"] = f"{result.controllers['sentence']} {bench.sentence}"
    extra = table_rows(bench.robust)
    if not extra.empty:
        result.table = pd.concat([result.table, extra], ignore_index=True)
