"""What the cyclic garbage collector costs a job, at Python's default thresholds and at
:data:`spa.pipeline.reuse.JOB_GC_THRESHOLD`: the same work in one process, alternately.

    .venv/bin/python benchmarks/bench_gc.py --repeat 5

The work is an analysis job's kind, over a job's heap (what its stages import: pandas,
SciPy's optimisers, numba's compiled loop, matplotlib): the three figure shapes of
``bench_save.py`` saved with :func:`spa.plots.save.save_figure`, and a run table's CSV written with
:func:`spa.io.write_csv`. For each threshold: CPU seconds of the work, seconds inside the
collector (``gc.callbacks``) and the number of collections, best of ``--repeat``; and
whether the files are the same bytes (they must be: nothing depends on when garbage goes).
"""

from __future__ import annotations

import argparse
import gc
import hashlib
import importlib
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pandas as pd

from spa.io import write_csv
from spa.pipeline.reuse import JOB_GC_THRESHOLD
from spa.plots.save import save_figure

sys.path.insert(0, str(Path(__file__).resolve().parent))
import bench_save

#: What an analysis job's stages import: its heap (numba's compiled loop, SciPy's optimisers).
JOB_MODULES = ("scipy.optimize", "spa.closedloop.loop", "spa.report.site", "spa.validation",
               "spa.stages.closed_loop", "spa.stages.identify", "spa.stages.staircase",
               "spa.stages.tune")  # fmt: skip

DEFAULT = (700, 10, 10)


def work(folder: Path, table: pd.DataFrame) -> str:
    """Every figure shape saved and the table written; the sha256 of what was written."""
    h = hashlib.sha256()
    for name, make in bench_save.FIGURES.items():
        path = folder / f"{name.replace(' ', '_')}.png"
        save_figure(make(), path)
        h.update(path.read_bytes())
    write_csv(table, folder / "runs.csv")
    h.update((folder / "runs.csv").read_bytes())
    return h.hexdigest()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=5)
    args = ap.parse_args()
    for module in JOB_MODULES:
        importlib.import_module(module)
    n = 200_000
    rng = np.random.default_rng(1)
    table = pd.DataFrame(
        {"t": np.arange(n) / 1000.0, "p": rng.random(n), "valve": rng.integers(0, 2, n),
         "u": rng.random(n)}
    )  # fmt: skip
    spent = [0.0, 0, 0.0]

    def callback(phase: str, info: dict) -> None:
        if phase == "start":
            spent[2] = time.process_time()
        else:
            spent[0] += time.process_time() - spent[2]
            spent[1] += 1

    gc.callbacks.append(callback)
    results: dict[tuple[int, ...], list[tuple[float, float, int]]] = {}
    digests: dict[tuple[int, ...], set[str]] = {}
    with tempfile.TemporaryDirectory() as tmp:
        work(Path(tmp), table)  # warm: fonts, caches
        for _ in range(args.repeat):
            for threshold in (DEFAULT, JOB_GC_THRESHOLD):
                gc.collect()
                gc.set_threshold(*threshold)
                spent[:2] = [0.0, 0]
                start = time.process_time()
                digest = work(Path(tmp), table)
                cpu = time.process_time() - start
                gc.set_threshold(*DEFAULT)
                results.setdefault(threshold, []).append((cpu, spent[0], spent[1]))
                digests.setdefault(threshold, set()).add(digest)
    same = len(set().union(*digests.values())) == 1
    print(f"best of {args.repeat}, CPU s; the same bytes at both thresholds: {same}")
    print("| thresholds | work | in the collector | collections |")
    print("|---|---:|---:|---:|")
    for threshold, rows in results.items():
        cpu, in_gc, count = min(rows)
        print(f"| {threshold} | {cpu:.3f} | {in_gc:.3f} | {count} |")


if __name__ == "__main__":
    main()
