"""`spa validate` on the MAT bomb of issue 30: raw/example whose MAT v5 run also holds three
variables dataset.yaml never names, 512 MiB of zeros each (compressed, about 2 MB on disk).

Run from the repository root (``--old``: another checkout of spa, run side by side with
this one on the same file):

    .venv/bin/python benchmarks/bench_mat_bomb.py [--old /tmp/perf/old] [--repeat 3]

Prints each tree's wall time and peak resident memory (``os.wait4`` of the ``spa validate``
process), median over the repeats.
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
sys.path.insert(0, str(ROOT / "tests"))
MAT = "staircase_iipfm-20ms-G1.2.mat"


def build(folder: Path) -> Path:
    """raw/example in ``folder``, its MAT run saved compressed with the three variables."""
    import scipy.io
    from file_writers import append_v5_zeros

    shutil.copytree(ROOT / "raw" / "example", folder)
    data = {k: v for k, v in scipy.io.loadmat(folder / MAT).items() if not k.startswith("__")}
    scipy.io.savemat(folder / MAT, data, do_compression=True)
    append_v5_zeros(folder / MAT, ["junk_a", "junk_b", "junk_c"], (512 << 20) // 8)
    return folder


def validate(tree: Path, folder: Path) -> tuple[float, float]:
    """Wall time (s) and peak RSS (MiB) of `spa validate folder` with spa from ``tree``."""
    env = {**os.environ, "PYTHONPATH": str(tree)}
    start = time.perf_counter()
    proc = subprocess.Popen(
        [sys.executable, "-m", "spa", "validate", str(folder)],
        cwd=tree,
        env=env,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    _, _, usage = os.wait4(proc.pid, 0)
    return time.perf_counter() - start, usage.ru_maxrss / 1024


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--old", type=Path, help="another spa checkout, run side by side")
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    trees = {"this tree": ROOT} | ({"old": args.old.resolve()} if args.old else {})
    with tempfile.TemporaryDirectory() as tmp:
        folder = build(Path(tmp) / "example")
        size = (folder / MAT).stat().st_size
        print(f"{MAT}: {size / 1e6:.2f} MB on disk, 3 x 512 MiB of unnamed zeros")
        runs: dict[str, list[tuple[float, float]]] = {name: [] for name in trees}
        for _ in range(args.repeat):
            for name, tree in trees.items():  # alternated: same load for both
                runs[name].append(validate(tree, folder))
    print(f"load average: {os.getloadavg()[0]:.1f}")
    print("| tree | wall (s) | peak RSS (MiB) |\n|---|---:|---:|")
    for name, values in runs.items():
        wall = statistics.median(v[0] for v in values)
        peak = statistics.median(v[1] for v in values)
        print(f"| {name} | {wall:.2f} | {peak:.0f} |")


if __name__ == "__main__":
    main()
