"""Command line: ``spa validate``, ``spa ingest``, ``spa init``, ``spa example``,
``spa identify``, ``spa tune``, ``spa design-pi``, ``spa export-controller``, ``spa plan`` and
``spa record``; ``spa --version``.

Exit status: 0 when every dataset is valid, 1 when any has an error, 2 for a usage error
(see ``spa --help``).
"""

from __future__ import annotations

import argparse
import inspect
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any, TextIO

__all__ = ["main"]

#: ``spa design-pi --tau-c``'s default, s: :data:`spa.closedloop.design.DEFAULT_TAU_C` (a test
#: checks they agree; the parser does not import the closed-loop package).
TAU_C = 0.2

_NUMBERS = dict(enumerate(["no", "one", "two", "three", "four", "five", "six", "seven", "eight",
                           "nine", "ten"]))  # fmt: skip


def _validate(args: argparse.Namespace, out: TextIO) -> int:
    """check dataset folders against the contract (raw/README.md)

    Check each dataset folder; print every problem, or one summary line per run. Exit 1 if any
    dataset has an error.
    """
    from spa.datasets import check_dataset

    status = 0
    for folder in args.folders:
        problems, summaries = check_dataset(folder)
        errors = [p for p in problems if p.is_error]
        warnings = [p for p in problems if not p.is_error]
        for p in problems:
            print(p, file=out)
        if errors:
            print(
                f"{folder}: INVALID, {len(errors)} error(s), {len(warnings)} warning(s)",
                file=out,
            )
            status = 1
            continue
        for s in summaries:
            print(s, file=out)
        print(f"{folder}: OK, {len(summaries)} run(s), {len(warnings)} warning(s)", file=out)
    return status


def _ingest(args: argparse.Namespace, out: TextIO) -> int:
    """validate a dataset and write one canonical run table per run

    Validate FOLDER, then write OUT_DIR/<run id>.parquet for each run.
    """
    from spa.datasets import DatasetError, ingest_dataset
    from spa.pipeline.safety import INGEST_MARKER, check_ingest_output

    try:
        target = check_ingest_output(args.out_dir, args.folder)
        paths = ingest_dataset(args.folder, args.out_dir)
    except DatasetError as exc:
        for p in exc.problems:
            print(p, file=out)
        print(
            f"{args.folder}: not ingested, {sum(p.is_error for p in exc.problems)} error(s)",
            file=out,
        )
        return 1
    except (ValueError, OSError) as exc:
        print(f"error: {exc}", file=out)
        return 1
    (target / INGEST_MARKER).write_text(f"run tables of {args.folder}, written by spa ingest\n")
    for path in paths:
        print(path, file=out)
    return 0


def _init(args: argparse.Namespace, out: TextIO) -> int:
    """draft dataset.yaml for a folder of recordings

    Read every data file of FOLDER and write FOLDER/dataset.yaml: a draft with guessed columns,
    units, kinds and modulators, each with its reason as a comment, and TODO where a guess
    failed; say, for each file it could not read, why. This is the one file spa writes into
    raw/; it never overwrites an existing dataset.yaml without --force and never touches data
    files.
    """
    from spa.datasets.draft_yaml import TODO, write_draft

    try:
        path, text, unread = write_draft(args.folder, force=args.force)
    except (OSError, ValueError) as exc:
        print(f"error: {exc}", file=out)
        return 1
    for file, why in unread.items():
        print(f"not read: {file}: {why}", file=out)
    todos = sum(f": {TODO}" in line for line in text.splitlines())
    runs = sum(line.startswith("  - id:") for line in text.splitlines())
    print(f"{path}: drafted {runs} run(s), {todos} TODO(s)", file=out)
    print(
        f"check the guesses (their reasons are comments), then: spa validate {args.folder}",
        file=out,
    )
    return 0


def _example(args: argparse.Namespace, out: TextIO) -> int:
    """write the example bench export (what raw/example holds)

    Simulate a small dataset laid out like a real bench export (CSV in ms and kPa with renamed
    columns, a MATLAB .mat run, a Parquet run) into FOLDER.
    """
    from spa.synthetic import write_example_dataset

    for path in write_example_dataset(args.folder, seed=args.seed):
        print(path, file=out)
    return 0


