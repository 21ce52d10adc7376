"""The session round trip over the range, to the verification page (benchmarks/README.md,
"The session to record: the round trip to the verification page").

For each plant: a plan from what a lab knows (its supply and a rough fill time), with the
recommended setting's runs beside the identification runs (``--full``; else the pilot
alone) → the C player closed on the plant (the physical plant's C twin, tick by tick) →
spa record → spa validate → identify, tune and the closed loop's design, promise and
controller.h, in memory as the pipeline's stages → spa plan --verify → its runs, the
closed-loop staircases through controller.h, on the same plant and on one twice slower
(chamber, dead times and spool transit) → verification.csv. Prints one line per plant and
verification: the identification's cost and each part's kept count.

    .venv/bin/python benchmarks/verify_round_trip.py [--full] [phys-finger ...]

With ``--pipeline`` (a physical plant, the full plan) the middle is the pipeline itself: the
recorded folder is a bench dataset of a ``raw_dir`` of its own, ``snakemake reproduce-all``
processes it (figures off, no simulated dataset), ``spa plan --verify`` reads its results,
and a second ``reproduce-all`` processes the two verification folders, whose pages
(``results/report/<name>-verify-*.html``) are checked for both parts' verdicts.

A model-made valve (``small-fast``, ``large-slow``, ``long-exhaust``: the configuration's
``params``) goes through the pilot and the verification's open-loop runs, played on
``spa.simulate`` of the valve (the model has no C twin to close the loop on).
"""

from __future__ import annotations

import argparse
import dataclasses
import io
import subprocess
import tempfile
import time
from contextlib import redirect_stdout
from pathlib import Path

import numpy as np
import pandas as pd
import yaml

from spa.cli import main
from spa.closedloop.promise import design_for_dataset
from spa.datasets import ingest_dataset, read_runs
from spa.identification import identify_with_config
from spa.identification.identified import read_identified
from spa.io import dump_yaml
from spa.model.modulators import Modulator
from spa.plan.design import design_session
from spa.plan.folder import write_plan
from spa.plan.host import play_on_physical, session_ticks
from spa.plan.limits import Limits
from spa.plan.prior import prior_from_numbers
from spa.plan.record import record_stream
from spa.synthetic.runs import dataset_plant
from spa.tuning import tune

ROOT = Path(__file__).resolve().parents[1]
CONFIG = yaml.safe_load((ROOT / "config" / "config.yaml").read_text())
CLOSED_LOOP = {**CONFIG["closed_loop"], "levels_fraction": [0.2, 0.4, 0.6]}


def _cli(*argv: object) -> tuple[int, str]:
    buf = io.StringIO()
    with redirect_stdout(buf):
        code = main([str(a) for a in argv])
    return code, buf.getvalue()


def slower(plant, factor: float):
    """The plant ``factor`` times slower (chamber, dead times, spool transit)."""
    return dataclasses.replace(
        plant,
        volume=plant.volume * factor,
        compliance=plant.compliance * factor,
        t_open=plant.t_open * factor,
        t_close=plant.t_close * factor,
        transit=plant.transit * factor,
    )


def record(folder: Path, plant, seed: int) -> None:
    noise = np.random.default_rng(seed).normal(0.0, plant.noise, session_ticks(folder))
    stream, _ = play_on_physical(folder, plant, noise)
    report = record_stream(folder, stream.splitlines())
    bad = [line for line in report if not line.endswith("ok")]
    if bad:
        raise RuntimeError(f"{folder}: {bad}")
    code, text = _cli("validate", folder)
    if code != 0:
        raise RuntimeError(text)


def round_trip(name: str, root: Path, full: bool) -> list[str]:
    plant, equivalent = dataset_plant(CONFIG["simulated"][name])
    limits = Limits(p_max=1.25 * plant.supply)
    prior = prior_from_numbers(plant.supply, 5 * equivalent.tau2)
    rec0 = tune(prior).recommendation.get("recommended") or {}
    mod = Modulator.from_mapping(rec0["setting"]) if full and rec0.get("setting") else None
    design = design_session(
        prior, limits, levels=4, settings=[], recommended=mod, pilot=not full, precondition=1
    )
    folder = root / name
    write_plan(folder, design)
    record(folder, plant, 2)
    ingest_dataset(folder, root / "results" / name / "runs")  # as the pipeline's runs stage
    runs, metas = read_runs(root / "results" / name / "runs")
    t0 = time.perf_counter()
    kinds = {k: m["kind"] for k, m in metas.items()}
    identified = identify_with_config(runs, kinds, metas=metas).to_dict()
    t_id = time.perf_counter() - t0
    rec = dict(tune(read_identified(identified)).recommendation)
    selected = CONFIG["analytic"]["selected"]
    result, bench = design_for_dataset(identified, runs, metas, selected, CLOSED_LOOP, rec)
    results = root / "results" / name
    for sub in ("identification", "tuning", "closed_loop"):
        (results / sub).mkdir(parents=True)
    (results / "identification" / "params.yaml").write_text(dump_yaml(identified))
    (results / "tuning" / "recommendation.yaml").write_text(dump_yaml(rec))
    (results / "closed_loop" / "controllers.yaml").write_text(dump_yaml(result.controllers))
    (results / "closed_loop" / "controller.h").write_text(bench.header)
    promise = (result.controllers.get("bench") or {}).get("promise") or {}
    delays = ", ".join(
        f"{d} {identified[d]['value'] * 1e3:.1f} ms [{identified[d]['lo'] * 1e3:.1f}, "
        f"{identified[d]['hi'] * 1e3:.1f}]"
        for d in ("t_on", "t_off")
    )
    lines = [
        f"{name} ({'full' if full else 'pilot'}, {len(design.runs)} runs): identified in "
        f"{t_id:.0f} s; {delays}; promise made: {bool(promise.get('kept'))}"
    ]
    for tag, on in (("same", plant), ("2x slower", slower(plant, 2.0))):
        vfolder = verify_on(root / f"{name}-verify-{tag.replace(' ', '')}", results, limits, on)
        lines.append(f"  on the {tag} plant: " + "; ".join(kept_parts(vfolder)))
    return lines


