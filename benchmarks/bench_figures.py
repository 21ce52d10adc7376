"""What drawing a dataset's figures costs, old and new spa side by side.

Run from the repository root, with the old tree beside it (``git archive <commit> | tar -x``
into a folder, ``.venv`` linked):

    .venv/bin/python benchmarks/bench_figures.py --old /tmp/figures-main --repeat 2

Each round runs, alternately so that all see the same load, `snakemake reproduce-all -c1`
of the small configuration (raw/example and `sim`) cold, with ``SPA_PROFILE_DIR`` set so that
each stage of the analysis job records its wall time (:func:`spa.pipeline.status._profiled`):

- old: the old tree, figures drawn (its default: PNG and SVG, every sample);
- new: this tree, figures drawn (PNG only, long traces reduced per pixel column);
- new, no figures: this tree with ``figures=none`` (the tables alone: the floor).

Prints, per run, the wall and CPU seconds of the whole run (Snakemake and every job) and the
CPU seconds of the work of each stage that draws, summed over the two datasets; the median
over the rounds. CPU seconds, not wall, since a shared machine's load moves the wall time.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
DRAWING = ("identify", "tune", "validate_model", "staircase", "sine", "chirp", "closed_loop")


def run(tree: Path, extra: list[str]) -> dict[str, float]:
    """CPU and wall seconds of one cold small run in ``tree``, and each drawing stage's
    CPU seconds (summed over the datasets)."""
    with tempfile.TemporaryDirectory(prefix="bench-figures-") as tmp:
        results, profile = Path(tmp) / "results", Path(tmp) / "profile"
        cmd = [sys.executable, "-m", "snakemake", "reproduce-all", "-c1", "--configfile",
               "config/small.yaml", "--config", f"results={results}", *extra]  # fmt: skip
        env = {**os.environ, "PYTHONPATH": str(tree), "SPA_PROFILE_DIR": str(profile)}
        start = time.perf_counter()
        proc = subprocess.Popen(cmd, cwd=tree, env=env, stdout=subprocess.DEVNULL,
                                stderr=subprocess.PIPE, text=True)  # fmt: skip
        _, status, usage = os.wait4(proc.pid, 0)
        wall = time.perf_counter() - start
        if os.waitstatus_to_exitcode(status) != 0:
            sys.exit(f"{tree}: {' '.join(cmd)} failed:\n{proc.stderr.read()[-3000:]}")
        out = {"wall": wall, "cpu": usage.ru_utime + usage.ru_stime}
        for stage in DRAWING:  # CPU seconds of the stage's work (the job's imports left out)
            timings = [json.loads(p.read_text()) for p in profile.glob(f"{stage}-*.json")]
            out[stage] = sum(t["cpu_total"] - t["cpu_before_work"] for t in timings)
        return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--old", type=Path, required=True, help="the old tree")
    parser.add_argument("--repeat", type=int, default=2)
    args = parser.parse_args()
    cases = {
        "old": (args.old.resolve(), []),
        "new": (ROOT, []),
        "new, figures: none": (ROOT, ["figures=none"]),
    }
    rounds: dict[str, list[dict[str, float]]] = {name: [] for name in cases}
    for _ in range(args.repeat):
        for name, (tree, extra) in cases.items():
            rounds[name].append(run(tree, extra))
    keys = ["wall", "cpu", *DRAWING]
    print("| run | " + " | ".join(keys) + " | drawing stages |")
    print("|---" * (len(keys) + 2) + "|")
    for name, rs in rounds.items():
        med = {k: statistics.median(r[k] for r in rs) for k in keys}
        total = sum(med[s] for s in DRAWING)
        print(f"| {name} | " + " | ".join(f"{med[k]:.1f}" for k in keys) + f" | {total:.1f} |")
    print(f"\nload average {os.getloadavg()}")


if __name__ == "__main__":
    main()
