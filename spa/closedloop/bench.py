"""What the ``closed_loop`` stage adds for the bench: the chosen controller as C, its worst
case over the identification's box and the disturbances a bench has.

:func:`bench_outputs` takes the stage's result (:func:`spa.closedloop.stage.closed_loop`) and

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

import pandas as pd

from spa.closedloop.controller import PIController
from spa.closedloop.disturbance import DROP, disturbances
from spa.closedloop.export import arduino_sketch, controller_header
from spa.closedloop.robust import robust_design
from spa.closedloop.stage import DEFAULTS, MAX_OVERSHOOT, ClosedLoopResult
from spa.model.modulators import Modulator
from spa.model.params import ValveParams

__all__ = [
    "NOISE_FALLBACK",
    "ROBUST_COLUMNS",
    "BenchOutputs",
    "apply_bench",
    "bench_outputs",
    "sensor_noise",
]

#: The sensor noise assumed when the identification gives none, bar (the simulated bench's).
NOISE_FALLBACK = 0.005

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
    "worst_steady_state_error",
    "worst_ripple_pp",
    "worst_ripple_rms",
    "tau_c_robust",
    "robust_rise_time",
    "robust_overshoot",
)

_NO_DESIGN = '#error "spa: no modulator setting could be designed for this valve"\n'


def sensor_noise(identified: Mapping[str, Any] | None) -> float:
    """The sensor's noise, bar: the pulse fit's residual RMS of ``params.yaml``.

    Parameters
    ----------
    identified : mapping or None
        ``params.yaml``'s content; its ``fits.pulse.rmse`` (sensor noise and what the model
        misses of the pulse runs) is used when positive and finite.

    Returns
    -------
    float
        That RMS, else :data:`NOISE_FALLBACK`.

    Examples
    --------
    >>> sensor_noise({"fits": {"pulse": {"rmse": 0.0061}}}), sensor_noise(None)
    (0.0061, 0.005)
    """
    try:
        value = float(identified["fits"]["pulse"]["rmse"])  # type: ignore[index]
    except (KeyError, TypeError, ValueError):
        return NOISE_FALLBACK
    return value if math.isfinite(value) and value > 0.0 else NOISE_FALLBACK


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
    """

    robust: pd.DataFrame
    header: str
    sketch: str
    summary: dict[str, Any] = field(default_factory=dict)
    sentence: str = ""


def _chosen(controllers: Mapping[str, Any]) -> tuple[str, str] | None:
    setting, name = controllers.get("setting"), controllers.get("controller")
    if not setting or not name:
        return None
    return Modulator.from_mapping(setting).label, str(name)


def bench_outputs(
    result: ClosedLoopResult,
    params: ValveParams,
    intervals: Mapping[str, tuple[float, float]] | None,
    cfg: Mapping[str, Any] | None = None,
    noise: float = NOISE_FALLBACK,
) -> BenchOutputs:
    """The header of the chosen loop, its worst case over the box, and the disturbances.

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
    noise : float, optional
        The sensor's noise, bar (:func:`sensor_noise`).

    Returns
    -------
    BenchOutputs
    """
    c = {**DEFAULTS, **dict(cfg or {})}
    ctl = result.controllers
    dt, hold = float(ctl.get("dt", c["dt"])), float(c["hold"])
    levels = [float(v) for v in ctl.get("levels", [])]
    limit = float(ctl.get("max_overshoot", c.get("max_overshoot", MAX_OVERSHOOT)))
    chosen = _chosen(ctl)
    rows: list[dict[str, Any]] = []
    if chosen is None:
        return BenchOutputs(pd.DataFrame(columns=list(ROBUST_COLUMNS)), _NO_DESIGN, _NO_DESIGN)
    label, name = chosen
    for mod_label, designs in ctl["controllers"].items():
        mod = Modulator.from_mapping(designs["setting"])
        ctrl = PIController.from_mapping(designs[name])
        own = [float(v) for v in designs.get("levels", levels)]  # the levels it holds
        d = disturbances(mod, ctrl, params, own, hold, dt, noise, seed=NOISE_SEED)
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
    mod = Modulator.from_mapping(ctl["controllers"][label]["setting"])
    tau_c = float(ctl.get("tau_c", c["tau_c"]))
    rd = robust_design(
        mod,
        name,
        params,
        intervals,
        levels=[float(v) for v in ctl["controllers"][label].get("levels", levels)],
        hold=hold,
        dt=dt,
        tau_c=tau_c,
        limit=limit,
    )
    box = {
        "n_corners": rd.n_corners,
        "tau_c": rd.tau_c,
        **{f"worst_{k}": v for k, v in rd.worst.items()},
        "tau_c_robust": math.nan if rd.tau_c_robust is None else rd.tau_c_robust,
        "robust_rise_time": rd.worst_robust.get("rise_time", math.nan),
        "robust_overshoot": rd.worst_robust.get("overshoot", math.nan),
    }
    for row in rows:
        row.update(box if row["chosen"] else dict.fromkeys(box, math.nan))
    chosen_row = next(r for r in rows if r["chosen"])
    summary = {k: chosen_row[k] for k in ROBUST_COLUMNS[4:]}
    summary["tau_c_tried"] = [[t, o] for t, o in rd.tried]
    summary["max_overshoot"] = limit
    ctrl = PIController.from_mapping(ctl["controllers"][label][name])
    note = (
        f"The closed_loop stage's choice (controllers.yaml), tau_c = {tau_c:g} s; worst "
        f"overshoot over the 95 % box {rd.worst['overshoot']:.1f} % ({rd.n_corners} corners)."
    )
    header = controller_header(
        mod, ctrl, dt, note=note, precision=str(c.get("precision", "double"))
    )
    return BenchOutputs(
        pd.DataFrame(rows, columns=list(ROBUST_COLUMNS)),
        header,
        arduino_sketch(),
        _plain(summary),
        bench_sentence(summary),
    )


