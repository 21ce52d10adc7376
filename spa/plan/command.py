"""``spa plan`` and ``spa record``: their arguments and what they run (spa/cli.py adds the
sub-commands)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any, TextIO

__all__ = ["plan_arguments", "record_arguments", "run_plan", "run_record"]


def plan_arguments(p: argparse.ArgumentParser) -> None:
    """``spa plan``'s arguments."""
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
        "--page",
        metavar="PAGE.md",
        help="a verification's predictions beside the measurements (default: none)",
    )


def run_plan(args: argparse.Namespace, out: TextIO) -> int:
    """Design, predict and write a plan; print its summary."""
    from spa.model.modulators import Modulator
    from spa.model.params import ValveParams
    from spa.plan.design import design_session
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
        design = design_session(
            prior,
            limits,
            dt=args.tick,
            seed=args.seed,
            levels=args.levels,
            replicates=args.replicates,
            recommended=recommended,
            pilot=args.pilot,
        )
        extra: dict = {
            "prior_source": source,
            "margins": {
                "time_scale": design.margins["time_scale"],
                "meaning": "identification runs sized for valves 3x slower "
                "and 3x faster than the prior",
            },
        }
        table = None
        if not args.no_predict:
            from spa.plan.precision import predict_precision

            table = predict_precision(design, calibration_for(limits.p_max))
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
    if table is not None:
        print("predicted 95 % half-widths (target) on the prior and 3x corners:", file=out)
        for corner, rows in table.groupby("corner", sort=False):
            cells = ", ".join(
                f"{r.parameter} {r.half_width:.2g} ({r.target:.2g}){'' if r.met else ' MISSED'}"
                for r in rows.itertuples()
            )
            print(f"  {corner}: {cells}", file=out)
    print((Path(args.folder) / "checklist.md").read_text(encoding="utf-8"), file=out, end="")
    return 0


#: The sensor noise a verification's bands assume, bar (stated in plan.yaml).
VERIFY_NOISE = 0.005


def _verify_plan(args: argparse.Namespace, limits: Any, out: TextIO) -> int:
    """``spa plan FOLDER --verify RESULTS``: the recommended setting's runs on the identified
    valve, with each staircase's predicted levels and FIT in plan.yaml."""
    import yaml

    from spa.identification.identified import read_identified
    from spa.model.modulators import Modulator
    from spa.plan.folder import calibration_for, write_plan
    from spa.plan.verify import design_verification, staircase_predictions

    results = Path(args.verify)
    valve = read_identified(str(results / "identification" / "params.yaml"))
    rec_path = results / "tuning" / "recommendation.yaml"
    rec = yaml.safe_load(rec_path.read_text(encoding="utf-8")) if rec_path.is_file() else None
    if not rec or not (rec.get("recommended") or {}).get("setting"):
        from spa.tuning import tune

        rec = dict(tune(valve).recommendation)
    setting = Modulator.from_mapping(rec["recommended"]["setting"])
    design = design_verification(
        valve.params,
        setting,
        limits,
        dt=args.tick,
        levels=args.levels,
        replicates=args.replicates,
        seed=args.seed,
    )
    cal = calibration_for(limits.p_max)
    predictions = {
        run.id: staircase_predictions(
            run,
            design.dt,
            valve.params,
            dict(valve.intervals),
            VERIFY_NOISE,
            cal["bar_per_count"],
        )
        for run in design.runs
        if run.kind == "staircase"
    }
    extra = {
        "prior_source": f"identified ({results})",
        "verify": {
            "results": str(results),
            "setting": setting.to_mapping(),
            "sensor_noise_bar": VERIFY_NOISE,
            "predictions": predictions,
        },
    }
    write_plan(args.folder, design, extra=extra)
    print(
        f"{args.folder}: verification of {results} ({setting.label}), {len(design.runs)} "
        f"runs, {design.duration / 60:.0f} min; {len(predictions)} staircases predicted",
        file=out,
    )
    print((Path(args.folder) / "checklist.md").read_text(encoding="utf-8"), file=out, end="")
    return 0


def verification_tables(folder: Path, plan: dict[str, Any]) -> dict[str, Any]:
    """Each predicted staircase of a verification plan against its recording."""
    import pandas as pd

    from spa.plan.verify import compare

    files = {r["id"]: folder / r["file"] for r in plan["runs"]}
    return {
        run_id: compare(pred, pd.read_csv(files[run_id]))
        for run_id, pred in plan["verify"]["predictions"].items()
        if files[run_id].is_file()
    }


def run_record(args: argparse.Namespace, out: TextIO) -> int:
    """Split the stream into the plan's run files; print one line per run."""
    from spa.plan.limits import PlanError
    from spa.plan.record import record_stream

    try:
        if args.stream == "-":
            report = record_stream(args.folder, sys.stdin)
        else:
            with open(args.stream, encoding="ascii", errors="replace") as fh:
                report = record_stream(args.folder, fh)
    except (PlanError, ValueError, OSError) as exc:
        print(f"error: {exc}", file=out)
        return 1
    for line in report:
        print(line, file=out)
    from spa.plan.record import read_plan

    plan = read_plan(args.folder)
    if plan.get("verify"):
        from spa.plan.verify import verification_page

        page = verification_page(plan["name"], verification_tables(Path(args.folder), plan))
        print(page, file=out)
        if args.page:
            Path(args.page).parent.mkdir(parents=True, exist_ok=True)
            Path(args.page).write_text(page, encoding="utf-8")
    print(f"next: spa validate {args.folder}", file=out)
    return 1 if any(line.startswith("missing") for line in report) else 0
