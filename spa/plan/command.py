"""``spa plan`` and ``spa record``: their arguments and what they run (spa/cli.py adds the
sub-commands)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any, TextIO

__all__ = [
    "plan_arguments",
    "record_arguments",
    "recorded_settings",
    "run_plan",
    "run_record",
]


def plan_arguments(p: argparse.ArgumentParser) -> None:
    """``spa plan``'s arguments (its help fits one screen: 24 lines of 80 columns)."""
    p.usage = "%(prog)s FOLDER --p-max BAR [options] [--verify RESULTS]"
    p.add_argument("folder", metavar="FOLDER", help="the new dataset folder, raw/<name>")
    prior = p.add_mutually_exclusive_group()
    prior.add_argument(
        "--params",
        metavar="PARAMS.yaml",
        help="prior: an identification (default: the paper's valve)",
    )
    prior.add_argument(
        "--supply", metavar="BAR,S", help="prior: supply, fill time (default: the paper's)"
    )
    p.add_argument(
        "--p-max",
        type=float,
        required=True,
        metavar="BAR",
        help="the actuator's rated maximum, bar",
    )
    p.add_argument(
        "--f-switch-max",
        type=float,
        metavar="HZ",
        help="valve's top switching rate (default: none)",
    )
    p.add_argument(
        "--on-time-max", type=float, metavar="S", help="longest coil on-time (default: none)"
    )
    link = p.add_mutually_exclusive_group()
    link.add_argument("--baud", type=int, default=115200, metavar="N", help="serial link's rate")
    link.add_argument(
        "--samples-per-s", type=float, metavar="N", help="logger's rate, not a UART (default: none)"
    )
    p.add_argument("--tick", type=float, default=0.002, metavar="S", help="log and control step")
    p.add_argument("--levels", type=int, default=11, metavar="N", help="staircase levels")
    p.add_argument("--replicates", type=int, default=3, metavar="N", help="of each experiment")
    p.add_argument(
        "--seed", type=int, default=0, metavar="N", help="of the runs' random order (default: 0)"
    )
    p.add_argument("--pilot", action="store_true", help="charge, discharge, pulses only")
    p.add_argument("--no-predict", action="store_true", help="skip the predicted precision")
    p.add_argument(
        "--verify", metavar="RESULTS", help="test results/<name>'s predictions (default: no)"
    )
    p.add_argument(
        "--budget", metavar="TIME", help="bench time at most, e.g. 90min, 1.5h (default: none)"
    )
    p.add_argument(
        "--missed-ok", action="store_true", help="a missed precision target warns (default: exit 3)"
    )
    # -h still works; its line makes room for the two above (the help fits one screen)
    for action in p._actions:
        if action.dest == "help":
            action.help = argparse.SUPPRESS


def record_arguments(p: argparse.ArgumentParser) -> None:
    """``spa record``'s arguments."""
    p.add_argument("folder", metavar="FOLDER", help="the plan's folder, raw/<name>")
    p.add_argument(
        "--stream",
        default="-",
        metavar="FILE",
        help="the board's stream: a file, a serial port's device, or - for stdin",
    )
    p.add_argument(
        "--recorded",
        metavar="WHEN",
        help="when the session was recorded, ISO 8601 (default: the stream file's time, or now)",
    )
    p.add_argument(
        "--page",
        metavar="PAGE.md",
        help="a verification's predictions beside the measurements (default: none)",
    )


