"""Import time of each workflow script: what a job pays before it does any work.

Run from the repository root:

    .venv/bin/python benchmarks/bench_imports.py            # median of 5 fresh interpreters
    .venv/bin/python benchmarks/bench_imports.py --repeat 9

For every script in ``workflow/scripts/``, the script's top-level ``import`` and ``from ...
import`` statements (found with :mod:`ast`, nothing else of the script runs) are executed in a
fresh interpreter, together with the ``snakemake.script`` module Snakemake's script directive
loads first; the wall time of that interpreter, minus that of an empty one, is the script's
import cost. The table goes to stdout as Markdown.
"""

from __future__ import annotations

import argparse
import ast
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


def wall(code: str, repeat: int) -> float:
    """Median wall time (s) of a fresh interpreter running ``code``."""
    times = []
    for _ in range(repeat):
        start = time.perf_counter()
        subprocess.run([sys.executable, "-c", code], cwd=ROOT, check=True)
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=5)
    args = parser.parse_args()
    empty = wall("pass", args.repeat)
    print(f"empty interpreter: {empty:.3f} s (subtracted)\n")
    print("| script | imports (s) | heavy modules loaded |")
    print("|---|---:|---|")
    for script in sorted(SCRIPTS.glob("*.py")):
        code = imports_of(script)
        cost = wall(code, args.repeat) - empty
        probe = code + (
            "\nimport sys; print(','.join(m for m in ('matplotlib.pyplot', 'scipy.signal', "
            "'scipy.optimize', 'scipy.stats', 'pandas') if m in sys.modules))"
        )
        heavy = subprocess.run(
            [sys.executable, "-c", probe], cwd=ROOT, check=True, capture_output=True, text=True
        ).stdout.strip()
        print(f"| {script.stem} | {cost:.2f} | {heavy.replace(',', ', ') or '-'} |")


if __name__ == "__main__":
    main()