def verify_on(vfolder: Path, results: Path, limits: Limits, on) -> Path:
    """``spa plan --verify`` of ``results`` into ``vfolder``, played on the plant ``on`` in C
    and recorded (``verification.csv``)."""
    code, text = _cli(
        "plan", vfolder, "--verify", results, "--p-max", f"{limits.p_max:g}",
        "--levels", "4", "--baud", "250000",
    )  # fmt: skip
    if code != 0:
        raise RuntimeError(text)
    noise = np.random.default_rng(5).normal(0.0, on.noise, session_ticks(vfolder))
    stream, _ = play_on_physical(vfolder, on, noise)
    log = vfolder.parent / f"{vfolder.name}.txt"
    log.write_text(stream)
    code, text = _cli("record", vfolder, "--stream", log)
    if code != 0:
        raise RuntimeError(text)
    return vfolder


def kept_parts(vfolder: Path) -> list[str]:
    """Each part's count of kept predictions in ``vfolder/verification.csv``."""
    frame = pd.read_csv(vfolder / "verification.csv")
    parts = []
    for part in ("recommendation", "promise"):
        rows = frame[frame["part"] == part]
        kept = int((rows["verdict"] == "kept").sum())
        parts.append(f"{part} {kept} of {len(rows)} kept")
    return parts


def round_trip_model(name: str, root: Path) -> list[str]:
    """A model-made valve of the full configuration (``simulated.<name>.params``): the pilot
    played by the C player on ``spa.simulate`` of the valve, identified, and the
    verification's open-loop runs (the recommendation; the model has no C twin to close the
    loop on) on the same valve and on one twice slower (``spa.plan.prior.scaled``)."""
    from spa import simulate
    from spa.model.params import ValveParams
    from spa.plan.folder import calibration_for
    from spa.plan.host import build_harness, planned_commands, play_session
    from spa.plan.prior import scaled
    from spa.plan.record import read_plan
    from spa.plan.verify import design_verification

    entry = CONFIG["simulated"][name]
    truth = ValveParams(**entry["params"])
    sd = float(entry.get("sensor", {}).get("noise", 0.003))
    limits = Limits(p_max=1.25 * truth.k2)
    design = design_session(
        prior_from_numbers(truth.k2, 5 * truth.tau2), limits, pilot=True, precondition=1
    )

    def play(folder: Path, d, valve, seed: int) -> str:
        exe = build_harness(folder, root / f"player-{folder.name}")
        noise = np.random.default_rng(seed).normal(0.0, sd, planned_commands(d).size)
        cal = calibration_for(limits.p_max)
        stream, _, _ = play_session(exe, d, lambda u: simulate(u, d.dt, valve), cal, noise)
        return stream

    folder = root / name
    write_plan(folder, design)
    record_stream(folder, play(folder, design, truth, 2).splitlines())
    code, text = _cli("validate", folder)
    if code != 0:
        raise RuntimeError(text)
    ingest_dataset(folder, root / "results" / name / "runs")
    runs, metas = read_runs(root / "results" / name / "runs")
    identified = identify_with_config(
        runs, {k: m["kind"] for k, m in metas.items()}, metas=metas
    ).to_dict()
    results = root / "results" / name
    (results / "identification").mkdir(parents=True)
    (results / "identification" / "params.yaml").write_text(dump_yaml(identified))
    within = all(
        identified[d]["lo"] <= getattr(truth, d) <= identified[d]["hi"]
        and abs(identified[d]["value"] - getattr(truth, d)) <= design.dt
        for d in ("t_on", "t_off")
    )
    lines = [f"{name} (model, pilot): delays within their intervals and one tick: {within}"]
    valve = read_identified(identified)
    for tag, on in (("same", truth), ("2x slower", scaled(truth, 2.0))):
        vfolder = root / f"{name}-verify-{tag.replace(' ', '')}"
        code, text = _cli(
            "plan", vfolder, "--verify", results, "--p-max", f"{limits.p_max:g}", "--levels", "4"
        )
        if code != 0:
            raise RuntimeError(text)
        plan = read_plan(vfolder)
        rec = Modulator.from_mapping(plan["verify"]["setting"])
        d = design_verification(valve.params, rec, limits, levels=4)
        log = root / f"{vfolder.name}.txt"
        log.write_text(play(vfolder, d, on, 5))
        code, text = _cli("record", vfolder, "--stream", log)
        if code != 0:
            raise RuntimeError(text)
        frame = pd.read_csv(vfolder / "verification.csv")
        kept = int((frame["verdict"] == "kept").sum())
        lines.append(f"  on the {tag} valve: recommendation {kept} of {len(frame)} kept")
    return lines


