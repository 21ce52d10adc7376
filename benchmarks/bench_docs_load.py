"""The site's build verdict under load: no false failure, and a real warning still fails.

Run from the repository root (the builds go to a temporary folder; about 40 minutes):

    .venv/bin/python benchmarks/bench_docs_load.py              # 10 loaded builds + 1 broken
    .venv/bin/python benchmarks/bench_docs_load.py --builds 3   # a shorter check

The builds read a copy of the working tree taken at the start (a change made while they run
is not theirs to judge). Each build is the suite's (``docs/_site.py``: ``-W --keep-going``,
warnings to a file, the verdict Sphinx's exit status and that file) and runs cold: a fresh
notebook cache for every build (``SPA_DOCS_NB_CACHE``), so that every build starts the
executed pages' kernels, as a fresh clone's CI does. Meanwhile a second process runs fast
unit tests in a loop
(:data:`LOAD`), so the two cores are oversubscribed. After the loaded builds, one more build
gets a broken cross-reference (``-D rst_epilog=...``: a ``:doc:`` to a page that does not
exist, appended to every reStructuredText page) and must fail.

Each build's verdict, time and whether a kernel's shutdown noise (libzmq's ``Assertion
failed``, tornado's ``ZMQStream`` traceback) appeared on stderr go to
``benchmarks/results/docs_load.csv``.
"""

from __future__ import annotations

import argparse
import csv
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "docs"))
import _site  # noqa: E402

#: The load: quick tests of the model, run over and over beside the builds.
LOAD = ["tests/test_modulators.py", "tests/test_plant.py", "tests/test_averaging.py",
        "tests/test_signal.py", "tests/test_linearity.py"]  # fmt: skip
NOISE = ("Assertion failed", "ZMQStream", "ZMQError")
BROKEN = "-D", "rst_epilog=See :doc:`no-such-page-injected`."


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--builds", type=int, default=10, help="loaded builds (default 10)")
    ap.add_argument("--csv", type=Path, default=ROOT / "benchmarks/results/docs_load.csv")
    args = ap.parse_args(argv)
    rows = []
    load = subprocess.Popen(
        ["bash", "-c", "while true; do \"$0\" -m pytest -q -p no:cacheprovider "
         "-o addopts= \"$@\" >/dev/null 2>&1; done", sys.executable, *LOAD],
        cwd=ROOT, start_new_session=True,
    )  # fmt: skip
    try:
        with tempfile.TemporaryDirectory(prefix="spa-docs-load-") as tmp:
            src = Path(tmp) / "src"
            skip = (".venv", ".git", "results", ".snakemake", "_build", "__pycache__", "generated")
            shutil.copytree(ROOT, src, ignore=shutil.ignore_patterns(*skip), symlinks=True)
            for i in range(args.builds + 1):
                broken = i == args.builds
                cache = Path(tmp) / f"cache{i}"
                os.environ["SPA_DOCS_NB_CACHE"] = str(cache)
                extra = BROKEN if broken else ()
                verdict = _site.build(src / "docs", Path(tmp) / f"site{i}", *extra, cwd=src)
                row = {
                    "build": i + 1,
                    "kind": "broken reference" if broken else "clean",
                    "expected": "fail" if broken else "pass",
                    "verdict": "pass" if verdict.ok else "fail",
                    "returncode": verdict.returncode,
                    "warning_lines": len(verdict.warnings.splitlines()),
                    "kernel_noise_on_stderr": any(n in verdict.output for n in NOISE),
                    "seconds": round(verdict.seconds, 1),
                }
                rows.append(row)
                print(row, flush=True)
                if row["verdict"] != row["expected"]:  # keep what Sphinx said
                    keep = args.csv.with_name(f"docs_load_build{i + 1}_warnings.txt")
                    keep.write_text(verdict.warnings + verdict.output[-5000:], encoding="utf-8")
    finally:
        os.killpg(load.pid, 15)
        load.wait()
    args.csv.parent.mkdir(parents=True, exist_ok=True)
    with args.csv.open("w", newline="", encoding="utf-8") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    false = sum(r["verdict"] != r["expected"] for r in rows if r["expected"] == "pass")
    true = sum(r["verdict"] == "fail" for r in rows if r["expected"] == "fail")
    print(f"false failures: {false} of {args.builds}; broken reference failed: {true} of 1")
    return int(false > 0 or true != 1)


if __name__ == "__main__":
    sys.exit(main())