def _run_folder(folder: Path, tmp: Path) -> Path:
    """The folder of run tables of ``folder``: ingested into ``tmp`` from a bench dataset
    (``dataset.yaml``), ``runs/`` of a results folder, or ``folder`` itself."""
    from spa.datasets import ingest_dataset

    if (folder / "dataset.yaml").is_file():
        ingest_dataset(folder, tmp / "runs")  # validates first; raises DatasetError
        return tmp / "runs"
    if (folder / "runs").is_dir():
        return folder / "runs"
    if any(folder.glob("*.parquet")):
        return folder
    raise ValueError(
        f"{folder}: expected a bench dataset folder (with dataset.yaml, e.g. raw/example), a "
        "results folder with runs/ (results/<name>) or a folder of run tables (*.parquet)"
    )


def _identify(args: argparse.Namespace, out: TextIO) -> int:
    """identify a valve's parameters (95 % intervals) from a dataset

    Identify c1, k2, tau2, t_on and t_off (paper Section 3.2) from the charge, discharge and
    pulse runs of DATASET, as the workflow's identify rule does, without Snakemake; print them
    with their 95 % intervals. DATASET is a bench dataset folder (validated and ingested into a
    temporary folder; nothing is written next to it), a results folder with runs/
    (results/<name>) or a folder of run tables.
    """
    import json
    import tempfile

    import yaml

    from spa.datasets import DatasetError, read_runs
    from spa.datasets.checks import k2_warning
    from spa.identification import identify_with_config
    from spa.report.params import fits_note, identification_notes, params_table

    try:
        config = yaml.safe_load(Path(args.config).read_text()) if args.config else None
        with tempfile.TemporaryDirectory(prefix="spa-identify-") as tmp:
            runs, metas = read_runs(_run_folder(Path(args.dataset), Path(tmp)))
        kinds = {rid: m["kind"] for rid, m in metas.items()}
        result = identify_with_config(runs, kinds, config, seed=args.seed, metas=metas).to_dict()
    except DatasetError as exc:
        for p in exc.problems:
            print(p, file=out)
        print(f"{args.dataset}: not identified: the dataset has errors", file=out)
        return 1
    except (ValueError, OSError, yaml.YAMLError) as exc:
        print(f"error: {exc}", file=out)
        return 1
    if args.json:
        print(json.dumps(result, indent=2, default=float), file=out)
        return 0
    table = params_table(result).drop(columns="method")
    print(f"{args.dataset}: {len(runs)} run(s); 95 % intervals", file=out)
    print(table.to_string(index=False, float_format=lambda x: f"{x:.5g}"), file=out)
    supply = dict((config or {}).get("datasets") or {}).get("plausible_supply_bar")
    k2 = result.get("k2")
    k2 = k2.get("value") if isinstance(k2, dict) else k2
    warning = k2_warning(k2, metas, supply) if isinstance(k2, int | float) else None
    if warning:
        print(f"warning: {warning}", file=out)
    note = fits_note(result).strip()
    if note:
        print(note, file=out)
    for line in identification_notes(result):
        print(line, file=out)
    return 0


def _plan(args: argparse.Namespace, out: TextIO) -> int:
    """plan a bench session and write its player for the board

    Write a session plan into FOLDER (new); print its predicted precision.
    """
    from spa.plan.command import run_plan

    return run_plan(args, out)


def _record(args: argparse.Namespace, out: TextIO) -> int:
    """split the player's stream into run files

    Read the board's stream (a file, a serial port's device or stdin), write each run's file
    of FOLDER/plan.yaml with the declared calibration, and flag dropped lines, overruns and
    vents.
    """
    from spa.plan.command import run_record

    return run_record(args, out)


def _version() -> str:
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("spa")
    except PackageNotFoundError:  # run from a source tree that is not installed
        import spa

        return spa.__version__


