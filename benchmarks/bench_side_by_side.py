"""Old and new spa side by side, in one run: the time an added dataset costs, the dry run over
102 datasets, and whether the tables are the same bytes.

Run from the repository root, with the old tree checked out beside it:

    git worktree add /tmp/perf/old 8e1fb4c
    .venv/bin/python benchmarks/bench_side_by_side.py --old /tmp/perf/old --copies 10

Both trees run with this interpreter (``PYTHONPATH`` set to the tree), `-c2`, the small
configuration with every figure drawn, alternately, so that both see the same load:

- base: `snakemake reproduce-all` of the small configuration with raw/example (and `sim`);
- added: the same with ``--copies`` more copies of raw/example; the time per added dataset
  is (added - base) / copies;
- dry run: `snakemake reproduce-all --dry-run` over 101 copies plus `sim` (102 datasets),
  nothing processed yet;
- tables: the sha256 of every CSV, YAML and Parquet file of the two base runs' results
  (logs and provenance records left out), compared file by file.

Prints a Markdown table with the ratio old / new, the load average, and the files that differ.
"""

from __future__ import annotations

import argparse
import hashlib
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def run(tree: Path, args: list[str], profile: Path | None = None) -> tuple[float, float]:
    """Wall time and CPU time (user + system of Snakemake and every job it waited for) of
    `snakemake reproduce-all -c2` (small config) with ``args`` in ``tree``; with ``profile``,
    each stage records its CPU time there (``SPA_PROFILE_DIR``)."""
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
    return elapsed, usage.ru_utime + usage.ru_stime


def copies(raw: Path, n: int, with_example: bool = True) -> Path:
    """A raw folder holding raw/example (if asked) and ``n`` renamed copies of it."""
    raw.mkdir(parents=True)
    if with_example:
        shutil.copytree(ROOT / "raw" / "example", raw / "example")
    for i in range(n):
        name = f"bench{i:03d}"
        shutil.copytree(ROOT / "raw" / "example", raw / name)
        spec = raw / name / "dataset.yaml"
        spec.write_text(spec.read_text().replace("name: example", f"name: {name}", 1))
    return raw


def digests(results: Path) -> dict[str, str]:
    """sha256 of every table under ``results`` (CSV, YAML, Parquet), logs and provenance out."""
    out = {}
    for path in sorted(results.rglob("*")):
        rel = path.relative_to(results).as_posix()
        if path.suffix not in (".csv", ".yaml", ".parquet") or not path.is_file():
            continue
        if rel.startswith("logs/") or "/logs/" in rel or "provenance" in rel:
            continue
        out[rel] = hashlib.sha256(path.read_bytes()).hexdigest()
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--old", type=Path, required=True, help="the old checkout")
    parser.add_argument("--copies", type=int, default=10)
    parser.add_argument("--dry-count", type=int, default=101)
    parser.add_argument("--keep", type=Path, help="work here and keep the results (empty)")
    args = parser.parse_args()
    trees = {"old": args.old.resolve(), "new": ROOT}
    times: dict[str, dict[str, float]] = {name: {} for name in trees}
    cpu: dict[str, dict[str, float]] = {name: {} for name in trees}
    loads = []
    with tempfile.TemporaryDirectory(prefix="side_by_side_") as tmp_name:
        tmp = args.keep.resolve() if args.keep else Path(tmp_name)
        base_raw = copies(tmp / "raw_base", 0)
        more_raw = copies(tmp / "raw_more", args.copies)
        dry_raw = copies(tmp / "raw_dry", args.dry_count, with_example=False)
        for step, raw in (("base", base_raw), ("added", more_raw)):
            for name, tree in trees.items():
                loads.append(os.getloadavg()[0])
                out = tmp / f"{step}_{name}"
                cfg = ["--config", f"results={out}", f"datasets={{'raw_dir': '{raw}'}}"]
                times[name][step], cpu[name][step] = run(tree, cfg, tmp / f"prof_{step}_{name}")
        for name, tree in trees.items():
            out = tmp / f"dry_{name}"
            cfg = ["--config", f"results={out}", f"datasets={{'raw_dir': '{dry_raw}'}}"]
            times[name]["dry"] = min(run(tree, [*cfg, "--dry-run", "--quiet"])[0] for _ in range(2))
        old_tables, new_tables = (digests(tmp / f"base_{name}") for name in trees)
    per = {n: (t["added"] - t["base"]) / args.copies for n, t in times.items()}
    per_cpu = {n: (t["added"] - t["base"]) / args.copies for n, t in cpu.items()}
    print(f"load average (1 min) at each run's start: {', '.join(f'{x:.1f}' for x in loads)}\n")
    print("| measure | old | new | old / new |\n|---|---:|---:|---:|")
    rows = [
        ("base run (example + sim), s", times["old"]["base"], times["new"]["base"]),
        (f"with {args.copies} more copies, s", times["old"]["added"], times["new"]["added"]),
        ("per added dataset, s", per["old"], per["new"]),
        ("base run, CPU s", cpu["old"]["base"], cpu["new"]["base"]),
        (f"with {args.copies} more copies, CPU s", cpu["old"]["added"], cpu["new"]["added"]),
        ("per added dataset, CPU s", per_cpu["old"], per_cpu["new"]),
        (f"dry run, {args.dry_count + 1} datasets, s (best of 2)",
         times["old"]["dry"], times["new"]["dry"]),
    ]  # fmt: skip
    for label, old, new in rows:
        print(f"| {label} | {old:.1f} | {new:.1f} | {old / new:.2f} |")
    same = [k for k in old_tables if new_tables.get(k) == old_tables[k]]
    differ = [k for k in old_tables if k in new_tables and new_tables[k] != old_tables[k]]
    only = sorted(set(old_tables) ^ set(new_tables))
    print(f"\ntables: {len(same)} of {len(old_tables)} byte-identical; differ: {differ or '-'}")
    print(f"in one run only: {only or '-'}")


if __name__ == "__main__":
    main()
