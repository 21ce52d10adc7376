"""``spa plan FOLDER --verify RESULTS``: the verification session planned on a dataset's
results, with every prediction and its band in ``plan.yaml`` (:func:`verify_plan`), and the
recorded verification compared with them (:func:`verification_tables`, which ``spa
record`` calls). The predictions themselves are :mod:`spa.plan.verify`'s; their bands'
terms :mod:`spa.plan.bands`' and :mod:`spa.plan.loop_bands`'."""

from __future__ import annotations

import argparse
import math
from pathlib import Path
from typing import Any, TextIO

__all__ = ["VERIFY_NOISE", "recorded_settings", "verification_tables", "verify_plan"]


#: The sensor noise a verification's bands assume, bar (stated in plan.yaml).
VERIFY_NOISE = 0.005


def verify_plan(args: argparse.Namespace, limits: Any, out: TextIO) -> int:
    """``spa plan FOLDER --verify RESULTS``: the recommended setting's runs on the identified
    valve, with each staircase's predicted levels and FIT in plan.yaml; and, when the
    closed_loop stage made a promise, the chosen controller's staircase played through its
    ``controller.h`` (the plan's tick is the header's step), with the promise's bands."""
    import yaml

    from spa.identification.identified import read_identified
    from spa.model.modulators import Modulator
    from spa.plan.bands import LEVEL, session_level
    from spa.plan.folder import calibration_for, write_plan
    from spa.plan.verdicts import band_widths
    from spa.plan.verify import (
        design_verification,
        sine_predictions,
        staircase_predictions,
    )

    results = Path(args.verify)
    params_path = results / "identification" / "params.yaml"
    valve = read_identified(str(params_path))
    identified = yaml.safe_load(params_path.read_text(encoding="utf-8"))
    rec_path = results / "tuning" / "recommendation.yaml"
    rec = yaml.safe_load(rec_path.read_text(encoding="utf-8")) if rec_path.is_file() else None
    if not rec or not (rec.get("recommended") or {}).get("setting"):
        from spa.tuning import tune

        rec = dict(tune(valve).recommendation)
    setting = Modulator.from_mapping(rec["recommended"]["setting"])
    noise = _sensor_noise(identified)
    promise, header, dt, said = _promise_of(results, args.tick)
    design = design_verification(
        valve.params,
        setting,
        limits,
        dt=dt,
        levels=args.levels,
        replicates=args.replicates,
        seed=args.seed,
        promise=promise,
    )
    cal = calibration_for(limits.p_max)
    quantum = cal["bar_per_count"]
    error = _model_error(results, valve.params, noise, quantum, setting.label, _heldout(identified))
    measured = any(error[k]["n"] for k in ("level", "sine_mean"))
    box = _draw_intervals(identified, valve) if measured else dict(valve.intervals)
    joint = _correlation(identified)
    made: dict[Any, dict[str, Any]] = {}  # replicates repeat one command: predicted once

    def predict(run: Any) -> dict[str, Any]:
        key = (run.kind, run.segments)
        if key not in made:
            make = staircase_predictions if run.kind == "staircase" else sine_predictions
            made[key] = make(
                run, design.dt, valve.params, box, noise, quantum, error, args.seed, joint
            )
        return made[key]

    predictions = {run.id: predict(run) for run in design.runs if run.kind == "staircase"}
    sines = {run.id: predict(run) for run in design.runs if run.kind == "sine"}
    checked, dropped = _drift_check(design, valve.params, predictions, sines, noise, cal)
    predictions = {rid: _drop(p, dropped[rid]) for rid, p in predictions.items()}
    sines = {rid: _drop(p, dropped[rid]) for rid, p in sines.items()}
    count = sum(_judged(p) for p in (*predictions.values(), *sines.values()))
    verify: dict[str, Any] = {
        "drift_check": checked,
        "results": str(results),
        "setting": setting.to_mapping(),
        "sensor_noise_bar": noise,
        "model_error": error,
        "predictions": predictions,
        "sines": sines,
    }
    closed = [run for run in design.runs if run.closed]
    if closed and promise is not None:
        verify["promise"] = _loop_verification(
            closed, promise, header or "", valve.params, design.dt, noise, quantum, box, joint
        )
        _loop_model_error(verify["promise"], results, valve.params, noise, quantum, args.seed)
    promise_bands = (verify.get("promise") or {}).get("bands") or {}
    count += len(closed) * sum("sd" in b for b in promise_bands.values())
    verify["session"] = {
        "predictions": count,
        "level": session_level(count),
        "false_alarm": 1.0 - LEVEL,
        "rule": "each prediction's 95 % band says kept or broken (about one in twenty breaks "
        "on the plant identified); the session is broken when any prediction leaves its band "
        "at the Sidak level 0.95**(1/predictions)",
    }
    verify["band_widths"] = band_widths(predictions, sines, verify.get("promise"), valve.params.k2)
    recorded = recorded_settings(results / "runs")
    verify["recorded_settings"] = recorded
    verify["extrapolated"] = setting.label not in recorded
    loop_label = None
    if verify.get("promise"):
        loop_label = Modulator.from_mapping(verify["promise"]["setting"]).label
        # the closed loop's own setting: its ripple and dynamics were never measured open
        # loop when the dataset did not record it
        verify["promise"]["extrapolated"] = loop_label not in recorded
    extra = {"prior_source": f"identified ({results})", "verify": verify}
    write_plan(args.folder, design, extra=extra, controller=header)
    print(
        f"{args.folder}: verification of {results} ({setting.label}), {len(design.runs)} "
        f"runs, {design.duration / 60:.0f} min; {len(predictions)} staircases and {len(sines)} "
        "sines predicted; "
        f"{said}",
        file=out,
    )
    level, fit = error["level"], error["fit"]
    print(
        "  model error in the bands (held out, x{:.3g} the in-sample): levels {:.3g} mbar "
        "(dof {:.3g}), FIT {:.3g} points ({}); {} predictions, the session broken when one "
        "leaves its band at {:.3g} %".format(
            error["heldout_factor"],
            1e3 * level["sd"],
            level["dof"],
            fit["sd"],
            error["measured_on"],
            count,
            100 * verify["session"]["level"],
        ),
        file=out,
    )
    widths = _widths_said(verify["band_widths"])
    if widths:
        print(f"  95 % bands: {widths}", file=out)
    gone = _dropped_said(predictions, sines)
    if gone:
        print(
            f"  dropped: {gone}: no ±50 % drift of t_on, t_off, k2 or tau2 moves them out of "
            "their bands, so they cannot fail on this bench (plan.yaml: verify.drift_check)",
            file=out,
        )
    if verify["extrapolated"]:
        print(
            f"  warning: extrapolated: {setting.label} is not among the settings "
            f"{results.name} recorded ({', '.join(recorded) or 'none'}); its predictions "
            "extrapolate the model, whose error was measured on those only. Record it and its "
            f"neighbours first: spa plan raw/<next> --params {params_path} --p-max "
            f"{limits.p_max:g}",
            file=out,
        )
    if loop_label is not None and verify["promise"]["extrapolated"]:
        print(
            f"  warning: extrapolated: the closed loop's setting {loop_label} is not among the "
            f"settings {results.name} recorded; its ripple and dynamics on this bench were "
            "never measured, and its bands hold the identification's uncertainty and the "
            "noise only",
            file=out,
        )
    print((Path(args.folder) / "checklist.md").read_text(encoding="utf-8"), file=out, end="")
    return 0