def run_plan(args: argparse.Namespace, out: TextIO) -> int:
    """Design, predict and write a plan; print its summary."""
    from spa.model.modulators import Modulator
    from spa.model.params import ValveParams
    from spa.plan.budget import MISSED_STATUS, first_settings, parse_duration, within_budget
    from spa.plan.design import default_settings, design_session
    from spa.plan.folder import calibration_for, write_plan
    from spa.plan.limits import Limits, PlanError
    from spa.plan.prior import prior_from_numbers, prior_from_params

    try:
        if Path(args.folder).exists():
            raise PlanError(f"{args.folder} exists: a plan is written into a new folder only")
        if args.params:
            prior, source = prior_from_params(args.params), f"identified ({args.params})"
        elif args.supply is not None:
            parts = args.supply.split(",")
            try:
                supply, fill = (float(v) for v in parts)
            except ValueError:
                raise PlanError(
                    f"--supply {args.supply}: expected BAR,S (supply pressure in bar, rough "
                    "fill time in s), e.g. --supply 2,1.5"
                ) from None
            prior = prior_from_numbers(supply, fill)
            source = f"{supply:g} bar, fills in about {fill:g} s"
        else:
            prior, source = ValveParams(), "the paper's nominal valve"
        limits = Limits(
            p_max=args.p_max,
            f_switch_max=args.f_switch_max,
            on_time_max=args.on_time_max,
            baud=None if args.samples_per_s else float(args.baud),
            samples_per_s=args.samples_per_s,
        )
        recommended = None
        if args.verify:
            return _verify_plan(args, limits, out)
        if not args.pilot:
            from spa.tuning import tune

            rec = tune(prior).recommendation.get("recommended") or {}
            if rec.get("setting"):
                recommended = Modulator.from_mapping(rec["setting"])

        budget = parse_duration(args.budget) if args.budget else None

        # the settings design_session records by default, in its order
        settings = [] if args.pilot else default_settings(prior, args.tick, recommended)

        def session(replicates: int, levels: int, n_settings: int, margin: float) -> Any:
            return design_session(
                prior,
                limits,
                dt=args.tick,
                seed=args.seed,
                levels=levels,
                replicates=replicates,
                settings=first_settings(settings, n_settings, recommended),
                recommended=recommended,
                pilot=args.pilot,
                margin=margin,
            )

        kept: dict[str, Any] = {}  # what the budget kept of the last design made

        def make(replicates: int, margin: float) -> Any:
            if budget is None:
                return session(replicates, args.levels, len(settings), margin)
            plan, info = within_budget(
                session, replicates, args.levels, len(settings), margin, budget, args.pilot
            )
            kept.update(info)
            return plan

        table, resized = None, []
        if args.no_predict:
            design = make(args.replicates, 3.0)
        else:
            from spa.plan.precision import size_for_targets

            design, table, resized = size_for_targets(
                make, args.replicates, 3.0, calibration_for(limits.p_max)
            )
        extra: dict = {
            "prior_source": source,
            "margins": {
                "time_scale": design.margins["time_scale"],
                "meaning": f"identification runs sized for valves "
                f"{design.margins['time_scale']:g}x slower and faster than the prior",
            },
        }
        if budget is not None:
            extra["budget"] = {"seconds": budget, **kept}
        if table is not None:
            extra["resized"] = resized
            extra["predicted"] = [
                {k: (float(v) if isinstance(v, float) else v) for k, v in row.items()}
                for row in table.drop(columns="note").to_dict("records")
            ]
        write_plan(args.folder, design, extra=extra)
    except (PlanError, ValueError, OSError) as exc:
        print(f"error: {exc}", file=out)
        return 1
    print(
        f"{args.folder}: {len(design.runs)} runs, {design.duration / 60:.0f} min; prior: "
        f"{source}; tick {design.dt * 1e3:g} ms ({design.link})",
        file=out,
    )
    for label, s in design.settings.items():
        mark = " (recommended)" if s.get("recommended") else ""
        print(f"  {label}{mark}: levels held {s['hold']:g} s", file=out)
    from spa.plan.avr import ATMEGA328P, avr_size

    size = avr_size(args.folder)
    if size is not None:
        print(
            f"  ATmega328P: the player takes {size['flash']} of {ATMEGA328P['flash']} bytes of "
            f"flash, {size['ram']} of {ATMEGA328P['ram']} of static RAM (without the Arduino "
            "core)",
            file=out,
        )
    for warning in design.margins.get("warnings", []):
        print(f"  note: {warning}", file=out)
    for label, why in design.refused.items():
        print(f"  refused {label}: {why}", file=out)
    for line in resized:
        print(f"  {line}", file=out)
    if table is not None:
        print("predicted 95 % half-widths (target) on the prior and 3x corners:", file=out)
        for corner, rows in table.groupby("corner", sort=False):
            cells = ", ".join(
                f"{r.parameter} {r.half_width:.2g} ({r.target:.2g}){'' if r.met else ' MISSED'}"
                for r in rows.itertuples()
            )
            print(f"  {corner}: {cells}", file=out)
    if budget is not None and kept["given_up"]:
        print(f"  budget {budget / 60:g} min: {kept['given_up']}", file=out)
    print((Path(args.folder) / "checklist.md").read_text(encoding="utf-8"), file=out, end="")
    missed = 0 if table is None else int((~table["met"]).sum())
    if missed:
        word = "warning" if args.missed_ok else "error"
        print(
            f"{word}: the plan misses {missed} of its precision targets (MISSED above)"
            + ("" if args.missed_ok else "; --missed-ok records it anyway and exits 0"),
            file=out,
        )
        return 0 if args.missed_ok else MISSED_STATUS
    return 0