def _tune(args: argparse.Namespace, out: TextIO) -> int:
    """tune the {count} modulators for a valve, recommend a setting

    Sweep the parameter of each of the {count} modulators ({names}) for the valve of PARAMS.yaml
    (an identification's params.yaml, whose 95 % intervals are propagated) or of the five
    parameters given; print Table 2 in brief (each modulator's optimum, its costs and
    chattering, and whether it lies at an end of its sweep) and the recommended setting; --yaml
    or --json print all of Table 2 and the recommendation. Exit 1 for a valve that cannot be
    tuned.
    """
    import yaml

    from spa.tuning import format_result, tune_with_config

    given = {k: getattr(args, k) for k in ("c1", "k2", "tau2", "t_on", "t_off")}
    missing = [f"--{k.replace('_', '-')}" for k, v in given.items() if v is None]
    if (args.params is None and missing) or (args.params is not None and len(missing) < 5):
        what = f"missing {' '.join(missing)}" if args.params is None else "not both"
        print(
            f"error: give PARAMS.yaml or all of --c1 --k2 --tau2 --t-on --t-off ({what})", file=out
        )
        return 2
    try:
        config = yaml.safe_load(Path(args.config).read_text()) if args.config else None
        result = tune_with_config(args.params or given, config, score=args.score)
    except (ValueError, OSError, yaml.YAMLError) as exc:
        print(f"error: {exc}", file=out)
        return 1
    print(format_result(result, as_json=args.json, as_yaml=args.yaml), file=out, end="")
    return 0


def _design_pi(args: argparse.Namespace, out: TextIO) -> int:
    """PI gains for a valve and a modulator setting (closed loop)

    Design a fixed and a gain-scheduled PI (SIMC on the averaged model's local gain, time
    constant and dead time) for the valve of PARAMS.yaml and one modulator setting; print the
    gains and the exact simulation of the set-point staircase (docs/model.md section 8).
    """
    from spa.closedloop.describe import design_summary, format_design, parse_modulator_spec
    from spa.identification.identified import read_identified

    try:
        mod = parse_modulator_spec(args.modulator)
        levels = [float(v) for v in args.levels.split(",")] if args.levels else None
        summary = design_summary(
            read_identified(str(args.params)).params, mod, tau_c=args.tau_c, levels=levels
        )
    except (ValueError, OSError) as exc:
        print(f"error: {exc}", file=out)
        return 1
    print(format_design(summary, as_json=args.json), file=out)
    return 0


def stage_choice(params_path: str | Path) -> dict[str, Any] | None:
    """The ``closed_loop`` stage's ``controllers.yaml`` for a ``params.yaml`` inside a
    results folder (``<ds>/identification/params.yaml`` -> ``<ds>/closed_loop/``, or beside
    it), or None when there is none."""
    import yaml

    here = Path(params_path).resolve().parent
    for folder in (here.parent / "closed_loop", here):
        path = folder / "controllers.yaml"
        if path.is_file():
            data = yaml.safe_load(path.read_text(encoding="utf-8"))
            return data if isinstance(data, dict) else None
    return None


def _export_controller(args: argparse.Namespace, out: TextIO) -> int:
    """C99 header and Arduino sketch of a designed PI

    Design the PIs for the valve of PARAMS.yaml and one modulator setting (as design-pi) and
    write one of them, with the modulator's per-step law, as OUT/controller.h (dependency-free
    C99: init and step(r, p) -> valve, xi, the step as a constant) and OUT/controller.ino (where
    the sensor read and valve write go).
    """
    from spa.closedloop.describe import parse_modulator_spec
    from spa.closedloop.export import export_designed
    from spa.identification.identified import read_identified
    from spa.model.modulators import Modulator

    try:
        identified = read_identified(str(args.params))
        valve = identified.params
        stage = stage_choice(args.params) or {}
        chosen = (
            Modulator.from_mapping(stage["setting"]).bind(valve) if "setting" in stage else None
        )
        if args.modulator:
            mod = parse_modulator_spec(args.modulator).bind(valve)
        elif chosen is not None:
            mod = chosen
        else:
            raise ValueError(
                "--modulator is needed: no closed_loop/controllers.yaml with a chosen setting "
                f"beside {args.params}"
            )
        controller = args.controller or str(stage.get("controller") or "scheduled_ff")
        tau_c, levels = args.tau_c, None
        if args.levels:
            levels = [float(v) for v in args.levels.split(",")]
        same = chosen is not None and mod.to_mapping() == chosen.to_mapping()
        if same:
            promise = (stage.get("bench") or {}).get("promise") or {}
            entry = (stage.get("controllers") or {}).get(mod.label) or {}
            if tau_c is None:
                tau_c = promise.get("tau_c", stage.get("tau_c"))
            if levels is None and entry.get("levels"):
                levels = [float(v) for v in entry["levels"]]
        header, sketch = export_designed(
            args.out,
            valve,
            mod,
            controller=controller,
            tau_c=TAU_C if tau_c is None else float(tau_c),
            levels=levels,
            dt=args.dt,
            precision=args.precision,
            unresolved=identified.unresolved,
        )
    except (ValueError, OSError) as exc:
        print(f"error: {exc}", file=out)
        return 1
    print(f"wrote {header} and {sketch} ({mod.label}, {controller} PI)", file=out)
    return 0