def _widths_said(widths: dict[str, Any]) -> str:
    """:func:`spa.plan.verdicts.band_widths` in words, for the command's output."""
    said = []
    lv = widths.get("levels")
    if lv:
        said.append(
            "levels {:.3g} mbar wide (median; {:.2g} % of k2, {:.2g} % of a step)".format(
                1e3 * lv["median_bar"], lv["of_range_percent"], lv["of_step_percent"]
            )
        )
    if "sine_amplitude" in widths:
        amp = widths["sine_amplitude"]
        said.append(
            "sine amplitude {:.3g} mbar ({:.2g} % of it)".format(
                1e3 * amp["median_bar"], amp["of_amplitude_percent"]
            )
        )
    loop = widths.get("closed_loop") or {}
    if "overshoot" in loop:
        said.append("overshoot {:.3g} points".format(loop["overshoot"]["width"]))
    if "settling_time" in loop:
        settle = loop["settling_time"]
        said.append(
            "settling {:.3g} s ({:.2g} % of the hold)".format(
                settle["width"], settle.get("of_hold_percent", math.nan)
            )
        )
    return "; ".join(said)


def _drift_check(
    design: Any,
    params: Any,
    staircases: dict[str, Any],
    sines: dict[str, Any],
    noise: float,
    cal: dict[str, Any],
) -> tuple[dict[str, dict[str, Any]], dict[str, dict[str, Any]]]:
    """:func:`spa.plan.drift.drift_check` of a verification's staircases and sines, and
    the predictions no drift breaks (:func:`spa.plan.drift.unbroken`)."""
    from spa.plan.drift import drift_check, unbroken
    from spa.plan.verify import sine_predictions, staircase_predictions

    runs = {run.id: run for run in design.runs}
    quantum = cal["bar_per_count"]
    moved: dict[Any, dict[str, Any]] = {}

    def predict(rid: str, valve: Any) -> dict[str, Any]:
        key = (runs[rid].kind, runs[rid].segments, valve)
        if key not in moved:
            make = staircase_predictions if rid in staircases else sine_predictions
            moved[key] = make(runs[rid], design.dt, valve, {}, noise, quantum)
        return moved[key]

    both = {**staircases, **sines}
    return drift_check(both, predict, params), unbroken(both, predict, params)


