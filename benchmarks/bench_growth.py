"""How `snakemake reproduce-all` grows with the number of bench datasets.

Run from the repository root (nothing is written to results/ or raw/):

    .venv/bin/python benchmarks/bench_growth.py                  # 1, 10, 50, 100 datasets
    .venv/bin/python benchmarks/bench_growth.py --counts 1 10    # a quicker look
    .venv/bin/python benchmarks/bench_growth.py --figures none   # one setting of `figures`
    .venv/bin/python benchmarks/bench_growth.py --add-one 10 100 # add one dataset to N

For each setting of `figures` (default both: `all`, every dataset's figures, as the small
configuration draws them; `none`, tables and figure data only) and each count N, N copies of
raw/example go into a temporary raw folder, and the small configuration
(`config/small.yaml`, so the simulated dataset `sim` as well) runs with `-c2` into a
temporary results folder:

- DAG build: wall time of `snakemake reproduce-all --dry-run` before the first run;
- cold run: wall time from an empty results folder, and the number of jobs it ran;
- no-op: wall time of a second run with nothing changed ("Nothing to be done");
- peak memory: the largest resident set of any process of the cold run (the Snakemake
  process itself or a job), from the kernel's accounting of the waited-for children.

The slope (time per added dataset) is the least-squares line through the cold times. The
table goes to stdout as Markdown, the figures to `benchmarks/out/growth.csv` and
`benchmarks/out/growth.png` (copy them beside benchmarks/README.md to publish them).
"""

from __future__ import annotations

import argparse
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]


def run(args: list[str], cwd: Path) -> tuple[float, str, float]:
    """Wall time, output and peak RSS (MiB) of one command and everything it waited for."""
    with tempfile.TemporaryFile("w+") as log:
        start = time.perf_counter()
        proc = subprocess.Popen(args, cwd=cwd, stdout=log, stderr=subprocess.STDOUT, text=True)
        # wait4's ru_maxrss is the largest resident set in the child's process tree.
        _, status, usage = os.wait4(proc.pid, 0)
        elapsed = time.perf_counter() - start
        proc.returncode = os.waitstatus_to_exitcode(status)
        log.seek(0)
        text = log.read()
    if proc.returncode != 0:
        sys.exit(f"{' '.join(args)} failed:\n{text[-4000:]}")
    return elapsed, text, usage.ru_maxrss / 1024.0


def make_raw(raw: Path, n: int) -> None:
    for i in range(n):
        name = f"bench{i:03d}"
        shutil.copytree(ROOT / "raw" / "example", raw / name)
        spec = raw / name / "dataset.yaml"
        spec.write_text(spec.read_text().replace("name: example", f"name: {name}", 1))


def measure(n: int, tmp: Path, figures: str) -> dict[str, float | str]:
    raw = tmp / "raw"
    make_raw(raw, n)
    out = tmp / "results"
    cmd = [
        sys.executable,
        "-m",
        "snakemake",
        "reproduce-all",
        "-c2",
        "--configfile",
        "config/small.yaml",
        "--config",
        f"results={out}",
        f"datasets={{'raw_dir': '{raw}'}}",
        f"figures={figures}",
    ]
    t_dag, _, _ = run([*cmd, "--dry-run", "--quiet"], ROOT)
    t_cold, log, peak = run(cmd, ROOT)
    jobs = len(re.findall(r"^Finished jobid", log, flags=re.M))
    t_noop, log_noop, _ = run(cmd, ROOT)
    if "Nothing to be done" not in log_noop:
        sys.exit(f"the second run with {n} datasets was not a no-op:\n{log_noop[-2000:]}")
    return {
        "figures": figures,
        "datasets": n,
        "jobs": jobs,
        "cold_s": t_cold,
        "noop_s": t_noop,
        "dag_s": t_dag,
        "peak_mib": peak,
    }


def _logged(path: Path, pattern: str) -> float:
    """The number a job's log reports with ``pattern`` (one group), or NaN."""
    m = re.findall(pattern, path.read_text()) if path.is_file() else []
    return float(m[-1]) if m else float("nan")