def _plain(summary: dict[str, Any]) -> dict[str, Any]:
    """Plain floats (YAML-ready), NaN as None."""

    def one(v: Any) -> Any:
        if isinstance(v, list):
            return [one(x) for x in v]
        if isinstance(v, bool):
            return v
        if isinstance(v, int | float):
            f = float(v)
            return None if math.isnan(f) else (int(v) if isinstance(v, int) else f)
        return v

    return {k: one(v) for k, v in summary.items()}


def bench_sentence(summary: Mapping[str, Any]) -> str:
    """The chosen loop over the box and under the disturbances, in one sentence.

    Examples
    --------
    >>> bench_sentence({"n_corners": 32, "tau_c": 0.2, "worst_rise_time": 0.9,
    ...   "worst_overshoot": 14.0, "tau_c_robust": 0.3, "drop_level": 0.35,
    ...   "recovery_time": 0.4, "dip": 0.01, "noise": 0.005, "added_ripple_rms": 0.002})[:60]
    "Over the identification's 95 % box (32 corners) its worst ri"
    """

    def num(key: str) -> float:
        v = summary.get(key)
        return math.nan if v is None else float(v)

    over, robust = num("worst_overshoot"), num("tau_c_robust")
    limit = num("max_overshoot") if summary.get("max_overshoot") is not None else MAX_OVERSHOOT
    text = (
        f"Over the identification's 95 % box ({int(num('n_corners'))} corners) its worst rise "
        f"time is {num('worst_rise_time'):.2f} s and overshoot {over:.0f} %"
    )
    if over <= limit:
        text += f", within the {limit:.3g} % limit"
    elif math.isfinite(robust):
        text += f"; τ_c = {robust:.3g} s (robust τ_c) keeps it within {limit:.3g} %"
    else:
        text += f"; no longer τ_c tried keeps it within {limit:.3g} %"
    rec = num("recovery_time")
    if math.isnan(rec):
        back = "is not back within 2 % before the level ends"
    elif rec == 0.0:
        back = "stays within 2 % of the undisturbed run"
    else:
        back = f"is back within 2 % after {rec:.2f} s"
    return (
        f"{text}. After a {DROP * 100:.0f} % supply drop at {num('drop_level'):.2f} bar the "
        f"pressure dips {num('dip') * 1e3:.0f} mbar and {back}; sensor noise of "
        f"{num('noise') * 1e3:.1f} mbar adds {num('added_ripple_rms') * 1e3:.2f} mbar RMS "
        "ripple. The C header is closed_loop/controller.h."
    )


#: ``robust.csv`` columns as rows of ``table.csv``: experiment -> (column, metric) pairs.
TABLE_ROWS: dict[str, tuple[tuple[str, str], ...]] = {
    "box_95": (
        ("worst_rise_time", "rise_time"),
        ("worst_overshoot", "overshoot"),
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
    """Add the bench numbers to ``controllers.yaml`` (key ``bench``), its sentence and
    ``table.csv`` (:func:`table_rows`: the box's worst case and the disturbances)."""
    if not bench.summary:
        return
    result.controllers["bench"] = bench.summary
    result.controllers["sentence"] = f"{result.controllers['sentence']} {bench.sentence}"
    extra = table_rows(bench.robust)
    if not extra.empty:
        result.table = pd.concat([result.table, extra], ignore_index=True)
