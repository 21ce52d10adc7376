"""Wall time of `snakemake reproduce-all`, and what a change to one dataset reruns.

Run from the repository root (nothing is written to results/ or raw/):

    .venv/bin/python benchmarks/bench_pipeline.py            # small and full configs
    .venv/bin/python benchmarks/bench_pipeline.py --small    # small config only

Every run goes to a temporary results folder with `--cores 2`. The raw datasets are copies
of raw/example in a temporary folder (`example` and `example2`), so that one of them can be
changed: the script edits one pressure value in example2's charge.csv, then asks
`snakemake --dry-run` which jobs would run, and checks that every one is example2's (or the
report, which gathers every dataset).
"""

from __future__ import annotations

import argparse
import re
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def snakemake(*args: str) -> tuple[float, str]:
    start = time.perf_counter()
    res = subprocess.run(
        [sys.executable, "-m", "snakemake", "reproduce-all", *args],
        cwd=ROOT,
        capture_output=True,
        text=True,
        check=False,
    )
    elapsed = time.perf_counter() - start
    if res.returncode != 0:
        sys.exit(f"snakemake {' '.join(args)} failed:\n{res.stderr[-3000:]}")
    return elapsed, res.stdout + res.stderr


def planned_jobs(log: str) -> list[tuple[str, str]]:
    """(rule, dataset wildcard or '') of every job a dry run lists."""
    jobs, rule = [], None
    for line in log.splitlines():
        m = re.match(r"^(?:local)?rule (\w+):", line.strip())
        if m:
            rule = m.group(1)
            jobs.append((rule, ""))
        m = re.match(r"^wildcards: .*dataset=([^,\s]+)", line.strip())
        if m and jobs:
            jobs[-1] = (jobs[-1][0], m.group(1))
    return jobs


def bench(config: list[str], tmp: Path, label: str) -> None:
    raw = tmp / "raw"
    for name in ("example", "example2"):
        shutil.copytree(ROOT / "raw" / "example", raw / name)
    spec = raw / "example2" / "dataset.yaml"
    spec.write_text(spec.read_text().replace("name: example", "name: example2", 1))
    out = tmp / "results"
    common = [*config, "--config", f"results={out}", f"datasets={{'raw_dir': '{raw}'}}", "-c2"]

    t_clean, log = snakemake(*common)
    n_jobs = len(re.findall(r"^Finished jobid", log, flags=re.M))
    t_noop, log_noop = snakemake(*common)
    assert "Nothing to be done" in log_noop, log_noop[-2000:]

    csv = raw / "example2" / "charge.csv"
    lines = csv.read_text().splitlines(keepends=True)
    fields = lines[10].split(",")
    fields[1] = f"{float(fields[1]) + 0.5:g}"  # one pressure sample, +0.5 kPa
    lines[10] = ",".join(fields)
    csv.write_text("".join(lines))
    _, dry = snakemake(*common, "--dry-run", "--quiet", "host")  # list the jobs (profile: quiet)
    jobs = planned_jobs(dry)
    gathering = ("report", "reproduce_all")
    others = [j for j in jobs if j[1] != "example2" and j[0] not in gathering]

    print(f"## {label}")
    print(f"- from a clean results folder: {t_clean:.1f} s, {n_jobs} jobs")
    print(f"- second run, nothing changed: {t_noop:.1f} s ('Nothing to be done')")
    print(
        f"- one value changed in example2/charge.csv: the dry run plans {len(jobs)} jobs, "
        f"{sorted({r for r, _ in jobs})}; jobs of other datasets: {others or 'none'}"
    )
    sys.stdout.flush()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--small", action="store_true", help="small config only")
    args = ap.parse_args()
    runs = [(["--configfile", "config/small.yaml"], "small config (config/small.yaml)")]
    if not args.small:
        runs.append(([], "full config (config/config.yaml)"))
    for config, label in runs:
        with tempfile.TemporaryDirectory(prefix="spa-bench-") as tmp:
            bench(config, Path(tmp), label)


if __name__ == "__main__":
    main()
