"""The session round trip over the range, to the verification page (benchmarks/README.md,
"The session to record: the round trip to the verification page").

For each plant: a plan from what a lab knows (its supply and a rough fill time), with the
settings ``spa plan`` records by default beside the identification runs (``--full``: the
recommended setting, its neighbours and the paper's four at the valve's scale; else the
pilot alone) → the C player closed on the plant tick by tick (the physical plant's C twin, or
spa's model plant in C for a model-made valve: ``spa.plan.host.play_on_plant``) →
spa record → spa validate → identify, tune and the closed loop's design, promise and
controller.h, in memory as the pipeline's stages → spa plan --verify → its runs, the
closed-loop staircases through controller.h, on the same plant and on one twice slower
(chamber, dead times and spool transit; a model-made valve ``spa.plan.prior.scaled``) →
verification.csv (``spa.plan.roundtrip.verify_on``); ``--drifts`` adds a plant with its
exhaust's conductance halved or its supply 20 % lower (:data:`DRIFTS`). Prints one line per
plant and verification: the identification's cost and each part's kept count; for a
model-made valve, whether the identified delays lie within their intervals and one logging
step of the truth.

    .venv/bin/python benchmarks/verify_round_trip.py [--full] [--csv FILE] [--drifts D,...]
        [phys-finger ...]

With ``--pipeline`` (a physical plant, the full plan) the middle is the pipeline itself: the
recorded folder is a bench dataset of a ``raw_dir`` of its own, ``snakemake reproduce-all``
processes it (figures off, no simulated dataset), ``spa plan --verify`` reads its results,
and a second ``reproduce-all`` processes the two verification folders, whose pages
(``results/report/<name>-verify-*.html``) are checked for both parts' verdicts.

A model-made valve (``small-fast``, ``large-slow``, ``long-exhaust``: the configuration's
``params``) goes through the same round trip, played on spa's model plant in C
(``spa/synthetic/model_plant.c``, equal to ``spa.simulate`` to 1e-12 bar).
"""

from __future__ import annotations

import argparse
import dataclasses
import io
import json
import subprocess
import tempfile
import time
from contextlib import redirect_stdout
from pathlib import Path

import numpy as np
import pandas as pd
import yaml

from spa.cli import main
from spa.model.modulators import Modulator
from spa.model.params import ValveParams
from spa.plan.design import design_session
from spa.plan.folder import write_plan
from spa.plan.host import play_on_plant, session_ticks
from spa.plan.limits import Limits
from spa.plan.prior import prior_from_numbers, scaled
from spa.plan.record import record_stream
from spa.plan.roundtrip import stages_in_memory, verify_on
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


#: The drifts a verification is played on besides the same plant (``--drifts``).
DRIFTS = ("2x slower", "exhaust halved", "supply -20%")


def drifted(plant, tag: str):
    """The plant after a drift: ``2x slower`` (:func:`slower`; a model-made valve
    ``spa.plan.prior.scaled``), ``exhaust halved`` (the exhaust's conductance halved; a
    model-made valve's ``tau2`` doubled) or ``supply -20%`` (the supply, or ``k2``, times
    0.8)."""
    model = isinstance(plant, ValveParams)
    if tag == "2x slower":
        return scaled(plant, 2.0) if model else slower(plant, 2.0)
    if tag == "exhaust halved":
        if model:
            return dataclasses.replace(plant, tau2=2.0 * plant.tau2)
        return dataclasses.replace(plant, c_exhaust=0.5 * plant.c_exhaust)
    if tag == "supply -20%":
        if model:
            return dataclasses.replace(plant, k2=0.8 * plant.k2)
        return dataclasses.replace(plant, supply=0.8 * plant.supply)
    raise ValueError(f"drift {tag!r}: expected one of {', '.join(DRIFTS)}")


def plant_of(name: str) -> tuple[object, float, float, float, object, str]:
    """The configuration's dataset ``name`` as a plant to play on: a physical plant (its C
    twin) or a model-made valve (``params``: spa's model plant in C); its supply, its
    charge's time constant, its sensor's noise (bar), the plant twice slower, and what it is.
    ``random:<k>`` is the physical plant :func:`spa.synthetic.draws.random_plant` draws from
    the seed ``[61, k]``: balloons, leaks, bounce, tube and sensor lags, none in the
    configuration."""
    if name.startswith("random:"):  # a plant no configuration holds: spa has not seen it
        from spa.synthetic.draws import random_plant
        from spa.synthetic.physical import equivalent_params

        plant = random_plant(np.random.default_rng([61, int(name.split(":")[1])]))
        equivalent = equivalent_params(plant)
        return plant, plant.supply, equivalent.tau2, plant.noise, slower(plant, 2.0), "random"
    entry = CONFIG["simulated"][name]
    if "params" in entry:
        truth = ValveParams(**entry["params"])
        sd = float((entry.get("sensor") or {}).get("noise", 0.003))
        return truth, truth.k2, truth.tau2, sd, scaled(truth, 2.0), "model"
    plant, equivalent = dataset_plant(entry)
    return plant, plant.supply, equivalent.tau2, plant.noise, slower(plant, 2.0), "physical"


