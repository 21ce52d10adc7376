"""Import time of each workflow script: what a job pays before it does any work.

Run from the repository root:

    .venv/bin/python benchmarks/bench_imports.py            # median of 5 fresh interpreters
    .venv/bin/python benchmarks/bench_imports.py --repeat 9
    .venv/bin/python benchmarks/bench_imports.py --importtime [--old /tmp/perf/old]

For every script in ``workflow/scripts/``, the script's top-level ``import`` and ``from ...
import`` statements (found with :mod:`ast`, nothing else of the script runs) are executed in a
fresh interpreter, together with the ``snakemake.script`` module Snakemake's script directive
loads first; the wall and CPU time of that interpreter, minus those of an empty one, are the
script's import cost. The table goes to stdout as Markdown.

``--importtime`` instead imports each module of ``spa.stages`` alone under ``python -X
importtime`` and prints, per module, its cumulative import time and that of the heavy
packages it pulled in (median over ``--repeat`` interpreters; ``-`` when not imported).
"""

from __future__ import annotations

import argparse
import ast
import os
import resource
import statistics
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SCRIPTS = ROOT / "workflow" / "scripts"


def imports_of(script: Path) -> str:
    """The script's top-level import statements, as source."""
    tree = ast.parse(script.read_text())
    lines = [
        ast.unparse(node)
        for node in tree.body
        if isinstance(node, ast.Import)
        or (isinstance(node, ast.ImportFrom) and node.module != "__future__")
    ]
    return "\n".join(["import snakemake.script", *lines])


def cost(code: str, repeat: int) -> tuple[float, float]:
    """Median wall time and CPU time (user + system, s) of a fresh interpreter running
    ``code``; CPU time is what a busy machine barely changes."""
    walls, cpus = [], []
    for _ in range(repeat):
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        start = time.perf_counter()
        subprocess.run([sys.executable, "-c", code], cwd=ROOT, check=True)
        walls.append(time.perf_counter() - start)
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
        cpus.append(after.ru_utime + after.ru_stime - before.ru_utime - before.ru_stime)
    return statistics.median(walls), statistics.median(cpus)


HEAVY = ("pandas", "scipy.optimize", "scipy.signal", "scipy.stats", "numba", "matplotlib")


def importtime(module: str, repeat: int, tree: Path = ROOT) -> dict[str, float]:
    """Median cumulative import time (s) of ``module`` (from the checkout ``tree``) and of
    each of :data:`HEAVY` it imports, from ``python -X importtime -c "import module"``."""
    runs: dict[str, list[float]] = {}
    env = {**os.environ, "PYTHONPATH": str(tree)}
    for _ in range(repeat):
        done = subprocess.run(
            [sys.executable, "-X", "importtime", "-c", f"import {module}"],
            cwd=tree, env=env, check=True, capture_output=True, text=True,
        )  # fmt: skip
        for line in done.stderr.splitlines():
            parts = line.split("|")
            if len(parts) == 3 and parts[2].strip() in (module, *HEAVY):
                runs.setdefault(parts[2].strip(), []).append(int(parts[1]) / 1e6)
    return {name: statistics.median(values) for name, values in runs.items()}


def stage_importtimes(repeat: int, trees: dict[str, Path]) -> None:
    """The ``--importtime`` table: each module in each tree, alternately."""
    print(f"| module | tree | import (s) | {' | '.join(HEAVY)} |")
    print(f"|---|---|---:|{'---:|' * len(HEAVY)}")
    for path in sorted((ROOT / "spa" / "stages").glob("[!_]*.py")):
        module = f"spa.stages.{path.stem}"
        for name, tree in trees.items():
            times = importtime(module, repeat, tree)
            heavy = " | ".join(f"{times[h]:.2f}" if h in times else "-" for h in HEAVY)
            print(f"| {module} | {name} | {times.get(module, float('nan')):.2f} | {heavy} |")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument("--importtime", action="store_true", help="spa.stages.* alone")
    parser.add_argument("--old", type=Path, help="with --importtime: another checkout too")
    args = parser.parse_args()
    if args.importtime:
        trees = {"this": ROOT} | ({"old": args.old.resolve()} if args.old else {})
        stage_importtimes(args.repeat, trees)
        return
    empty_wall, empty_cpu = cost("pass", args.repeat)
    print(f"empty interpreter: {empty_wall:.3f} s wall, {empty_cpu:.3f} s CPU (subtracted)\n")
    print("| script | imports, wall (s) | imports, CPU (s) | heavy modules loaded |")
    print("|---|---:|---:|---|")
    for script in sorted(SCRIPTS.glob("*.py")):
        code = imports_of(script)
        wall, cpu = cost(code, args.repeat)
        probe = code + (
            "\nimport sys; print(','.join(m for m in ('matplotlib.pyplot', 'scipy.signal', "
            "'scipy.optimize', 'scipy.stats', 'pandas') if m in sys.modules))"
        )
        heavy = subprocess.run(
            [sys.executable, "-c", probe], cwd=ROOT, check=True, capture_output=True, text=True
        ).stdout.strip()
        heavy = heavy.replace(",", ", ") or "-"
        print(f"| {script.stem} | {wall - empty_wall:.2f} | {cpu - empty_cpu:.2f} | {heavy} |")


if __name__ == "__main__":
    main()