#: A command name longer than this does not widen the name column: its help follows it after
#: two spaces on the same line (``export-controller``).
_LONG_NAME = 12


class _Formatter(argparse.HelpFormatter):
    """argparse's formatter, counting the commands' own indent (so ``design-pi`` fits),
    keeping the column of the short names when one name is long, and adding
    ``(default: X)`` to an option's help where it has a value and does not say it."""

    def _get_help_string(self, action: argparse.Action) -> str:
        text = action.help or ""
        shown = action.default not in (None, False, argparse.SUPPRESS)
        if shown and action.option_strings and "default" not in text:
            text += " (default: %(default)s)"
        return text

    def add_argument(self, action: argparse.Action) -> None:
        before = self._action_max_length
        super().add_argument(action)
        if isinstance(action, argparse._SubParsersAction):
            short = [len(name) for name in action.choices if len(name) <= _LONG_NAME]
            width = max(short, default=0) + self._current_indent + 4
            self._action_max_length = max(before, width)

    def _format_action(self, action: argparse.Action) -> str:
        header = self._format_action_invocation(action)
        position = min(self._action_max_length + 2, self._max_help_position)
        if action.help and len(header) > position - self._current_indent - 2:
            line = f"{' ' * self._current_indent}{header}  {self._expand_help(action)}"
            if len(line) <= self._width:
                return line + "\n"
        return super()._format_action(action)


#: The modulator setting's syntax on the command line, with an example.
_MODULATOR = ("KIND:NAME=VALUE,...", "e.g. iipfm:t_l=0.02,gain=1.15 or pwm:f_w=20")


def _folder(p: argparse.ArgumentParser, dest: str = "folder", help: str = "") -> None:
    """The dataset folder argument (``FOLDER``)."""
    p.add_argument(dest, metavar="FOLDER", help=help or "dataset folder, raw/<name>")


def _params(p: argparse.ArgumentParser, **kwargs: Any) -> None:
    """The identified parameters' file (``PARAMS.yaml``)."""
    p.add_argument("params", metavar="PARAMS.yaml", help="identified parameters", **kwargs)


def _config(p: argparse.ArgumentParser, takes: str, otherwise: str) -> None:
    """``--config CONFIG.yaml``, which ``takes`` these sections (else ``otherwise``)."""
    p.add_argument(
        "--config",
        metavar="CONFIG.yaml",
        help=f"take {takes} from this configuration (default: none, {otherwise})",
    )


def _setting(
    p: argparse.ArgumentParser, levels: str, tau_c: float | None, tau_c_default: str = ""
) -> None:
    """The design's ``--tau-c`` (default ``tau_c``, described by ``tau_c_default``) and
    ``--levels`` (whose default ``levels`` describes)."""
    p.add_argument(
        "--tau-c", type=float, default=tau_c, help="closed-loop time constant, s" + tau_c_default
    )
    p.add_argument("--levels", metavar="R1,R2,...", help=f"set-points, bar (default: {levels})")