def _drop(prediction: dict[str, Any], unbroken: dict[str, Any]) -> dict[str, Any]:
    """``prediction`` with what no drift breaks marked dropped: ``dropped_levels`` (indices),
    ``fit_dropped``, ``mean_dropped``, ``amplitude_dropped``; the comparison skips them."""
    out = dict(prediction)
    if "level" in unbroken:
        out["dropped_levels"] = list(unbroken["level"])
        out["fit_dropped"] = bool(unbroken["fit"])
    else:
        out["mean_dropped"] = bool(unbroken["mean"])
        out["amplitude_dropped"] = bool(unbroken["amplitude"])
    return out


def _judged(prediction: dict[str, Any]) -> int:
    """How many of a run's predictions are compared (those not dropped)."""
    if "p" in prediction:
        kept = len(prediction["p"]) - len(prediction.get("dropped_levels") or [])
        return kept + (0 if prediction.get("fit_dropped") else 1)
    return sum(not prediction.get(f"{k}_dropped") for k in ("mean", "amplitude"))


def _dropped_said(staircases: dict[str, Any], sines: dict[str, Any]) -> str:
    """The dropped predictions in words, each kind once (e.g. "the level at xi = 0.00, the
    sine's amplitude"); "" when none."""
    said: list[str] = []
    for pred in staircases.values():
        for i in pred.get("dropped_levels") or []:
            said.append(f"the level at xi = {pred['xi'][i]:.2f}")
        if pred.get("fit_dropped"):
            said.append("the staircase's FIT")
    for pred in sines.values():
        for key in ("mean", "amplitude"):
            if pred.get(f"{key}_dropped"):
                said.append(f"the sine's {key}")
    return ", ".join(dict.fromkeys(said))


def recorded_settings(folder: Path) -> list[str]:
    """The labels of the modulator settings of a dataset's modulated runs (its run tables'
    metadata, ``results/<name>/runs``), sorted; none without run tables.

    Examples
    --------
    >>> recorded_settings(Path("no-such-folder"))
    []
    """
    from spa.datasets import read_run_meta
    from spa.model.modulators import Modulator

    labels = set()
    for path in sorted(folder.glob("*.parquet")) if folder.is_dir() else []:
        meta = read_run_meta(path)
        if isinstance(meta.get("modulator"), dict):
            labels.add(Modulator.from_mapping(meta["modulator"]).label)
    return sorted(labels)