def record(folder: Path, plant, seed: int, sd: float) -> None:
    noise = np.random.default_rng(seed).normal(0.0, sd, session_ticks(folder))
    stream, _ = play_on_plant(folder, plant, noise)
    report = record_stream(folder, stream.splitlines())
    bad = [line for line in report if not line.endswith("ok")]
    if bad:
        raise RuntimeError(f"{folder}: {bad}")
    code, text = _cli("validate", folder)
    if code != 0:
        raise RuntimeError(text)


def round_trip(
    name: str,
    root: Path,
    full: bool,
    rows: list | None = None,
    drifts: tuple[str, ...] = DRIFTS[:1],
) -> list[str]:
    """A plant of the full configuration (physical, or a model-made valve) through the
    round trip: the plan played on its C twin, the stages in memory, and the verification
    (its closed-loop staircases through controller.h) on the same plant and after each of
    ``drifts`` (:func:`drifted`)."""
    plant, supply, tau2, sd, _, what = plant_of(name)
    limits = Limits(p_max=1.25 * supply)
    prior = prior_from_numbers(supply, 5 * tau2)
    rec0 = tune(prior).recommendation.get("recommended") or {}
    mod = Modulator.from_mapping(rec0["setting"]) if full and rec0.get("setting") else None
    design = design_session(
        prior, limits, levels=4, recommended=mod, pilot=not full, precondition=1
    )
    safe = name.replace(":", "-")  # a folder's and a dataset's name
    folder = root / safe
    write_plan(folder, design)
    record(folder, plant, 2, sd)
    t0 = time.perf_counter()
    results = root / "results" / safe
    stages = stages_in_memory(folder, results, CONFIG["analytic"]["selected"], CLOSED_LOOP)
    t_id = time.perf_counter() - t0
    identified, promise = stages["identified"], stages["promise"]
    delays = ", ".join(
        f"{d} {identified[d]['value'] * 1e3:.1f} ms [{identified[d]['lo'] * 1e3:.1f}, "
        f"{identified[d]['hi'] * 1e3:.1f}]"
        for d in ("t_on", "t_off")
    )
    lines = [
        f"{name} ({what}, {'full' if full else 'pilot'}, {len(design.runs)} runs): identified, "
        f"tuned, closed loop in {t_id:.0f} s; {delays}; promise made: {bool(promise.get('kept'))}"
    ]
    if isinstance(plant, ValveParams):
        within = {
            d: identified[d]["lo"] <= getattr(plant, d) <= identified[d]["hi"]
            and abs(identified[d]["value"] - getattr(plant, d)) <= design.dt
            for d in ("t_on", "t_off")
        }
        lines.append(
            f"  truth t_on {plant.t_on * 1e3:g} ms, t_off {plant.t_off * 1e3:g} ms; within "
            f"their intervals and one {design.dt * 1e3:g} ms tick: {within}"
        )
    for tag, on in (("same", plant), *((d, drifted(plant, d)) for d in drifts)):
        vfolder = root / f"{safe}-verify-{tag.replace(' ', '').replace('%', '')}"
        frame = verify_on(vfolder, results, on, limits.p_max, noise_sd=sd).frame
        lines.append(f"  on the {tag} plant: " + "; ".join(kept_parts(frame)))
        again = session_agreement(vfolder, identified) if tag == "same" else {}
        if again:
            said = [f"{n} {'overlaps' if again[n + '_overlap'] else 'DISJOINT'}" for n in NAMES]
            lines.append("  the verification session's own intervals: " + ", ".join(said))
        if rows is not None:
            rows.append({**summary_row(name, what, identified, promise, tag, frame), **again})
    return lines


#: The identified parameters whose intervals two sessions of one plant should share.
NAMES = ("c1", "k2", "tau2", "t_on", "t_off")