#: The sensor noise a verification's bands assume, bar (stated in plan.yaml).
VERIFY_NOISE = 0.005


def _verify_plan(args: argparse.Namespace, limits: Any, out: TextIO) -> int:
    """``spa plan FOLDER --verify RESULTS``: the recommended setting's runs on the identified
    valve, with each staircase's predicted levels and FIT in plan.yaml; and, when the
    closed_loop stage made a promise, the chosen controller's staircase played through its
    ``controller.h`` (the plan's tick is the header's step), with the promise's bands."""
    import yaml

    from spa.identification.identified import read_identified
    from spa.model.modulators import Modulator
    from spa.plan.folder import calibration_for, write_plan
    from spa.plan.verify import (
        design_verification,
        promise_predictions,
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
    error = _model_error(results, valve.params)
    box = dict(valve.intervals)
    predictions = {
        run.id: staircase_predictions(
            run, design.dt, valve.params, box, noise, cal["bar_per_count"], error
        )
        for run in design.runs
        if run.kind == "staircase"
    }
    sines = {
        run.id: sine_predictions(
            run, design.dt, valve.params, box, noise, cal["bar_per_count"], error
        )
        for run in design.runs
        if run.kind == "sine"
    }
    verify: dict[str, Any] = {
        "drift_check": _drift_check(design, valve.params, predictions, sines, noise, cal),
        "results": str(results),
        "setting": setting.to_mapping(),
        "sensor_noise_bar": noise,
        "model_error": error,
        "predictions": predictions,
        "sines": sines,
    }
    closed = [run for run in design.runs if run.closed]
    if closed and promise is not None:
        loop_setting = _header_setting(header or "")
        hold = float(closed[0].meta["hold"])
        allowance = _settling_allowance(
            valve.params, loop_setting, promise, hold, design.dt, noise, cal["bar_per_count"]
        )
        verify["promise"] = {
            "runs": [run.id for run in closed],
            "lead": float(closed[0].meta["lead"]),
            "setting": loop_setting,
            "levels": [float(v) for v in promise["levels"]],
            "hold": hold,
            "made": bool(promise.get("kept")),
            "settling_noise_allowance_s": allowance,
            "bands": promise_predictions(promise, noise, cal["bar_per_count"], allowance),
        }
    recorded = recorded_settings(results / "runs")
    verify["recorded_settings"] = recorded
    verify["extrapolated"] = setting.label not in recorded
    extra = {"prior_source": f"identified ({results})", "verify": verify}
    write_plan(args.folder, design, extra=extra, controller=header)
    print(
        f"{args.folder}: verification of {results} ({setting.label}), {len(design.runs)} "
        f"runs, {design.duration / 60:.0f} min; {len(predictions)} staircases and {len(sines)} "
        "sines predicted; "
        f"{said}",
        file=out,
    )
    print(
        "  model error in the bands: levels {:.3g} mbar, FIT {:.3g} points, sine mean {:.3g} "
        "and amplitude {:.3g} mbar ({})".format(
            1e3 * error["level_bar"],
            error["fit_points"],
            1e3 * error["sine_mean_bar"],
            1e3 * error["sine_amplitude_bar"],
            error["measured_on"],
        ),
        file=out,
    )
    fixed = [kind for kind, c in verify["drift_check"].items() if not c["can_fail"]]
    if fixed:
        print(
            f"  warning: no ±50 % drift of t_on, t_off, k2 or tau2 moves the {', '.join(fixed)} "
            "predictions out of their bands: they cannot fail on this bench (plan.yaml: "
            "verify.drift_check)",
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
    print((Path(args.folder) / "checklist.md").read_text(encoding="utf-8"), file=out, end="")
    return 0


def _drift_check(
    design: Any,
    params: Any,
    staircases: dict[str, Any],
    sines: dict[str, Any],
    noise: float,
    cal: dict[str, Any],
) -> dict[str, dict[str, Any]]:
    """:func:`spa.plan.drift.drift_check` of a verification's staircases and sines."""
    from spa.plan.drift import drift_check
    from spa.plan.verify import sine_predictions, staircase_predictions

    runs = {run.id: run for run in design.runs}
    quantum = cal["bar_per_count"]

    def predict(rid: str, valve: Any) -> dict[str, Any]:
        make = staircase_predictions if rid in staircases else sine_predictions
        return make(runs[rid], design.dt, valve, {}, noise, quantum)

    return drift_check({**staircases, **sines}, predict, params)


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


def _model_error(results: Path, params: Any) -> dict[str, Any]:
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
    return recorded_model_error(runs, metas, params, where=str(folder))


def _sensor_noise(identified: Any) -> float:
    """The identification's sensor noise (bar), else :data:`VERIFY_NOISE`."""
    try:
        value = float(identified["noise"]["sensor"])
    except (KeyError, TypeError, ValueError):
        return VERIFY_NOISE
    return value if value > 0 else VERIFY_NOISE


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
    files = {r["id"]: folder / r["file"] for r in plan["runs"]}
    tables: dict[str, dict[str, Any]] = {"recommendation": {}, "promise": {}}
    for run_id, pred in verify["predictions"].items():
        if files[run_id].is_file():
            tables["recommendation"][run_id] = compare(pred, pd.read_csv(files[run_id]))
    for run_id, pred in (verify.get("sines") or {}).items():
        if files[run_id].is_file():
            tables["recommendation"][run_id] = compare_sine(pred, pd.read_csv(files[run_id]))
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
                )
    return tables


def _file_time(path: str) -> str | None:
    """When a saved stream was last written (UTC, to the minute); None for a serial port's
    device or a pipe (the session is being recorded now)."""
    import datetime
    import stat

    info = Path(path).stat()
    if not stat.S_ISREG(info.st_mode):
        return None
    when = datetime.datetime.fromtimestamp(info.st_mtime, datetime.UTC)
    return when.isoformat(timespec="minutes")


def run_record(args: argparse.Namespace, out: TextIO) -> int:
    """Split the stream into the plan's run files; print one line per run."""
    from spa.plan.limits import PlanError
    from spa.plan.record import record_stream

    try:
        if args.stream == "-":
            report = record_stream(args.folder, sys.stdin, args.recorded)
        else:
            with open(args.stream, encoding="ascii", errors="replace") as fh:
                report = record_stream(args.folder, fh, args.recorded or _file_time(args.stream))
    except (PlanError, ValueError, OSError) as exc:
        print(f"error: {exc}", file=out)
        return 1
    for line in report:
        print(line, file=out)
    from spa.plan.record import read_plan

    plan = read_plan(args.folder)
    if plan.get("verify"):
        from spa.plan.verify import verification_frame, verification_page

        frame = verification_frame(verification_tables(Path(args.folder), plan))
        csv = Path(args.folder) / "verification.csv"
        frame.to_csv(csv, index=False, float_format="%.6g")
        page = verification_page(plan["name"], frame)
        print(page, file=out)
        print(f"wrote {csv} (the dataset's report page shows it)", file=out)
        if args.page:
            Path(args.page).parent.mkdir(parents=True, exist_ok=True)
            Path(args.page).write_text(page, encoding="utf-8")
    print(f"next: spa validate {args.folder}", file=out)
    return 1 if any(line.startswith("missing") for line in report) else 0
