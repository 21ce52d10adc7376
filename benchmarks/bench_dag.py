"""What building the DAG costs with many datasets, before a first run and when nothing is to do.

Run from the repository root (nothing is written to results/ or raw/):

    .venv/bin/python benchmarks/bench_dag.py                 # 100 datasets, 3 repeats
    .venv/bin/python benchmarks/bench_dag.py --count 50 --repeat 5

N copies of raw/example go into a temporary raw folder; `snakemake reproduce-all --dry-run`
with the small configuration is timed twice:

- cold: an empty results folder (every output is missing, so each is named as a target of
  reproduce-all as well: the most the workflow's rebuild check adds);
- no-op: a results folder where every output exists, made by creating each one (empty, the
  report last) and recording them as a finished run does
  (spa.pipeline.provenance.record_outputs), so
  that the workflow checks every output's existence and every recorded size and time. No job
  runs: this is the DAG and the check alone, what a second `reproduce-all` costs before it
  says "Nothing to be done".

Prints the median and range of each, in seconds.
"""

from __future__ import annotations

import argparse
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def dry_run(raw: Path, results: Path) -> tuple[float, str]:
    args = [sys.executable, "-m", "snakemake", "reproduce-all", "-n", "--configfile",
            "config/small.yaml", "--config", f"results={results}",
            f"datasets={{raw_dir: {raw}}}"]  # fmt: skip
    start = time.perf_counter()
    res = subprocess.run(args, cwd=ROOT, capture_output=True, text=True)
    elapsed = time.perf_counter() - start
    if res.returncode != 0:
        sys.exit(res.stderr[-3000:])
    return elapsed, res.stdout + res.stderr


def fake_complete_run(results: Path, datasets: list[str]) -> None:
    """Every output of the run, empty, in the order of the pipeline; the run recorded."""
    from spa.pipeline.outputs import all_targets

    last = {str(results / "report.html"), str(results / "status.yaml")}
    targets = sorted(all_targets(results, datasets), key=lambda p: p in last)
    for path in map(Path, targets):
        if path.suffix:
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_bytes(b"")
        else:
            path.mkdir(parents=True, exist_ok=True)
    for path in map(Path, targets):  # strictly increasing times: nothing is stale
        os.utime(path, ns=(time.time_ns(), time.time_ns()))
    try:  # a tree without the record (to compare with one) skips it
        from spa.pipeline.provenance import output_ledger, record_outputs
    except ImportError:
        return
    record_outputs(targets, ROOT / output_ledger(results))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--count", type=int, default=100)
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    with tempfile.TemporaryDirectory(prefix="spa-dag-") as tmp:
        raw, results = Path(tmp) / "raw", Path(tmp) / "results"
        for i in range(args.count):
            shutil.copytree(ROOT / "raw" / "example", raw / f"bench{i:03d}")
            spec = raw / f"bench{i:03d}" / "dataset.yaml"
            spec.write_text(spec.read_text().replace("name: example", f"name: bench{i:03d}"))
        cold = [dry_run(raw, results)[0] for _ in range(args.repeat)]
        names = ["sim"] + [f"bench{i:03d}" for i in range(args.count)]
        fake_complete_run(results, sorted(names))
        noop = []
        for _ in range(args.repeat):
            elapsed, text = dry_run(raw, results)
            if "Nothing to be done" not in text:
                sys.exit(f"the faked complete run is not complete:\n{text[-3000:]}")
            noop.append(elapsed)
        try:
            from spa.pipeline.provenance import output_ledger

            (ROOT / output_ledger(results)).unlink(missing_ok=True)
        except ImportError:
            pass
    for name, times in (("cold dry run", cold), ("no-op dry run", noop)):
        print(
            f"{args.count} datasets, {name}: median {statistics.median(times):.2f} s "
            f"(min {min(times):.2f}, max {max(times):.2f}, {len(times)} runs)"
        )


if __name__ == "__main__":
    main()