def _model_error(
    results: Path,
    params: Any,
    noise: float = 0.0,
    quantum: float = 0.0,
    setting: str | None = None,
    factor: float = 1.0,
) -> dict[str, Any]:
    """The identified valve's error on the dataset's own staircases and sines
    (``results/runs``, the pipeline's run tables), for the verification's bands
    (:func:`spa.plan.verify_error.recorded_model_error`); every term 0, said so, without
    them."""
    from spa.datasets import read_runs
    from spa.plan.verify_error import no_model_error, recorded_model_error

    folder = results / "runs"
    if not folder.is_dir() or not any(folder.glob("*.parquet")):
        return no_model_error(f"no run tables in {folder}")
    runs, metas = read_runs(folder)
    return recorded_model_error(
        runs,
        metas,
        params,
        where=str(folder),
        noise=noise,
        quantum=quantum,
        setting=setting,
        factor=factor,
    )


def _draw_intervals(identified: Any, valve: Any) -> dict[str, tuple[float, float]]:
    """The 95 % intervals the verification's draws take when the model's error was measured
    on recorded staircases or sines: the refinement's own statistical ones,
    ``value ± 1.96 se`` (``refinement.se``: sandwich and leave-one-run-out, before the
    widening by the gap to the start and the logging step, a misfit the model error term
    then measures on the recordings instead), clipped at 0 for a delay; the reported
    intervals for a parameter without one, and for the actuator's own laws. Without
    recorded staircases or sines the draws take the reported intervals: their widening is
    then the only evidence of the misfit."""
    box = dict(valve.intervals)
    record = identified if isinstance(identified, dict) else {}
    if (record.get("laws") or {}).get("chosen") == "identified":
        return box
    se = (record.get("refinement") or {}).get("se") or {}
    for name, value in se.items():
        if name in box and isinstance(value, (int, float)) and math.isfinite(value):
            x = float(getattr(valve.params, name))
            lo = x - 1.959964 * float(value)
            box[name] = (max(lo, 0.0) if name.startswith("t_") else lo, x + 1.959964 * value)
    return box


def _correlation(identified: Any) -> dict[str, Any] | None:
    """How the identification's errors move together, for the verification's draws: the
    laws fit's ``covariance`` when it chose the actuator's own laws, else the refinement's
    ``correlation``; None without either."""
    record = identified if isinstance(identified, dict) else {}
    laws = record.get("laws") or {}
    if laws.get("chosen") == "identified" and isinstance(laws.get("covariance"), dict):
        return dict(laws["covariance"])
    found = (record.get("refinement") or {}).get("correlation")
    return dict(found) if isinstance(found, dict) else None


def _heldout(identified: Any) -> float:
    """The identification's held-out factor (:func:`spa.plan.bands.heldout_factor`): of the
    actuator's own laws when it chose them (``laws.fit_identified`` over
    ``laws.fit_insample``), else of the refinement (``refinement.fit_heldout`` over
    ``fit_after``); 1 without either."""
    from spa.plan.bands import heldout_factor

    record = identified if isinstance(identified, dict) else {}
    laws = record.get("laws") or {}
    if laws.get("chosen") == "identified" and laws.get("fit_identified"):
        return heldout_factor(laws["fit_identified"], laws.get("fit_insample") or {})
    ref = record.get("refinement") or {}
    return heldout_factor(ref.get("fit_heldout") or {}, ref.get("fit_after") or {})


def _sensor_noise(identified: Any) -> float:
    """The identification's sensor noise (bar), else :data:`VERIFY_NOISE`."""
    try:
        value = float(identified["noise"]["sensor"])
    except (KeyError, TypeError, ValueError):
        return VERIFY_NOISE
    return value if value > 0 else VERIFY_NOISE