def add_one(n: int, tmp: Path) -> dict[str, float | str]:
    """N datasets processed without figures, then one more with its figures: the wall time of
    that run, the report jobs' peak RSS (from their logs) and the pages' sizes."""
    raw = tmp / "raw"
    make_raw(raw, n)
    out = tmp / "results"
    base = [sys.executable, "-m", "snakemake", "reproduce-all", "-c2", "--configfile",
            "config/small.yaml", "--config", f"results={out}",
            f"datasets={{'raw_dir': '{raw}'}}"]  # fmt: skip
    t_cold, _, _ = run([*base, "figures=none"], ROOT)
    new = f"bench{n:03d}"
    shutil.copytree(ROOT / "raw" / "example", raw / new)
    spec = raw / new / "dataset.yaml"
    spec.write_text(spec.read_text().replace("name: example", f"name: {new}", 1))
    cmd = [*base, f"figures=[{new}]"]
    t_dag, _, _ = run([*cmd, "--dry-run", "--quiet"], ROOT)
    t_add, log, _ = run(cmd, ROOT)
    jobs = len(re.findall(r"^Finished jobid", log, flags=re.M))
    t_noop, log_noop, _ = run(cmd, ROOT)
    if "Nothing to be done" not in log_noop:
        sys.exit(f"the run after adding one dataset was not complete:\n{log_noop[-2000:]}")
    pages = sorted((out / "report").glob("*.html"), key=lambda p: p.stat().st_size)
    rss = r"peak RSS of the job(?: so far)?:? ([\d.]+) MiB"
    return {
        "datasets": n,
        "cold_none_s": t_cold,
        "add_one_s": t_add,
        "add_one_jobs": jobs,
        "noop_s": t_noop,
        "dag_s": t_dag,
        "index_kib": (out / "report.html").stat().st_size / 1024,
        "largest_page": pages[-1].name,
        "largest_page_kib": pages[-1].stat().st_size / 1024,
        "report_rss_mib": _logged(out / "logs" / "report.log", rss),
        "overview_rss_mib": _logged(out / "logs" / "overview.log", rss),
        "new_dataset_job_rss_mib": _logged(out / "logs" / new / "page.log", rss),
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--counts", type=int, nargs="+", default=[1, 10, 50, 100])
    ap.add_argument("--figures", nargs="+", default=["all", "none"], choices=["all", "none"])
    ap.add_argument(
        "--add-one",
        type=int,
        nargs="+",
        metavar="N",
        help="instead: N datasets processed without figures, then one more added with its "
        "figures; time that run, the report jobs' peak RSS and the pages' sizes",
    )
    args = ap.parse_args()
    if args.add_one:
        for n in args.add_one:
            with tempfile.TemporaryDirectory(prefix="spa-add-one-") as tmp:
                print(add_one(n, Path(tmp)), flush=True)
        return
    rows: list[dict] = []
    slopes = {}
    for figures in args.figures:
        for n in args.counts:
            with tempfile.TemporaryDirectory(prefix="spa-growth-") as tmp:
                rows.append(measure(n, Path(tmp), figures))
            print(f"measured {rows[-1]}", file=sys.stderr, flush=True)
        mine = [r for r in rows if r["figures"] == figures]
        n = np.array([r["datasets"] for r in mine], dtype=float)
        cold = np.array([r["cold_s"] for r in mine])
        slopes[figures] = float(np.polyfit(n, cold, 1)[0]) if len(mine) > 1 else float("nan")

    print(
        "| figures | bench datasets | jobs | cold run (s) | no-op (s) | DAG (s) | peak RSS (MiB) |"
    )
    print("|---|---:|---:|---:|---:|---:|---:|")
    for r in rows:
        print(
            f"| {r['figures']} | {r['datasets']} | {r['jobs']} | {r['cold_s']:.1f} | "
            f"{r['noop_s']:.1f} | {r['dag_s']:.1f} | {r['peak_mib']:.0f} |"
        )
    for figures, slope in slopes.items():
        print(
            f"\nfigures={figures}: slope {slope:.2f} s per added dataset (least squares, cold runs)"
        )

    out = ROOT / "benchmarks" / "out"
    out.mkdir(parents=True, exist_ok=True)
    import pandas as pd

    pd.DataFrame(rows).to_csv(out / "growth.csv", index=False)
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.5, 4.2))
    for figures, style in zip(slopes, ["-", "--"], strict=False):
        mine = [r for r in rows if r["figures"] == figures]
        n = [r["datasets"] for r in mine]
        label = f"figures: {figures}"
        ax.plot(n, [r["cold_s"] for r in mine], "o" + style, color="C0",
                label=f"cold run, {label} ({slopes[figures]:.2f} s per dataset)")  # fmt: skip
        ax.plot(n, [r["noop_s"] for r in mine], "s" + style, color="C1", label=f"no-op, {label}")
        ax.plot(n, [r["dag_s"] for r in mine], "^" + style, color="C2", label=f"DAG build, {label}")
    ax.set_xlabel("bench datasets (copies of raw/example) + sim")
    ax.set_ylabel("wall time (s), 2 cores")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(out / "growth.png", dpi=150)


if __name__ == "__main__":
    main()