def reproduce_all(root: Path, strict: bool = True) -> list[str]:
    """``snakemake reproduce-all`` on the bench datasets of ``root/raw`` alone, into
    ``root/results`` (no simulated dataset, no figures); the lines naming a failed dataset
    (raised when ``strict``)."""
    override = root / "override.yaml"
    override.write_text(
        yaml.safe_dump(
            {
                "results": str(root / "results"),
                "simulated": dict.fromkeys(CONFIG.get("simulated") or {}),
                "datasets": {"raw_dir": str(root / "raw"), "exclude": []},
                "figures": "none",
            }
        )
    )
    cmd = [str(ROOT / ".venv" / "bin" / "snakemake"), "reproduce-all", "-c2"]
    res = subprocess.run(
        [*cmd, "--configfile", str(override), "--keep-going"],
        cwd=ROOT,
        capture_output=True,
        text=True,
    )
    failed = [ln.strip() for ln in res.stderr.splitlines() if ln.startswith("dataset ")]
    if res.returncode != 0 and (strict or not failed):
        raise RuntimeError(f"reproduce-all failed:\n{res.stderr[-3000:]}")
    return sorted(set(failed))


def round_trip_pipeline(name: str, root: Path) -> list[str]:
    """The full plan of a physical plant through the pipeline and back to its pages."""
    plant, equivalent = dataset_plant(CONFIG["simulated"][name])
    limits = Limits(p_max=1.25 * plant.supply)
    prior = prior_from_numbers(plant.supply, 5 * equivalent.tau2)
    rec0 = tune(prior).recommendation.get("recommended") or {}
    mod = Modulator.from_mapping(rec0["setting"]) if rec0.get("setting") else None
    design = design_session(
        prior, limits, levels=4, settings=[], recommended=mod, pilot=False, precondition=1
    )
    folder = root / "raw" / name
    write_plan(folder, design)
    record(folder, plant, 2)
    t0 = time.perf_counter()
    reproduce_all(root)
    results = root / "results" / name
    identified = yaml.safe_load((results / "identification" / "params.yaml").read_text())
    laws = (identified.get("laws") or {}).get("chosen")
    lines = [
        f"{name} (pipeline, {len(design.runs)} runs): reproduce-all "
        f"{time.perf_counter() - t0:.0f} s; laws {laws}"
    ]
    folders = {
        tag: verify_on(root / "raw" / f"{name}-verify-{tag.replace(' ', '')}", results, limits, on)
        for tag, on in (("same", plant), ("2x slower", slower(plant, 2.0)))
    }
    failed = reproduce_all(root, strict=False)
    lines += [f"  the pipeline on the verification: {line}" for line in failed]
    for tag, vfolder in folders.items():
        page = root / "results" / "report" / f"{vfolder.name}.html"
        html = page.read_text(encoding="utf-8") if page.is_file() else ""
        heads = [
            h
            for h in ("Verification: the recommendation", "Verification: the closed loop")
            if h in html
        ]
        lines.append(
            f"  on the {tag} plant: " + "; ".join(kept_parts(vfolder))
            + f"; its page {'shows' if heads else 'MISSING'} {', '.join(heads) or 'the verdicts'}"
        )
    return lines


def run() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("plants", nargs="*", default=["phys-finger", "phys-choked", "phys-balloon"])
    ap.add_argument("--full", action="store_true", help="the recommended setting's runs too")
    ap.add_argument(
        "--pipeline", action="store_true", help="through snakemake reproduce-all (physical plants)"
    )
    args = ap.parse_args()
    with tempfile.TemporaryDirectory(prefix="spa-verify-") as tmp:
        for name in args.plants:
            t0 = time.perf_counter()
            try:
                if args.pipeline:
                    lines = round_trip_pipeline(name, Path(tmp) / name)
                elif "params" in CONFIG["simulated"][name]:
                    lines = round_trip_model(name, Path(tmp))
                else:
                    lines = round_trip(name, Path(tmp), args.full)
            except (RuntimeError, ValueError, KeyError) as exc:
                lines = [f"{name}: failed: {exc}"]
            lines[0] += f" ({time.perf_counter() - t0:.0f} s in all)"
            print("\n".join(lines), flush=True)


if __name__ == "__main__":
    run()