def _loop_verification(
    closed: list[Any],
    promise: dict[str, Any],
    header: str,
    params: Any,
    dt: float,
    noise: float,
    quantum: float,
    box: dict[str, tuple[float, float]],
    joint: dict[str, Any] | None,
) -> dict[str, Any]:
    """``verify.promise``: the closed-loop staircases' runs, lead, setting and levels, what
    the stage promised (its worst case over the box), and the predictions with their
    bands (:func:`spa.plan.loop_bands.loop_predictions`); a promise written before it
    carried its controller keeps the promise's own numbers as bands
    (:func:`spa.plan.verify.promise_predictions`)."""
    from spa.closedloop.controller import PIController
    from spa.plan.loop_bands import loop_predictions
    from spa.plan.verify import promise_predictions

    setting = _header_setting(header)
    hold = float(closed[0].meta["hold"])
    levels = [float(v) for v in promise["levels"]]
    out: dict[str, Any] = {
        "runs": [run.id for run in closed],
        "lead": float(closed[0].meta["lead"]),
        "setting": setting,
        "levels": levels,
        "hold": hold,
        "made": bool(promise.get("kept")),
        "promised": {k: promise.get(k) for k in ("overshoot", "settling_time", "ripple_pp")},
    }
    if isinstance(promise.get("controller"), dict):
        ctrl = PIController.from_mapping(promise["controller"])
        bands = loop_predictions(
            params, setting, ctrl, levels, hold, dt, noise, quantum, box, joint
        )
        out["unpredicted"] = {k: b for k, b in bands.items() if "value" not in b}
        out["bands"] = {k: b for k, b in bands.items() if "value" in b}
        out["method"] = (
            "the staircase simulated through the exported PI and modulator on valves drawn "
            "from the identification's uncertainty, each with the sensor's noise, measured as "
            "a recording is: mean +- t sd sqrt(1 + 1/draws) (spa.plan.loop_bands)"
        )
        return out
    allowance = _settling_allowance(params, setting, promise, hold, dt, noise, quantum)
    out["settling_noise_allowance_s"] = allowance
    step = round(hold / dt)
    samples = step - 3 * step // 4  # a step's last quarter, as spa.closedloop.metrics takes it
    out["bands"] = promise_predictions(promise, noise, quantum, allowance, samples)
    out["method"] = "the promise's own worst case (no controller in it to simulate)"
    return out


def _loop_model_error(
    loop: dict[str, Any], results: Path, params: Any, noise: float, quantum: float, seed: int
) -> None:
    """The promise's ripple, settling-time and duty bands with the model's error on the
    dataset's open-loop staircases of the loop's own setting
    (:func:`spa.plan.loop_bands.with_model_error` of :mod:`spa.plan.loop_error`'s
    measures), in place. A duty is predicted only with its error measured, and within
    :data:`spa.plan.loop_error.DUTY_RANGE`: the bands alone hold the identification's
    uncertainty, not the plant's own conductances, which a closed loop's command shows and
    its levels hide. Nothing else changes without those bands or run tables."""
    from spa.model.modulators import Modulator
    from spa.plan.loop_bands import DUTIES, with_model_error
    from spa.plan.loop_error import (
        DUTY_RANGE,
        RIPPLE_MIN_LEVELS,
        duty_error,
        ripple_error,
        settling_error,
    )

    bands = loop.get("bands") or {}
    folder = results / "runs"
    measures = {"ripple_pp": ripple_error, "settling_time": settling_error}
    measures.update({name: duty_error for name in DUTIES})
    errors: dict[Any, dict[str, Any]] = {}  # measure -> its error, once for both duties
    if set(measures) & set(bands) and folder.is_dir() and any(folder.glob("*.parquet")):
        from spa.datasets import read_runs

        runs, metas = read_runs(folder)
        label = Modulator.from_mapping(loop["setting"]).label
        for name, measure in measures.items():
            if name in bands:
                if measure not in errors:
                    errors[measure] = measure(runs, metas, params, label, noise, quantum, seed)
                bands[name] = with_model_error(bands[name], errors[measure])
    lo, hi = DUTY_RANGE
    for name in DUTIES:
        band = bands.get(name)
        if band is None:
            continue
        if not (band.get("model_error") or {}).get("applied"):
            why = (
                "the model's error on the command was not measured on "
                f"{RIPPLE_MIN_LEVELS} recorded levels"
            )
        elif not lo < float(band["value"]) < hi:
            why = f"the level is held with the valve's command outside {lo:g}-{hi:g}"
        else:
            continue
        loop.setdefault("unpredicted", {})[name] = {"why": why, "unit": band.get("unit")}
        del bands[name]


