"""``spa plan`` and ``spa record``: their arguments and what they run (spa/cli.py adds the
sub-commands)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any, TextIO

from spa.plan.verify_command import recorded_settings, verification_tables, verify_plan

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
            return verify_plan(args, limits, out)
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
        level = (plan["verify"].get("session") or {}).get("level")
        page = verification_page(plan["name"], frame, level)
        print(page, file=out)
        print(f"wrote {csv} (the dataset's report page shows it)", file=out)
        if args.page:
            Path(args.page).parent.mkdir(parents=True, exist_ok=True)
            Path(args.page).write_text(page, encoding="utf-8")
    print(f"next: spa validate {args.folder}", file=out)
    return 1 if any(line.startswith("missing") for line in report) else 0
