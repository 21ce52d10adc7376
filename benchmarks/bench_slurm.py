"""What the cluster path costs the scheduler and the file system, measured on a one-node SLURM.

Run from the repository root; `submit` and `poll` need a cluster (`.ci/slurm.sh up`, as root):

    .venv/bin/python benchmarks/bench_slurm.py submit --count 200
    .venv/bin/python benchmarks/bench_slurm.py poll --count 1000
    .venv/bin/python benchmarks/bench_slurm.py dag --count 10000
    .venv/bin/python benchmarks/bench_slurm.py files RESULTS

- submit: `sbatch` of ``count`` held one-line jobs (``-H``: they never run), the wall time of
  each call (what the plugin pays per submission), then ``scancel``.
- poll: with ``count`` held jobs of one name in the controller, the plugin's status queries
  (`squeue --states=all --name <run>`, and `sacct ... --name <run>` when accounting is on),
  timed over repeats; then ``scancel``.
- dag: ``count`` bench datasets (hard links to raw/example's files, each with its own
  dataset.yaml) and `snakemake reproduce-all --profile profiles/slurm --dry-run` with the
  small configuration: the DAG build on the login node, and how many submissions it plans.
- files: the files and bytes each dataset of a finished results folder holds (its folder,
  its logs and its report page), what a parallel file system's inode and space quotas see.

Queue waits are left out: on a private idle cluster they mean nothing.
"""

from __future__ import annotations

import argparse
import os
import re
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _timed(cmd: list[str]) -> tuple[float, str]:
    start = time.perf_counter()
    res = subprocess.run(cmd, capture_output=True, text=True, check=True)
    return time.perf_counter() - start, res.stdout


def _summary(name: str, times: list[float]) -> str:
    ms = [t * 1000 for t in times]
    return (
        f"{name}: median {statistics.median(ms):.1f} ms (min {min(ms):.1f}, max {max(ms):.1f}, "
        f"{len(ms)} calls)"
    )


def _submit_held(count: int, name: str) -> tuple[list[float], list[str]]:
    times, ids = [], []
    for _ in range(count):
        cmd = ["sbatch", "--parsable", "-H", "-J", name, "--mem=100", "-t", "5", "--wrap", "true"]
        elapsed, out = _timed(cmd)
        times.append(elapsed)
        ids.append(out.strip().split(";")[0])
    return times, ids


def submit(count: int) -> None:
    name = f"spa-bench-{os.getpid()}"
    times, _ = _submit_held(count, name)
    subprocess.run(["scancel", "--name", name], check=True)
    print(_summary(f"sbatch ({count} held jobs)", times))
    print(f"  {count} submissions: {sum(times):.1f} s of sbatch calls in a row")


def poll(count: int, repeat: int) -> None:
    name = f"spa-bench-{os.getpid()}"
    _submit_held(count, name)
    try:
        squeue = ["squeue", "--format=%i|%T", "--states=all", "--noheader", "--name", name]
        times = [_timed(squeue)[0] for _ in range(repeat)]
        print(_summary(f"squeue status query, {count} jobs of the run", times))
        sacct = ["sacct", "-X", "--parsable2", "--noheader", "--format=JobIdRaw,State"]
        sacct += ["--name", name]
        if subprocess.run(sacct, capture_output=True).returncode == 0:
            times = [_timed(sacct)[0] for _ in range(repeat)]
            print(_summary(f"sacct status query, {count} jobs of the run", times))
        else:
            print("sacct: no accounting on this cluster")
    finally:
        subprocess.run(["scancel", "--name", name], check=True)


def dag(count: int) -> None:
    with tempfile.TemporaryDirectory(prefix="spa-slurm-dag-") as tmp:
        raw, results = Path(tmp) / "raw", Path(tmp) / "results"
        start = time.perf_counter()
        src = ROOT / "raw" / "example"
        spec = (src / "dataset.yaml").read_text()
        for i in range(count):
            folder = raw / f"bench{i:05d}"
            folder.mkdir(parents=True)
            for path in src.iterdir():
                if path.name != "dataset.yaml":
                    os.link(path, folder / path.name)
            (folder / "dataset.yaml").write_text(
                spec.replace("name: example", f"name: bench{i:05d}")
            )
        print(f"{count} datasets laid out in {time.perf_counter() - start:.1f} s")
        args = [sys.executable, "-m", "snakemake", "reproduce-all", "--profile", "profiles/slurm",
                "--dry-run", "--configfile", "config/small.yaml", "--config",
                f"results={results}", f"datasets={{raw_dir: {raw}}}"]  # fmt: skip
        start = time.perf_counter()
        res = subprocess.run(args, cwd=ROOT, capture_output=True, text=True)
        elapsed = time.perf_counter() - start
        if res.returncode != 0:
            sys.exit(res.stderr[-3000:])
        text = res.stdout + res.stderr
        groups = text.count("Group job dataset")
        total = re.search(r"^total\s+(\d+)$", text, re.M)
        print(
            f"{count} datasets: dry run through profiles/slurm {elapsed:.1f} s wall; "
            f"{total.group(1) if total else '?'} jobs, {groups} dataset groups"
        )


def files(results: Path) -> None:
    names = sorted(p.name for p in results.iterdir() if p.is_dir() and (p / "status").is_dir())
    for name in names:
        paths = [p for p in (results / name).rglob("*")]
        paths += list((results / "logs" / name).rglob("*"))
        page = results / "report" / f"{name}.html"
        paths += [page] if page.exists() else []
        n_files = sum(p.is_file() for p in paths)
        n_dirs = sum(p.is_dir() for p in paths)
        size = sum(p.stat().st_size for p in paths if p.is_file())
        print(f"{name}: {n_files} files, {n_dirs} folders, {size / 1e6:.2f} MB")
    store = results / ".store"
    if store.exists():
        items = [p for p in store.rglob("*") if p.is_file()]
        size = sum(p.stat().st_size for p in items)
        print(f".store (all datasets): {len(items)} files, {size / 1e6:.2f} MB")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = ap.add_subparsers(dest="what", required=True)
    sub.add_parser("submit").add_argument("--count", type=int, default=200)
    p = sub.add_parser("poll")
    p.add_argument("--count", type=int, default=1000)
    p.add_argument("--repeat", type=int, default=20)
    sub.add_parser("dag").add_argument("--count", type=int, default=10000)
    sub.add_parser("files").add_argument("results", type=Path)
    args = ap.parse_args()
    if args.what in ("submit", "poll") and shutil.which("sbatch") is None:
        sys.exit("no sbatch here: start the test cluster first (.ci/slurm.sh up, as root)")
    if args.what == "submit":
        submit(args.count)
    elif args.what == "poll":
        poll(args.count, args.repeat)
    elif args.what == "dag":
        dag(args.count)
    else:
        files(args.results)


if __name__ == "__main__":
    main()
