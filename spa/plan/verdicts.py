"""The verification's measurements and verdicts: a recorded run measured as its prediction
was made (:func:`level_means`, :func:`sine_fit`), each prediction ``kept`` or ``broken by
...`` (:func:`compare`, :func:`compare_sine`, :func:`compare_promise`), the session's
verdict (:func:`session_verdict`) and the page and table ``spa record`` writes
(:func:`verification_page`, :func:`verification_frame`). :mod:`spa.plan.verify` plans the
verification and makes the predictions."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
import numpy.typing as npt
import pandas as pd

from spa.model.params import ValveParams

#: A comparison's columns, one row per prediction.
_ROW_COLUMNS = ["prediction", "predicted", "band", "measured", "verdict", "session"]

__all__ = [
    "PARTS",
    "band_widths",
    "compare",
    "compare_promise",
    "compare_sine",
    "level_means",
    "session_verdict",
    "sine_fit",
    "verdict",
    "verification_frame",
    "verification_page",
]


def compare_promise(
    prediction: Mapping[str, Any],
    run: pd.DataFrame,
    setting: Mapping[str, Any],
    params: ValveParams,
    lead: float,
    made: bool = True,
    session: float | None = None,
) -> pd.DataFrame:
    """A recorded closed-loop staircase (``t``, ``p``, ``r``, ``valve``) against its
    predictions: its worst overshoot, settling time and ripple, measured as the predictions
    were (:func:`spa.plan.loop_bands.measure_loop_run`), each ``kept`` or ``broken by ...``.

    ``prediction``: :func:`spa.plan.loop_bands.loop_predictions`'s bands (or
    :func:`promise_predictions`'s, for a plan written before them); ``setting``: the
    controller's modulator (the cycle-mean's window); ``lead``: the seconds at the first
    level left out; ``made``: whether the stage made the promise (else the rows say "no
    promise made"); ``session``: the session's level, for the ``session`` column (the
    band's ``sd`` times its ``scale``, with its ``dof``).
    """
    from spa.plan.loop_bands import measure_loop_run

    measured = measure_loop_run(run, setting, params, lead)
    names = {
        "overshoot": ("worst overshoot %", "points", 1.0),
        "settling_time": ("worst settling time s", "s", 1.0),
        "ripple_pp": ("worst ripple bar pp", "mbar", 1e3),
        "duty_top": ("command holding the top level (open fraction)", "points", 1e2),
        "duty_bottom": ("command holding the bottom level (open fraction)", "points", 1e2),
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
                "session": "outside"
                if session is not None and "sd" in band and math.isinf(value)
                else _session_mark(
                    value,
                    float(band["value"]),
                    float(band["sd"]) * float(band.get("scale", 1.0)) if "sd" in band else None,
                    band.get("dof"),
                    session,
                    float(band.get("pad", 0.0)),
                ),
            }
        )
    return pd.DataFrame(rows, columns=_ROW_COLUMNS)


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


def _session_mark(
    measured: float, predicted: float, sd: Any, dof: Any, level: float | None, pad: float = 0.0
) -> str:
    """``inside`` or ``outside`` the prediction's band at the session's level
    (:func:`spa.plan.bands.session_level`), ``pad`` wider at each end (a discrete measure's
    continuity correction); "" when the plan states no session level or the prediction no
    standard deviation (a plan written before the bands were calibrated)."""
    from spa.plan.bands import half_width

    if level is None or sd is None or not math.isfinite(measured):
        return ""
    half = float(half_width(float(sd), float(dof if dof is not None else math.inf), level)) + pad
    return "inside" if abs(measured - predicted) <= half else "outside"


def compare_sine(
    prediction: Mapping[str, Any], run: pd.DataFrame, session: float | None = None
) -> pd.DataFrame:
    """A recorded sine (``t`` s, ``p`` bar) against :func:`sine_predictions`: its mean and
    amplitude, each ``kept`` or ``broken by ...``, and ``session``: inside or outside its
    band at the session's level ``session`` (:func:`_session_mark`)."""
    mean, amp, _ = sine_fit(
        run["t"], run["p"], float(prediction["omega"]), float(prediction["start"])
    )
    rows = []
    for key, label, value in (
        ("mean", "sine mean bar", mean),
        ("amplitude", "sine amplitude bar", amp),
    ):
        if prediction.get(f"{key}_dropped"):
            continue  # the plan dropped it: no drift breaks it
        lo, hi = float(prediction[f"{key}_lo"]), float(prediction[f"{key}_hi"])
        rows.append(
            {
                "prediction": label,
                "predicted": float(prediction[key]),
                "band": f"{lo:.4g} to {hi:.4g} bar",
                "measured": value,
                "verdict": verdict(value, lo, hi, "mbar", 1e3),
                "session": _session_mark(
                    value,
                    float(prediction[key]),
                    prediction.get(f"{key}_sd"),
                    prediction.get(f"{key}_dof"),
                    session,
                ),
            }
        )
    return pd.DataFrame(rows, columns=_ROW_COLUMNS)


def compare(
    prediction: Mapping[str, Any], run: pd.DataFrame, session: float | None = None
) -> pd.DataFrame:
    """A recorded staircase (``t`` s, ``p`` bar) against its prediction: one row per level
    and one for the FIT, each ``kept`` or ``broken by ...``, and ``session``: inside or
    outside its band at the session's level ``session`` (:func:`_session_mark`). The levels
    and the FIT the plan dropped (``dropped_levels``, ``fit_dropped``: no drift breaks them)
    have no row; the FIT is still over every level."""
    xi = np.asarray(prediction["xi"])
    dropped = set(prediction.get("dropped_levels") or [])
    means, _ = level_means(run["t"], run["p"], float(prediction["hold"]), xi.size)
    sds = prediction.get("sd") or [None] * xi.size
    dofs = prediction.get("dof") or [None] * xi.size
    rows = []
    for i, x in enumerate(xi):
        if i in dropped:
            continue
        lo, hi = prediction["lo"][i], prediction["hi"][i]
        rows.append(
            {
                "prediction": f"level xi = {x:.2f}",
                "predicted": prediction["p"][i],
                "band": f"{lo:.4g} to {hi:.4g} bar",
                "measured": means[i],
                "verdict": verdict(means[i], lo, hi, "mbar", 1e3),
                "session": _session_mark(
                    float(means[i]), float(prediction["p"][i]), sds[i], dofs[i], session
                ),
            }
        )
    fit = _fit(xi, means) if np.isfinite(means).all() else math.nan
    if prediction.get("fit_dropped"):
        return pd.DataFrame(rows, columns=_ROW_COLUMNS)
    rows.append(
        {
            "prediction": "FIT %",
            "predicted": prediction["fit"],
            "band": f"{prediction['fit_lo']:.3g} to {prediction['fit_hi']:.3g} %",
            "measured": fit,
            "verdict": verdict(fit, prediction["fit_lo"], prediction["fit_hi"], "points"),
            "session": _session_mark(
                fit,
                float(prediction["fit"]),
                prediction.get("fit_sd"),
                prediction.get("fit_dof"),
                session,
            ),
        }
    )
    return pd.DataFrame(rows, columns=_ROW_COLUMNS)


def session_verdict(frame: pd.DataFrame, level: float | None = None) -> str:
    """The session's verdict in one sentence: how many predictions (of every part) left their
    95 % bands (about one in twenty does on an unchanged plant) and whether any left its band
    at the session's level ``level`` (:func:`spa.plan.bands.session_level`: designed for an
    unchanged plant to break one session in twenty; measured 7-16 %); "" when no prediction
    was judged at a session level (a plan written before the bands were calibrated).

    Examples
    --------
    >>> rows = pd.DataFrame({"part": ["recommendation"] * 2, "session": ["inside"] * 2,
    ...                      "verdict": ["kept", "broken by +3 mbar"]})
    >>> said = session_verdict(rows, 0.975)
    >>> said[:46], "the session is kept (designed for 5 % false alarms" in said
    ('Session: 1 of 2 predictions outside their 95 %', True)
    """
    rows = frame
    if rows.empty or "session" not in rows:
        return ""
    judged = rows[rows["session"].isin(["inside", "outside"])]
    if judged.empty:
        return ""
    broken = int((judged["verdict"] != "kept").sum())
    outside = int((judged["session"] == "outside").sum())
    at = f"the session level {100 * level:.3g} %" if level is not None else "the session level"
    said = (
        f"Session: {broken} of {len(judged)} predictions outside their 95 % bands (about "
        f"{0.05 * len(judged):.2g} expected by chance on the plant identified); "
    )
    if outside:
        return said + (
            f"{outside} outside their bands at {at}: the "
            "session is broken (the plant is not the one identified; designed for 5 % false "
            "alarms per session, measured 7-16 % on spa's model valves)."
        )
    return said + (
        f"none outside its band at {at}: the session is kept (designed for 5 % false alarms "
        "per session, measured 7-16 % on spa's model valves)."
    )


#: The page's parts: what each compares.
PARTS = {
    "recommendation": "Recommendation: the recommended setting's levels and FIT",
    "promise": "Promise: the closed loop's overshoot, settling, ripple and the command holding "
    "its levels",
}


def verification_frame(tables: Mapping[str, Mapping[str, pd.DataFrame]]) -> pd.DataFrame:
    """Every comparison in one table, ``part``, ``run`` and :func:`compare`'s columns
    (``spa record`` writes it as the plan folder's ``verification.csv``)."""
    frames = [
        table.assign(part=part, run=run_id, **({} if "session" in table else {"session": ""}))
        for part, by_run in tables.items()
        for run_id, table in by_run.items()
    ]
    columns = ["part", "run", "prediction", "predicted", "band", "measured", "verdict", "session"]
    if not frames:
        return pd.DataFrame(columns=columns)
    return pd.concat(frames, ignore_index=True)[columns]


def verification_page(title: str, frame: pd.DataFrame, level: float | None = None) -> str:
    """The comparison (:func:`verification_frame`) as a markdown page: per part, one table
    per recorded run, and how many of its predictions were kept; the recommendation's
    :func:`session_verdict` at the session's ``level``."""
    lines = [f"# {title}: predictions against the bench", ""]
    said = session_verdict(frame, level)
    if said:
        lines += [said, ""]
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


def band_widths(
    staircases: Mapping[str, Mapping[str, Any]],
    sines: Mapping[str, Mapping[str, Any]],
    promise: Mapping[str, Any] | None,
    k2: float,
) -> dict[str, Any]:
    """How wide a verification's 95 % bands are against what they are about: a band as
    wide as the staircase's step cannot tell one level from the next (issue 61: 75-209 mbar
    bands, 12 % of the range, that still missed).

    Parameters
    ----------
    staircases, sines : mapping
        ``verify.predictions`` and ``verify.sines`` of a verification plan (``lo``, ``hi``,
        ``p``, ``fit_lo``, ``fit_hi``, ``amplitude``, ``mean_lo`` ...); dropped ones are left
        out.
    promise : mapping or None
        ``verify.promise`` (its ``bands`` and ``hold``).
    k2 : float
        The identified supply, bar: the range a level can take.

    Returns
    -------
    dict
        ``levels``: median and largest width (bar), the median as % of ``k2`` and of the
        staircases' median step; ``fit``: median width, FIT points; ``sine_mean`` and
        ``sine_amplitude``: median width (bar) and as % of the sines' median amplitude;
        ``closed_loop``: each band's width in its unit, the settling time's also as % of the
        hold and the ripple's as % of its predicted value. Keys without a band are left out.

    Examples
    --------
    >>> st = {"a": {"p": [0.1, 0.2, 0.3], "lo": [0.09, 0.19, 0.29], "hi": [0.11, 0.21, 0.31],
    ...             "fit_lo": 98.0, "fit_hi": 99.0}}
    >>> w = band_widths(st, {}, None, 1.0)["levels"]
    >>> round(w["median_bar"], 3), round(w["of_range_percent"], 1), round(w["of_step_percent"])
    (0.02, 2.0, 20)
    """

    def median(values: Sequence[float]) -> float:
        return float(np.median(values)) if len(values) else math.nan

    out: dict[str, Any] = {}
    widths: list[float] = []
    steps: list[float] = []
    fits: list[float] = []
    for pred in staircases.values():
        gone = set(pred.get("dropped_levels") or [])
        lo, hi = pred.get("lo") or [], pred.get("hi") or []
        pairs = enumerate(zip(lo, hi, strict=True))
        widths += [float(h - w) for i, (w, h) in pairs if i not in gone]
        levels = np.asarray(pred.get("p") or [], dtype=np.float64)
        steps += [float(d) for d in np.abs(np.diff(levels)) if d > 0.0]
        if "fit_lo" in pred and not pred.get("fit_dropped"):
            fits.append(float(pred["fit_hi"]) - float(pred["fit_lo"]))
    if widths:
        med = median(widths)
        out["levels"] = {
            "median_bar": med,
            "largest_bar": float(max(widths)),
            "of_range_percent": 100.0 * med / float(k2),
            "of_step_percent": 100.0 * med / median(steps) if steps else math.nan,
        }
    if fits:
        out["fit"] = {"median_points": median(fits)}
    amplitude = median([float(s["amplitude"]) for s in sines.values() if "amplitude" in s])
    for part in ("mean", "amplitude"):
        kept = [s for s in sines.values() if f"{part}_lo" in s and not s.get(f"{part}_dropped")]
        if kept:
            med = median([float(s[f"{part}_hi"]) - float(s[f"{part}_lo"]) for s in kept])
            out[f"sine_{part}"] = {"median_bar": med, "of_amplitude_percent": 100 * med / amplitude}
    bands = (promise or {}).get("bands") or {}
    loop: dict[str, Any] = {}
    for key, band in bands.items():
        width = float(band["hi"]) - float(band["lo"])
        entry: dict[str, Any] = {"width": width, "unit": band.get("unit")}
        if key == "settling_time" and (promise or {}).get("hold"):
            entry["of_hold_percent"] = 100.0 * width / float(promise["hold"])  # type: ignore[index]
        if key == "ripple_pp" and float(band.get("value") or 0.0) > 0.0:
            entry["of_value_percent"] = 100.0 * width / float(band["value"])
        loop[key] = entry
    if loop:
        out["closed_loop"] = loop
    return out