def session_agreement(folder: Path, identified: dict) -> dict:
    """The verification session ``folder`` identified on its own (``spa identify --json``,
    the full configuration) against the full session's ``identified``: each parameter's
    interval and whether the two overlap (the overview flags a change where they do not,
    ``spa.report.overview.interval_changes``); empty when it does not identify."""
    code, text = _cli("identify", folder, "--config", ROOT / "config" / "config.yaml", "--json")
    if code != 0:
        return {}
    again = json.loads(text)
    out: dict = {}
    for n in NAMES:
        a, b = identified[n], again[n]
        out[f"verify_{n}_lo"], out[f"verify_{n}_hi"] = float(b["lo"]), float(b["hi"])
        out[f"{n}_overlap"] = bool(b["lo"] <= a["hi"] and a["lo"] <= b["hi"])
    return out


def summary_row(name, what, identified, promise, tag, frame) -> dict:
    """One verification of one plant as a row of ``--csv``: the identified delays, each
    part's kept and total predictions, and whether the session's verdict broke (any
    prediction outside its band at the session's level)."""
    row = {"plant": name, "kind": what, "verified_on": tag}
    for d in ("t_on", "t_off"):
        row[f"{d}_ms"] = round(1e3 * identified[d]["value"], 3)
        row[f"{d}_lo_ms"] = round(1e3 * identified[d]["lo"], 3)
        row[f"{d}_hi_ms"] = round(1e3 * identified[d]["hi"], 3)
    row["promise_levels"] = len(promise.get("levels") or [])
    for part in ("recommendation", "promise"):
        rows = frame[frame["part"] == part]
        row[f"{part}_kept"] = int((rows["verdict"] == "kept").sum())
        row[f"{part}_n"] = len(rows)
    row["session_broken"] = bool((frame["session"] == "outside").any())
    return row


def kept_parts(frame: pd.DataFrame) -> list[str]:
    """Each part's count of kept predictions in a ``verification.csv``."""
    parts = []
    for part in ("recommendation", "promise"):
        rows = frame[frame["part"] == part]
        kept = int((rows["verdict"] == "kept").sum())
        parts.append(f"{part} {kept} of {len(rows)} kept")
    return parts


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


def full_plan(supply: float, tau2: float) -> tuple[Limits, object]:
    """The limits and the full plan a lab gets from its supply and a rough fill time
    (``5 tau2``): the identification runs and the prior's recommended setting."""
    limits = Limits(p_max=1.25 * supply)
    prior = prior_from_numbers(supply, 5 * tau2)
    rec0 = tune(prior).recommendation.get("recommended") or {}
    mod = Modulator.from_mapping(rec0["setting"]) if rec0.get("setting") else None
    design = design_session(prior, limits, levels=4, recommended=mod, pilot=False, precondition=1)
    return limits, design


def round_trip_pipeline(name: str, root: Path) -> list[str]:
    """The full plan of a physical plant through the pipeline and back to its pages."""
    plant, supply, tau2, sd, slow, _ = plant_of(name)
    limits, design = full_plan(supply, tau2)
    folder = root / "raw" / name
    write_plan(folder, design)
    record(folder, plant, 2, sd)
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
        tag: verify_on(
            root / "raw" / f"{name}-verify-{tag.replace(' ', '')}",
            results,
            on,
            limits.p_max,
            noise_sd=sd,
        ).folder
        for tag, on in (("same", plant), ("2x slower", slow))
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
            f"  on the {tag} plant: "
            + "; ".join(kept_parts(pd.read_csv(vfolder / "verification.csv")))
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
    ap.add_argument("--keep", metavar="DIR", help="work in DIR (kept), not a temporary folder")
    ap.add_argument("--csv", metavar="FILE", help="one row per plant and verification")
    ap.add_argument(
        "--drifts",
        default=DRIFTS[0],
        help="comma-separated drifts verified besides the same plant, of: "
        + ", ".join(DRIFTS).replace("%", "%%"),
    )
    args = ap.parse_args()
    rows: list = []
    with tempfile.TemporaryDirectory(prefix="spa-verify-") as scratch:
        tmp = args.keep or scratch
        Path(tmp).mkdir(parents=True, exist_ok=True)
        for name in args.plants:
            t0 = time.perf_counter()
            try:
                if args.pipeline:
                    lines = round_trip_pipeline(name, Path(tmp) / name)
                else:
                    drifts = tuple(d.strip() for d in args.drifts.split(",") if d.strip())
                    lines = round_trip(name, Path(tmp), args.full, rows, drifts)
            except (RuntimeError, ValueError, KeyError) as exc:
                lines = [f"{name}: failed: {exc}"]
                rows.append({"plant": name, "failed": str(exc)[:200]})
            lines[0] += f" ({time.perf_counter() - t0:.0f} s in all)"
            print("\n".join(lines), flush=True)
    if args.csv:
        pd.DataFrame(rows).to_csv(args.csv, index=False)


if __name__ == "__main__":
    run()