def _parser() -> argparse.ArgumentParser:
    from spa.model.modulators import get_kind, kinds

    names = [get_kind(k).name for k in kinds()]
    count = _NUMBERS.get(len(names), str(len(names)))
    parser = argparse.ArgumentParser(
        prog="spa",
        formatter_class=_Formatter,
        description="Soft pneumatic actuator characterisation: dataset tools. The pipeline "
        "itself runs with `snakemake reproduce-all`.",
        epilog="`spa COMMAND --help` describes a command's arguments.",
    )
    parser.add_argument("--version", action="version", version=f"spa {_version()}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", title="commands")

    def command(name: str, func: Any, **fill: str) -> argparse.ArgumentParser:
        """The sub-command ``name`` that ``func`` runs: its help is the first line of
        ``func``'s docstring, its description the rest (``{key}`` filled from ``fill``)."""
        doc = inspect.cleandoc(func.__doc__ or "")
        summary, _, rest = (doc.format(**fill) if fill else doc).partition("\n\n")
        p = sub.add_parser(
            name,
            formatter_class=_Formatter,
            help=summary.replace("%", "%%"),
            description=" ".join(rest.split()),
        )
        p.set_defaults(func=func)
        return p

    p = command("validate", _validate)
    p.add_argument("folders", nargs="+", metavar="FOLDER", help="dataset folder, raw/<name>")
    p = command("ingest", _ingest)
    _folder(p)
    p.add_argument("out_dir", metavar="OUT_DIR", help="output folder (not inside raw/)")
    p = command("init", _init)
    _folder(p)
    p.add_argument("--force", action="store_true", help="replace an existing dataset.yaml")
    p = command("example", _example)
    _folder(p, help="destination, e.g. raw/example")
    p.add_argument("--seed", type=int, default=2025, help="noise seed")
    p = command("identify", _identify)
    p.add_argument("dataset", metavar="DATASET", help="raw/<name>, results/<name> or a runs/")
    _config(p, "identification:, nominal: and seed:", "the built-in defaults")
    p.add_argument("--seed", type=int, help="bootstrap seed (default: the config's, else 0)")
    p.add_argument("--json", action="store_true", help="print params.yaml's content as JSON")
    p = command("tune", _tune, count=count, names=", ".join(names))
    _params(p, nargs="?")
    for name, unit in (
        ("c1", "s*bar^-0.5"),
        ("k2", "bar"),
        ("tau2", "s"),
        ("t-on", "s"),
        ("t-off", "s"),
    ):
        p.add_argument(
            f"--{name}", type=float, help=f"{name} in {unit} (no default: all five or PARAMS.yaml)"
        )
    _config(p, "sweeps, n_xi and the tuning: section", "the paper's grids")
    p.add_argument(
        "--score",
        choices=["J", "J_exact"],
        help="cost minimised (default: the config's tuning.score, else J)",
    )
    what = p.add_mutually_exclusive_group()
    what.add_argument(
        "--yaml", action="store_true", help="print all of Table 2 and the recommendation as YAML"
    )
    what.add_argument("--json", action="store_true", help="the same as JSON, for scripts")
    p = command("design-pi", _design_pi)
    _params(p)
    p.add_argument("--modulator", required=True, metavar=_MODULATOR[0], help=_MODULATOR[1])
    _setting(p, "fractions 0.1-0.8 of k2 that the setting holds", TAU_C)
    p.add_argument("--json", action="store_true", help="print JSON for scripts")
    p = command("export-controller", _export_controller)
    _params(p)
    p.add_argument(
        "--modulator",
        metavar=_MODULATOR[0],
        help=f"{_MODULATOR[1]} (default: the closed_loop stage's choice when PARAMS.yaml is in a "
        "results folder); an LPWM without its valve inverts the valve of PARAMS.yaml",
    )
    p.add_argument(
        "--controller",
        choices=["fixed", "scheduled", "scheduled_ff"],
        default=None,
        help="which design (default: the closed_loop stage's choice when PARAMS.yaml is in "
        "a results folder, else scheduled_ff: gain-scheduled with feed-forward)",
    )
    _setting(
        p,
        "the stage's for its chosen setting, else spread over the range the setting holds",
        None,
        " (default: the stage's shipped one for its chosen setting, else 0.2)",
    )
    p.add_argument("--dt", type=float, default=0.001, help="controller step, s")
    p.add_argument(
        "--precision",
        choices=["double", "single"],
        default="double",
        help="the PI's arithmetic: double (default, the simulation's to the bit) or single "
        "(float, for single-precision FPUs)",
    )
    p.add_argument("--out", required=True, metavar="DIR", help="output folder")
    from spa.plan.command import plan_arguments, record_arguments

    plan_arguments(command("plan", _plan))
    record_arguments(command("record", _record))
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run the ``spa`` command line; return the exit status.

    Parameters
    ----------
    argv : sequence of str, optional
        Arguments after the program name; default ``sys.argv[1:]``.

    Returns
    -------
    int
        0 on success, 1 if a dataset has an error, 2 for a usage error.
    """
    from spa._guard import ShadowedPackageError, check_package

    try:
        check_package()
    except ShadowedPackageError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    parser = _parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as exc:  # argparse exits on --help and on usage errors
        return int(exc.code or 0)
    if args.command is None:
        parser.print_help(sys.stderr)
        return 2
    return int(args.func(args, sys.stdout))