def _settling_allowance(
    params: Any,
    setting: dict[str, Any],
    promise: dict[str, Any],
    hold: float,
    dt: float,
    noise: float,
    quantum: float,
) -> float:
    """:func:`spa.plan.settling.settling_allowance` for the promise's controller, or 0 when
    the promise names none (a promise written before it carried its controller)."""
    from spa.closedloop.controller import PIController
    from spa.plan.settling import settling_allowance

    if not isinstance(promise.get("controller"), dict) or promise.get("settling_time") is None:
        return 0.0
    ctrl = PIController.from_mapping(promise["controller"])
    levels = [float(v) for v in promise["levels"]]
    return settling_allowance(params, setting, ctrl, levels, hold, dt, noise, quantum)


def _header_setting(text: str) -> dict[str, Any]:
    """The modulator setting a controller header's ``Setting:`` comment line records."""
    import ast
    import re

    m = re.search(r"^\s*\*\s*Setting:\s*(\{.*\})\s*$", text, flags=re.MULTILINE)
    if m is None:
        raise ValueError("controller.h: no 'Setting: {...}' line in its comment")
    return dict(ast.literal_eval(m.group(1)))


def _promise_of(results: Path, tick: float) -> tuple[Any, str | None, float, str]:
    """The closed_loop stage's promise (``controllers.yaml: bench.promise``) and header of
    ``results``, the plan's tick (the header's step when there is one), and a sentence
    saying which."""
    import yaml

    from spa.plan.verify import header_step

    path = results / "closed_loop" / "controllers.yaml"
    header = results / "closed_loop" / "controller.h"
    if not path.is_file() or not header.is_file():
        return None, None, tick, f"no closed loop ({path} or {header.name} missing)"
    bench = (yaml.safe_load(path.read_text(encoding="utf-8")) or {}).get("bench")
    promise = bench.get("promise") if isinstance(bench, dict) else None
    if not isinstance(promise, dict) or not promise.get("levels"):
        return None, None, tick, f"no closed loop: {path} holds no bench.promise"
    text = header.read_text(encoding="utf-8")
    _, dt = header_step(text)
    kept = "promise" if promise.get("kept") else "no promise: its runs are recorded, unjudged"
    return promise, text, dt, f"closed loop through {header} at its step {dt * 1e3:g} ms ({kept})"


def verification_tables(folder: Path, plan: dict[str, Any]) -> dict[str, dict[str, Any]]:
    """Each predicted staircase of a verification plan against its recording
    (``recommendation``), and each closed-loop staircase against the promise (``promise``)."""
    import pandas as pd

    from spa.identification.identified import read_identified
    from spa.plan.verify import compare, compare_promise, compare_sine

    verify = plan["verify"]
    level = (verify.get("session") or {}).get("level")
    files = {r["id"]: folder / r["file"] for r in plan["runs"]}
    tables: dict[str, dict[str, Any]] = {"recommendation": {}, "promise": {}}
    for run_id, pred in verify["predictions"].items():
        if files[run_id].is_file():
            tables["recommendation"][run_id] = compare(pred, pd.read_csv(files[run_id]), level)
    for run_id, pred in (verify.get("sines") or {}).items():
        if files[run_id].is_file():
            tables["recommendation"][run_id] = compare_sine(pred, pd.read_csv(files[run_id]), level)
    promise = verify.get("promise") or {}
    if promise.get("bands"):
        params_path = Path(verify["results"]) / "identification" / "params.yaml"
        params = read_identified(str(params_path)).params
        for run_id in promise["runs"]:
            if files[run_id].is_file():
                tables["promise"][run_id] = compare_promise(
                    promise["bands"],
                    pd.read_csv(files[run_id]),
                    promise["setting"],
                    params,
                    float(promise["lead"]),
                    bool(promise.get("made", True)),
                    level,
                )
    return tables
