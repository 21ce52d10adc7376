"""A verification session: the runs that test what spa predicted for a dataset, and the
page that puts each prediction beside its measurement.

:func:`design_verification` plans, on the identified valve, the recommended setting's
staircases and sine (with the identification runs at the start and end as a drift check),
and the closed-loop stage's promise: the chosen controller's staircase (``bench.promise``'s
levels and hold), played by the player through the exported ``controller.h``.
:func:`promise_predictions` states the promise as bands and :func:`compare_promise` measures
a recorded closed-loop staircase against them.
:func:`staircase_predictions` predicts each level's pressure and the staircase's FIT with a
95 % band: the planned command (open loop: the same on any plant) simulated on the
identified valve and at every corner of the identification's 95 % box (:func:`corners`),
widened by the model's error measured on the identification's own recordings
(:mod:`spa.plan.verify_error`) and by the sensor noise on the level's mean.
:func:`compare` measures a recorded staircase the same way and says, for each prediction,
"kept" (inside its band) or "broken by ..." with the amount.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from typing import Any

import numpy as np
import numpy.typing as npt
import pandas as pd

from spa.model.modulators import Modulator
from spa.model.params import ValveParams
from spa.plan.design import SessionDesign, design_session
from spa.plan.limits import Limits
from spa.plan.session import PlannedRun, Segment, run_commands, run_xi

__all__ = [
    "PARTS",
    "closed_loop_runs",
    "compare",
    "compare_promise",
    "compare_sine",
    "corners",
    "design_verification",
    "header_step",
    "level_means",
    "promise_predictions",
    "sine_fit",
    "sine_predictions",
    "staircase_predictions",
    "verdict",
    "verification_frame",
    "verification_page",
]


def design_verification(
    params: ValveParams,
    recommended: Modulator,
    limits: Limits,
    *,
    dt: float = 0.002,
    levels: int = 11,
    replicates: int = 3,
    seed: int = 0,
    promise: Mapping[str, Any] | None = None,
    margin: float = 3.0,
) -> SessionDesign:
    """The verification session: the recommended setting only, on the identified valve;
    with ``promise`` (``controllers.yaml``'s ``bench.promise``), ``replicates`` closed-loop
    staircases of the exported controller (:func:`closed_loop_runs`) before the drift check.

    The drift checks (charge, discharge and pulses at the start and the end) keep a first
    session's margins: sized for valves ``margin`` times slower and faster than the
    identified one, so that the verification's own recordings identify the valve they
    were made on even when it is not the one identified (the case a verification exists
    to catch)."""
    design = design_session(
        params,
        limits,
        dt=dt,
        levels=levels,
        replicates=replicates,
        seed=seed,
        settings=[],
        recommended=recommended.bind(params),
        precondition=1,
        margin=margin,
    )
    if promise is None:
        return design
    loops = closed_loop_runs(promise, dt, replicates)
    runs = list(design.runs)
    end = next((i for i, r in enumerate(runs) if r.block == "end"), len(runs))
    return dataclasses.replace(design, runs=tuple(runs[:end] + loops + runs[end:]))


def closed_loop_runs(promise: Mapping[str, Any], dt: float, replicates: int) -> list[PlannedRun]:
    """The promise's staircase played by the exported controller: one hold at the first
    level (the staircase starts settled, as the closed-loop stage measures it), then the
    levels up and back down, each held the promise's hold.

    Raises
    ------
    ValueError
        When ``promise`` has no levels or hold (``controllers.yaml: bench.promise``).
    """
    try:
        levels = [float(v) for v in promise["levels"]]
        hold = float(promise["hold"])
    except (KeyError, TypeError, ValueError):
        raise ValueError(
            "controllers.yaml: bench.promise has no levels and hold (the closed_loop stage "
            "made no promise to verify)"
        ) from None
    if len(levels) < 2 or not (math.isfinite(hold) and hold >= 2 * dt):
        raise ValueError(f"bench.promise: levels {levels} and hold {hold!r} s make no staircase")
    ticks = max(2, round(hold / dt))
    stairs = [levels[0], *levels, *levels[-2::-1]]
    segs = tuple(Segment(ticks, "loop", v) for v in stairs)
    said = ", ".join(f"{v:.3g}" for v in levels)
    return [
        PlannedRun(
            f"closed-loop_r{r}",
            "closed_loop",
            segs,
            block="closed_loop",
            notes=f"controller.h holds {said} bar up then down, {hold:.3g} s each, after one "
            "hold at the first (not measured)",
            meta={"lead": ticks * dt, "hold": ticks * dt, "levels": levels},
        )
        for r in range(1, replicates + 1)
    ]


def promise_predictions(
    promise: Mapping[str, Any], noise: float, quantum: float, settling_allowance: float = 0.0
) -> dict[str, dict[str, Any]]:
    """The promise as predictions with their 95 % bands.

    The promise is already the worst case over the 95 % box and the model error; the bands
    add what the sensor adds to a log: the overshoot and settling are on the cycle-mean
    pressure (:data:`spa.closedloop.promise.OVERSHOOT_MARGIN` points, one cycle), the
    ripple is the peak-to-peak of the logged pressure, to which the noise adds about
    ``2 x 3.3 noise`` (99.9 % of a normal's spread) and the ADC one step. The settling time
    adds ``settling_allowance`` s, what the sensor's noise in the loop adds to it
    (:func:`spa.plan.settling.settling_allowance`).

    When the stage made no promise (``kept`` false: no ``tau_c`` tried kept the overshoot
    and settling over the box), its worst case over the box is still what it predicts, and
    is what the bands hold; :func:`compare_promise` names such rows "no promise made".

    Returns
    -------
    dict
        ``overshoot`` (%), ``settling_time`` (s, when the worst case settles) and
        ``ripple_pp`` (bar), each ``value``, ``lo``, ``hi`` and ``unit``; only those the
        promise gives a number for.
    """
    from spa.closedloop.promise import OVERSHOOT_MARGIN

    def num(key: str) -> float:
        try:
            return float(promise.get(key))  # type: ignore[arg-type]
        except (TypeError, ValueError):
            return math.nan

    over, settle, ripple = num("overshoot"), num("settling_time"), num("ripple_pp")
    out: dict[str, dict[str, Any]] = {}
    if math.isfinite(over):
        out["overshoot"] = {"value": over, "lo": 0.0, "hi": over + OVERSHOOT_MARGIN, "unit": "%"}
    if math.isfinite(ripple):
        hi = ripple + 6.6 * noise + quantum
        out["ripple_pp"] = {"value": ripple, "lo": 0.0, "hi": hi, "unit": "bar"}
    if math.isfinite(settle):
        hi = settle + max(float(settling_allowance), 0.0)
        out["settling_time"] = {"value": settle, "lo": 0.0, "hi": hi, "unit": "s"}
    return out


def compare_promise(
    prediction: Mapping[str, Any],
    run: pd.DataFrame,
    setting: Mapping[str, Any],
    params: ValveParams,
    lead: float,
    made: bool = True,
) -> pd.DataFrame:
    """A recorded closed-loop staircase (``t``, ``p``, ``r``, ``valve``) against the promise:
    its worst overshoot, settling time and ripple, measured as spa measures its own
    (:func:`spa.synthetic.physical.measure_staircase`), the settling time each step on its
    own samples and past what the sensor adds (:func:`spa.plan.settling.settling_times`),
    each ``kept`` or ``broken by ...``.

    ``prediction``: :func:`promise_predictions`'s; ``setting``: the controller's modulator
    (the cycle-mean's window); ``lead``: the seconds at the first level left out; ``made``:
    whether the stage made the promise (else the rows say "no promise made": the bands are
    its worst case over the box).
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
    # each step on its own samples, its band widened by what the sensor adds to the
    # cycle-mean (spa.plan.settling); an unsettled step has no settling time (inf): the
    # promise's is broken outright
    settle = max(settling_times(run, periods, first, lead), default=0.0)
    measured = {
        "overshoot": summary["worst_overshoot"],
        "settling_time": settle,
        "ripple_pp": summary["worst_ripple_pp"],
    }
    names = {
        "overshoot": ("worst overshoot %", "points", 1.0),
        "settling_time": ("worst settling time s", "s", 1.0),
        "ripple_pp": ("worst ripple bar pp", "mbar", 1e3),
    }
    rows = []
    for key, band in prediction.items():
        label, unit, scale = names[key]
        value = float(measured[key])
        rows.append(
            {
                "prediction": label if made else f"{label} (no promise made)",
                "predicted": float(band["value"]),
                "band": f"{band['lo']:.4g} to {band['hi']:.4g} {band['unit']}",
                "measured": value,
                "verdict": "broken: not settled within 2 % by the end of a level"
                if key == "settling_time" and math.isinf(value)
                else verdict(value, float(band["lo"]), float(band["hi"]), unit, scale),
            }
        )
    return pd.DataFrame(rows)


def header_step(text: str) -> tuple[str, float]:
    """The prefix and step (s) of an exported ``controller.h``.

    Raises
    ------
    ValueError
        When the text is not a spa controller header.

    Examples
    --------
    >>> header_step("#define SPA_CTRL_DT 0.001\\nstatic inline spa_ctrl_output spa_ctrl_step(")
    ('spa_ctrl', 0.001)
    """
    import re

    m = re.search(r"static\s+(?:inline\s+)?(\w+)_output\s+(\w+)_step\s*\(", text)
    if m is None or m.group(1) != m.group(2):
        raise ValueError("not a spa controller header: no '<prefix>_output <prefix>_step(' in it")
    d = re.search(rf"#define\s+{m.group(1).upper()}_DT\s+(\S+)", text)
    if d is None:
        raise ValueError(f"controller header: no {m.group(1).upper()}_DT")
    return m.group(1), float(d.group(1))


def corners(params: ValveParams, intervals: Mapping[str, tuple[float, float]]) -> list[ValveParams]:
    """The valve at every corner of the 95 % box, as the design's box has them
    (:func:`spa.identification.identified.corners`: the valve's own laws kept, the delays
    moved together by their mean and difference); the estimate alone without intervals.

    Before, the corners were rebuilt from the five numbers alone, so a valve with the
    actuator's own laws had paper-law corners around a laws estimate: on phys-choked the
    estimate's level at xi = 0.67 (3.616 bar) lay outside its own band (2.896 to 3.32 bar).
    """
    from spa.identification.identified import corners as box_corners

    return box_corners(params, intervals) or [params]


def level_means(
    t: npt.ArrayLike, p: npt.ArrayLike, hold: float, n_levels: int
) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.int64]]:
    """The mean pressure over the second half of each level (``hold`` s each), and the
    samples each mean is over."""
    t = np.asarray(t, dtype=np.float64)
    p = np.asarray(p, dtype=np.float64)
    means, counts = [], []
    for i in range(n_levels):
        inside = (t >= (i + 0.5) * hold - 1e-9) & (t < (i + 1) * hold - 1e-9)
        counts.append(int(inside.sum()))
        means.append(float(p[inside].mean()) if inside.any() else math.nan)
    return np.asarray(means), np.asarray(counts)


def _fit(xi: np.ndarray, p: np.ndarray) -> float:
    from spa.openloop.levels import linear_fit_metrics

    return float(linear_fit_metrics(xi, p)["fit"])


def staircase_predictions(
    run: PlannedRun,
    dt: float,
    params: ValveParams,
    intervals: Mapping[str, tuple[float, float]],
    noise: float,
    quantum: float,
    error: Mapping[str, Any] | None = None,
) -> dict[str, Any]:
    """Each level's predicted pressure and the FIT, with 95 % bands.

    ``error``: the model's error measured on the identification's own recordings
    (:func:`spa.plan.verify_error.recorded_model_error`; ``level_bar`` and ``fit_points``),
    added to each band (none when not given).

    Returns
    -------
    dict
        ``xi`` (levels), ``hold`` (s), ``p`` (predicted on the identified valve),
        ``lo``/``hi`` (the band: over the estimate and the box's corners, widened by the
        model error, ``1.96 noise/sqrt(n)`` and half the ADC step), and ``fit`` with
        ``fit_lo``/``fit_hi`` (over the same valves, widened by the FIT's model error and
        half a point).
    """
    from spa import simulate

    seg = run.segments[0]
    hold_ticks = int(seg.c)
    n = run.ticks // hold_ticks
    xi = run_xi(run)
    assert xi is not None
    levels = xi[::hold_ticks][:n]
    u = run_commands(run, dt)
    t = np.arange(u.size) * dt
    hold = hold_ticks * dt
    nominal, count = level_means(t, simulate(u, dt, params), hold, n)
    box = np.array(
        [nominal]
        + [level_means(t, simulate(u, dt, c), hold, n)[0] for c in corners(params, intervals)]
    )
    err = error or {}
    widen = (
        float(err.get("level_bar", 0.0))
        + 1.96 * noise / np.sqrt(np.maximum(count, 1))
        + 0.5 * quantum
    )
    fits = [_fit(levels, row) for row in box]
    fit_widen = float(err.get("fit_points", 0.0)) + 0.5
    return {
        "xi": levels.tolist(),
        "hold": hold,
        "p": nominal.tolist(),
        "lo": (box.min(axis=0) - widen).tolist(),
        "hi": (box.max(axis=0) + widen).tolist(),
        "fit": _fit(levels, nominal),
        "fit_lo": min(fits) - fit_widen,
        "fit_hi": max(fits) + fit_widen,
    }


def verdict(measured: float, lo: float, hi: float, unit: str, scale: float = 1.0) -> str:
    """``kept`` when ``measured`` lies in ``[lo, hi]``, else ``broken by <amount> <unit>``.

    Examples
    --------
    >>> verdict(0.5, 0.4, 0.6, "bar"), verdict(0.7, 0.4, 0.6, "mbar", 1e3)
    ('kept', 'broken by +100 mbar')
    """
    if not math.isfinite(measured):
        return "not measured"
    if lo <= measured <= hi:
        return "kept"
    off = measured - hi if measured > hi else measured - lo
    return f"broken by {off * scale:+.3g} {unit}"


def sine_fit(
    t: npt.ArrayLike, p: npt.ArrayLike, omega: float, start: float
) -> tuple[float, float, int]:
    """The mean and the amplitude of the fundamental at ``omega`` (rad/s) of ``p`` from
    ``start`` s on (least squares on ``1, sin, cos``), and the samples used."""
    t = np.asarray(t, dtype=np.float64)
    p = np.asarray(p, dtype=np.float64)
    keep = t >= start - 1e-9
    a = np.column_stack(
        [np.ones(int(keep.sum())), np.sin(omega * t[keep]), np.cos(omega * t[keep])]
    )
    coef, *_ = np.linalg.lstsq(a, p[keep], rcond=None)
    return float(coef[0]), float(math.hypot(coef[1], coef[2])), int(keep.sum())


def sine_predictions(
    run: PlannedRun,
    dt: float,
    params: ValveParams,
    intervals: Mapping[str, tuple[float, float]],
    noise: float,
    quantum: float,
    error: Mapping[str, Any] | None = None,
) -> dict[str, Any]:
    """The sine's mean pressure and amplitude over its second half, predicted with 95 %
    bands (over the estimate and the box's corners, widened by the model error measured on
    the identification's own sines, ``error``'s ``sine_mean_bar`` and
    ``sine_amplitude_bar``, by the noise on a least-squares fit of ``n`` samples,
    ``1.96 noise sqrt(2/n)`` on the amplitude and ``1.96 noise/sqrt(n)`` on the mean, and by
    half the ADC step)."""
    from spa import simulate

    seg = run.segments[0]
    omega = float(seg.c) / dt
    u = run_commands(run, dt)
    t = np.arange(u.size) * dt
    start = 0.5 * u.size * dt
    nominal = sine_fit(t, simulate(u, dt, params), omega, start)
    box = np.array(
        [nominal[:2]]
        + [sine_fit(t, simulate(u, dt, c), omega, start)[:2] for c in corners(params, intervals)]
    )
    n = max(nominal[2], 1)
    err = error or {}
    wide_mean = float(err.get("sine_mean_bar", 0.0)) + 1.96 * noise / math.sqrt(n) + 0.5 * quantum
    wide_amp = (
        float(err.get("sine_amplitude_bar", 0.0))
        + 1.96 * noise * math.sqrt(2.0 / n)
        + 0.5 * quantum
    )
    return {
        "omega": omega,
        "start": start,
        "mean": nominal[0],
        "mean_lo": float(box[:, 0].min()) - wide_mean,
        "mean_hi": float(box[:, 0].max()) + wide_mean,
        "amplitude": nominal[1],
        "amplitude_lo": float(box[:, 1].min()) - wide_amp,
        "amplitude_hi": float(box[:, 1].max()) + wide_amp,
    }


def compare_sine(prediction: Mapping[str, Any], run: pd.DataFrame) -> pd.DataFrame:
    """A recorded sine (``t`` s, ``p`` bar) against :func:`sine_predictions`: its mean and
    amplitude, each ``kept`` or ``broken by ...``."""
    mean, amp, _ = sine_fit(
        run["t"], run["p"], float(prediction["omega"]), float(prediction["start"])
    )
    rows = []
    for key, label, value in (
        ("mean", "sine mean bar", mean),
        ("amplitude", "sine amplitude bar", amp),
    ):
        lo, hi = float(prediction[f"{key}_lo"]), float(prediction[f"{key}_hi"])
        rows.append(
            {
                "prediction": label,
                "predicted": float(prediction[key]),
                "band": f"{lo:.4g} to {hi:.4g} bar",
                "measured": value,
                "verdict": verdict(value, lo, hi, "mbar", 1e3),
            }
        )
    return pd.DataFrame(rows)


def compare(prediction: Mapping[str, Any], run: pd.DataFrame) -> pd.DataFrame:
    """A recorded staircase (``t`` s, ``p`` bar) against its prediction: one row per level
    and one for the FIT, each ``kept`` or ``broken by ...``."""
    xi = np.asarray(prediction["xi"])
    means, _ = level_means(run["t"], run["p"], float(prediction["hold"]), xi.size)
    rows = []
    for i, x in enumerate(xi):
        lo, hi = prediction["lo"][i], prediction["hi"][i]
        rows.append(
            {
                "prediction": f"level xi = {x:.2f}",
                "predicted": prediction["p"][i],
                "band": f"{lo:.4g} to {hi:.4g} bar",
                "measured": means[i],
                "verdict": verdict(means[i], lo, hi, "mbar", 1e3),
            }
        )
    fit = _fit(xi, means) if np.isfinite(means).all() else math.nan
    rows.append(
        {
            "prediction": "FIT %",
            "predicted": prediction["fit"],
            "band": f"{prediction['fit_lo']:.3g} to {prediction['fit_hi']:.3g} %",
            "measured": fit,
            "verdict": verdict(fit, prediction["fit_lo"], prediction["fit_hi"], "points"),
        }
    )
    return pd.DataFrame(rows)


#: The page's parts: what each compares.
PARTS = {
    "recommendation": "Recommendation: the recommended setting's levels and FIT",
    "promise": "Promise: the closed loop's overshoot, settling and ripple",
}


def verification_frame(tables: Mapping[str, Mapping[str, pd.DataFrame]]) -> pd.DataFrame:
    """Every comparison in one table, ``part``, ``run`` and :func:`compare`'s columns
    (``spa record`` writes it as the plan folder's ``verification.csv``)."""
    frames = [
        table.assign(part=part, run=run_id)
        for part, by_run in tables.items()
        for run_id, table in by_run.items()
    ]
    columns = ["part", "run", "prediction", "predicted", "band", "measured", "verdict"]
    if not frames:
        return pd.DataFrame(columns=columns)
    return pd.concat(frames, ignore_index=True)[columns]


def verification_page(title: str, frame: pd.DataFrame) -> str:
    """The comparison (:func:`verification_frame`) as a markdown page: per part, one table
    per recorded run, and how many of its predictions were kept."""
    lines = [f"# {title}: predictions against the bench", ""]
    for part, heading in PARTS.items():
        rows = frame[frame["part"] == part]
        kept = int((rows["verdict"] == "kept").sum())
        lines += [f"## {heading}: {kept} of {len(rows)} kept", ""]
        if rows.empty:
            lines += ["No run of this part recorded (or no prediction made).", ""]
        for run_id, table in rows.groupby("run", sort=False):
            lines += [
                f"### {run_id}",
                "",
                "| prediction | predicted | 95 % band | measured | verdict |",
                "|---|---|---|---|---|",
            ]
            for r in table.itertuples():
                cells = [r.prediction, f"{r.predicted:.4g}", r.band, f"{r.measured:.4g}", r.verdict]
                lines.append("| " + " | ".join(cells) + " |")
            lines.append("")
    return "\n".join(lines)
