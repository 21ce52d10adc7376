"""Old and new spa side by side, in one run: what an added dataset costs (with figures and with
``figures: none``), what a ``tuning:`` change over 20 processed datasets costs, the dry run
over 102 datasets, each run's peak memory, where an added dataset's CPU goes, and whether the
tables are the same bytes.

Run from the repository root, with the old tree checked out beside it:

    git -C /work/main worktree add /work/wt/base 3efa4f0
    nice .venv/bin/python benchmarks/bench_side_by_side.py --old /work/wt/base \\
        --copies 2 --processed 20 --dry-count 101

Both trees run with this interpreter (``PYTHONPATH`` set to the tree), `-c2`, the small
configuration, alternately (old, new, old, new...), so that both see the same load. The added
datasets are ``python -m spa example --seed <n>``: the example bench with its own sensor noise,
so that their bytes, and every result, differ (no stage of one is reused by another).

- figures: `snakemake reproduce-all` with raw/example (and `sim`), then with ``--copies``
  more datasets: per added dataset = (added - base) / copies, wall and CPU;
- no figures: the same with ``figures: none`` and ``--processed`` - 2 added datasets;
- tuning change: over that processed run (``--processed`` datasets), the same command with
  ``tuning: {max_chattering: 0.04}``, against that run's own cold time;
- dry run: `snakemake reproduce-all --dry-run` over ``--dry-count`` copies plus `sim`,
  nothing processed yet (min and median of ``--repeat``);
- peak: the largest resident set of any process of each run (``os.wait4``);
- per stage: each stage's CPU in an added dataset's analysis job, ``SPA_PROFILE_DIR``
  (spa.pipeline.status): the median over the added datasets;
- tables: the sha256 of every CSV, YAML and Parquet file of the two base runs' results
  (logs, provenance records and ``status.yaml`` left out), compared file by file.

Prints Markdown tables with the ratio old / new and the load average at each run's start.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
TUNING_CHANGE = "tuning:\n  max_chattering: 0.04\n"


def run(tree: Path, args: list[str], profile: Path | None = None) -> tuple[float, float, float]:
    """Wall time, CPU time (user + system of Snakemake and every job it waited for) and peak
    RSS (MiB, the largest process) of `snakemake reproduce-all -c2` (small config) with
    ``args`` in ``tree`` (first, more config files: they follow config/small.yaml); with
    ``profile``, each stage records its CPU time there."""
    cmd = [sys.executable, "-m", "snakemake", "reproduce-all", "-c2", "--configfile",
           "config/small.yaml", *args]  # fmt: skip
    env = {**os.environ, "PYTHONPATH": str(tree)}
    if profile is not None:
        env["SPA_PROFILE_DIR"] = str(profile)
    with tempfile.TemporaryFile("w+") as log:
        start = time.perf_counter()
        proc = subprocess.Popen(cmd, cwd=tree, env=env, stdout=log, stderr=subprocess.STDOUT)
        _, status, usage = os.wait4(proc.pid, 0)
        elapsed = time.perf_counter() - start
        if os.waitstatus_to_exitcode(status) != 0:
            log.seek(0)
            sys.exit(f"{tree}: {' '.join(cmd)} failed:\n{log.read()[-4000:]}")
    return elapsed, usage.ru_utime + usage.ru_stime, usage.ru_maxrss / 1024


def seeded(raw: Path, n: int, with_example: bool = True, seed0: int = 100) -> Path:
    """A raw folder holding raw/example (if asked) and ``n`` example benches of their own
    noise seeds (``python -m spa example --seed``), named bench000...; made once, copied."""
    raw.mkdir(parents=True)
    if with_example:
        shutil.copytree(ROOT / "raw" / "example", raw / "example")
    for i in range(n):
        name = f"bench{i:03d}"
        subprocess.run([sys.executable, "-m", "spa", "example", "--seed", str(seed0 + i),
                        str(raw / name)], check=True, capture_output=True,
                       env={**os.environ, "PYTHONPATH": str(ROOT)})  # fmt: skip
    return raw


def copies(raw: Path, n: int) -> Path:
    """``n`` renamed byte copies of raw/example (the dry run processes nothing)."""
    raw.mkdir(parents=True)
    for i in range(n):
        name = f"bench{i:03d}"
        shutil.copytree(ROOT / "raw" / "example", raw / name)
        spec = raw / name / "dataset.yaml"
        spec.write_text(spec.read_text().replace("name: example", f"name: {name}", 1))
    return raw


def config(folder: Path, raw: Path, results: Path, extra: str = "") -> list[str]:
    cfg = folder / f"{results.name}.yaml"
    cfg.write_text(f"results: {results}\ndatasets:\n  raw_dir: {raw}\n  include: []\n"
                   f"  exclude: []\n{extra}")  # fmt: skip
    return [str(cfg)]


def digests(results: Path) -> dict[str, str]:
    """sha256 of every table under ``results`` (CSV, YAML, Parquet), logs and provenance out."""
    out = {}
    for path in sorted(results.rglob("*")):
        rel = path.relative_to(results).as_posix()
        if path.suffix not in (".csv", ".yaml", ".parquet") or not path.is_file():
            continue
        if rel.startswith(("logs/", ".store/")) or "provenance" in rel or rel == "status.yaml":
            continue
        out[rel] = hashlib.sha256(path.read_bytes()).hexdigest()
    return out


def stage_cpu(profile: Path, datasets: list[str]) -> dict[str, float]:
    """Median CPU seconds of each stage of ``datasets``' analysis jobs, and of the job's start
    (interpreter, imports) before its first stage, from ``SPA_PROFILE_DIR`` records."""
    per: dict[str, list[float]] = {}
    for d in datasets:
        records = {}
        for path in profile.glob(f"*-{d}.json"):
            stage = path.name[: -len(f"-{d}.json")]
            records[stage] = json.loads(path.read_text())
        if not records:
            continue
        for stage, rec in records.items():
            per.setdefault(stage, []).append(rec["cpu_total"] - rec["cpu_before_work"])
        first = min(records.values(), key=lambda r: r["cpu_before_work"])
        per.setdefault("(job start)", []).append(first["cpu_before_work"])
    return {k: statistics.median(v) for k, v in per.items()}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--old", type=Path, required=True, help="the old checkout")
    parser.add_argument("--new", type=Path, default=ROOT, help="the new checkout")
    parser.add_argument("--copies", type=int, default=2, help="added datasets with figures")
    parser.add_argument("--processed", type=int, default=20, help="datasets of the tuning change")
    parser.add_argument("--dry-count", type=int, default=101)
    parser.add_argument("--repeat", type=int, default=3, help="dry runs per tree")
    parser.add_argument("--keep", type=Path, help="work here and keep the results (empty)")
    parser.add_argument("--no-figures-runs", action="store_true",
                        help="skip the two runs with figures (a busy machine)")  # fmt: skip
    parser.add_argument("--figures-runs-only", action="store_true",
                        help="only the two runs with figures (and the dry runs)")  # fmt: skip
    args = parser.parse_args()
    trees = {"old": args.old.resolve(), "new": args.new.resolve()}
    wall: dict[str, dict[str, float]] = {name: {} for name in trees}
    cpu: dict[str, dict[str, float]] = {name: {} for name in trees}
    peak: dict[str, float] = dict.fromkeys(trees, 0.0)
    dry: dict[str, list[float]] = {name: [] for name in trees}
    loads = []
    with tempfile.TemporaryDirectory(prefix="side_by_side_") as tmp_name:
        tmp = args.keep.resolve() if args.keep else Path(tmp_name)
        added = seeded(tmp / "raw_more", max(args.copies, args.processed - 2))
        base_raw = tmp / "raw_base"
        base_raw.mkdir()
        shutil.copytree(ROOT / "raw" / "example", base_raw / "example")
        figs_raw = tmp / "raw_figs"
        shutil.copytree(added, figs_raw, ignore=lambda d, names: [
            n for n in names if n.startswith("bench") and int(n[5:]) >= args.copies
        ])  # fmt: skip
        dry_raw = copies(tmp / "raw_dry", args.dry_count)
        none = "figures: none\n"
        steps = [
            ("base", base_raw, ""),
            ("added", figs_raw, ""),
            ("base_none", base_raw, none),
            ("processed", added, none),
            ("tuning", added, none + TUNING_CHANGE),
        ]
        if args.no_figures_runs:
            steps = steps[2:]
        if args.figures_runs_only:
            steps = steps[:2]
        for step, raw, extra in steps:
            for name, tree in trees.items():
                loads.append(os.getloadavg()[0])
                out = tmp / f"{'processed' if step == 'tuning' else step}_{name}"
                cfg = config(tmp, raw, out, extra)
                w, c, m = run(tree, cfg, tmp / f"prof_{step}_{name}")
                wall[name][step], cpu[name][step] = w, c
                peak[name] = max(peak[name], m)
        for _ in range(args.repeat):
            for name, tree in trees.items():
                cfg = config(tmp, dry_raw, tmp / f"dry_{name}")
                dry[name].append(run(tree, [*cfg, "--dry-run", "--quiet"])[0])
        first = "base_none" if args.no_figures_runs else "base"
        old_tables, new_tables = (digests(tmp / f"{first}_{name}") for name in trees)
        names = [f"bench{i:03d}" for i in range(args.copies)]
        stages = {n: stage_cpu(tmp / f"prof_added_{n}", names) for n in trees}
        stages_none = {n: stage_cpu(tmp / f"prof_processed_{n}", names) for n in trees}
        for n in trees:  # steps left out
            stages_none[n] = stages_none[n] if (tmp / f"prof_processed_{n}").exists() else {}
            stages[n] = stages[n] if (tmp / f"prof_added_{n}").exists() else {}
    n_none = max(args.copies, args.processed - 2)
    nan = float("nan")
    for table in (*wall.values(), *cpu.values()):
        for step in ("base", "added", "base_none", "processed", "tuning"):
            table.setdefault(step, nan)
    per = {n: (t["added"] - t["base"]) / args.copies for n, t in wall.items()}
    per_cpu = {n: (t["added"] - t["base"]) / args.copies for n, t in cpu.items()}
    per_none = {n: (t["processed"] - t["base_none"]) / n_none for n, t in wall.items()}
    per_none_cpu = {n: (t["processed"] - t["base_none"]) / n_none for n, t in cpu.items()}
    print(f"load average (1 min) at each run's start: {', '.join(f'{x:.1f}' for x in loads)}\n")
    print("| measure | old | new | old / new |\n|---|---:|---:|---:|")
    rows = [
        ("base run (example + sim), wall s", wall["old"]["base"], wall["new"]["base"]),
        (f"with {args.copies} more datasets, wall s", wall["old"]["added"], wall["new"]["added"]),
        ("**per added dataset, figures, wall s**", per["old"], per["new"]),
        ("per added dataset, figures, CPU s", per_cpu["old"], per_cpu["new"]),
        ("**per added dataset, figures: none, wall s**", per_none["old"], per_none["new"]),
        ("per added dataset, figures: none, CPU s", per_none_cpu["old"], per_none_cpu["new"]),
        (f"cold run of {n_none + 2} datasets (figures: none), wall s",
         wall["old"]["processed"], wall["new"]["processed"]),
        ("**tuning: change over them, wall s**", wall["old"]["tuning"], wall["new"]["tuning"]),
        ("tuning: change over them, CPU s", cpu["old"]["tuning"], cpu["new"]["tuning"]),
        (f"dry run, {args.dry_count + 1} datasets, wall s (min of {args.repeat})",
         min(dry["old"]), min(dry["new"])),
        (f"dry run, {args.dry_count + 1} datasets, wall s (median)",
         statistics.median(dry["old"]), statistics.median(dry["new"])),
        ("peak RSS of any process, MiB", peak["old"], peak["new"]),
    ]  # fmt: skip
    for label, old, new in rows:
        print(f"| {label} | {old:.1f} | {new:.1f} | {old / new:.2f} |")
    for name in trees:
        share = wall[name]["tuning"] / wall[name]["processed"]
        print(f"\n{name}: tuning change / cold run = {share:.0%} wall, "
              f"{cpu[name]['tuning'] / cpu[name]['processed']:.0%} CPU")  # fmt: skip
    for title, table in (("figures", stages), ("figures: none", stages_none)):
        print(f"\nCPU s of an added dataset's analysis job by stage ({title}; median over "
              f"{len(names)}):\n\n| stage | old | new |\n|---|---:|---:|")  # fmt: skip
        keys = list(dict.fromkeys([*table["old"], *table["new"]]))
        for key in keys:
            old, new = table["old"].get(key, float("nan")), table["new"].get(key, float("nan"))
            print(f"| {key} | {old:.2f} | {new:.2f} |")
    same = [k for k in old_tables if new_tables.get(k) == old_tables[k]]
    differ = [k for k in old_tables if k in new_tables and new_tables[k] != old_tables[k]]
    only = sorted(set(old_tables) ^ set(new_tables))
    print(f"\ntables: {len(same)} of {len(old_tables)} byte-identical; differ: {differ or '-'}")
    print(f"in one run only: {only or '-'}")


if __name__ == "__main__":
    main()
