"""The baseline that "nothing changed" is checked on: every output of the small and the full
run, by its SHA-256, and the suite's test ids.

Run from the repository root (runs go to temporary folders; nothing is written to results/
or raw/):

    .venv/bin/python benchmarks/baseline.py --write          # record benchmarks/baseline/
    .venv/bin/python benchmarks/baseline.py --check          # compare today's tree with it
    .venv/bin/python benchmarks/baseline.py --check --small  # the small run and the ids only

``--write`` runs ``snakemake reproduce-all`` with the small and the full configuration into
temporary results folders, writes one ``<sha256>  <path>`` line per output into
``benchmarks/baseline/outputs-small.sha256`` and ``outputs-full.sha256``, and the test ids
that ``pytest --collect-only`` lists into ``benchmarks/baseline/test-ids.txt``. ``--check``
runs the same and lists every output that was added, removed or changed, and every test id
added or removed; it exits 1 when anything differs.

Execution records are left out: the job logs (``logs/``), the content store's bookkeeping
(``.store/``, which holds copies of the outputs under the digest of what each stage read, and
so changes with any source file), and the files that record where and when a run happened
(:data:`RECORDS`). What is left is the science: tables, figures, parameters, controllers and
the report's pages.
"""

from __future__ import annotations

import argparse
import hashlib
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
BASELINE = ROOT / "benchmarks" / "baseline"
CONFIGS = {"small": ["--configfile", "config/small.yaml"], "full": []}

#: Folders and files of a results folder that record the run rather than its results.
SKIP_DIRS = ("logs", ".store", ".snakemake", "status", "provenance")
RECORDS = ("status.yaml", "execution.json")


def run(config: str, results: Path) -> None:
    """``snakemake reproduce-all`` of ``config`` ("small" or "full") into ``results``."""
    cmd = [sys.executable, "-m", "snakemake", "reproduce-all", *CONFIGS[config],
           "--config", f"results={results}"]  # fmt: skip
    res = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, check=False)
    if res.returncode != 0:
        sys.exit(f"{' '.join(cmd)} failed:\n{res.stderr[-3000:]}")


def is_record(relative: Path) -> bool:
    """Whether a results file records the run (left out of the baseline).

    Examples
    --------
    >>> is_record(Path("logs/sim/identify.log")), is_record(Path("sim/status/identify.yaml"))
    (True, True)
    >>> is_record(Path("sim/identification/params.yaml"))
    False
    """
    parts = relative.parts
    return bool(set(parts[:-1]) & set(SKIP_DIRS)) or relative.name in RECORDS


def digests(results: Path) -> dict[str, str]:
    """``relative path -> SHA-256`` of every output of ``results`` but the records. A file
    that names the results folder (a recommendation's ``source:``) is hashed with that name
    written ``<results>``, so that two runs into different folders compare."""
    out, where = {}, str(results.resolve()).encode()
    for path in sorted(results.rglob("*")):
        rel = path.relative_to(results)
        if path.is_file() and not is_record(rel):
            data = path.read_bytes().replace(where, b"<results>")
            out[rel.as_posix()] = hashlib.sha256(data).hexdigest()
    return out


def test_ids() -> list[str]:
    """The suite's test ids, as ``pytest --collect-only`` lists them (doctests included)."""
    res = subprocess.run(
        [sys.executable, "-m", "pytest", "--collect-only", "-q", "-p", "no:cacheprovider",
         "-o", "addopts=--doctest-modules"],
        cwd=ROOT, capture_output=True, text=True, check=False,
    )  # fmt: skip
    return sorted(line for line in res.stdout.splitlines() if "::" in line)


def read(path: Path) -> dict[str, str]:
    lines = path.read_text(encoding="utf-8").splitlines()
    return {name: digest for digest, name in (line.split("  ", 1) for line in lines if line)}


def compare(old: dict[str, str], new: dict[str, str]) -> list[str]:
    """One line per difference: ``+ path`` added, ``- path`` removed, ``~ path`` changed.

    Examples
    --------
    >>> compare({"a": "1", "b": "2"}, {"b": "3", "c": "4"})
    ['- a', '~ b', '+ c']
    """
    lines = [f"- {k}" for k in old if k not in new]
    lines += [f"~ {k}" for k in old if k in new and old[k] != new[k]]
    return lines + [f"+ {k}" for k in new if k not in old]


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    mode = ap.add_mutually_exclusive_group(required=True)
    mode.add_argument("--write", action="store_true", help="record benchmarks/baseline/")
    mode.add_argument("--check", action="store_true", help="compare with benchmarks/baseline/")
    ap.add_argument("--small", action="store_true", help="the small run only (and the ids)")
    ap.add_argument(
        "--results",
        action="append",
        default=[],
        metavar="CONFIG=DIR",
        help="hash DIR, a finished run of CONFIG (small or full), instead of running",
    )
    args = ap.parse_args(argv)
    given = dict(item.split("=", 1) for item in args.results)
    BASELINE.mkdir(exist_ok=True)
    differ = False
    for config in ("small",) if args.small else ("small", "full"):
        if config in given:
            new = digests(Path(given[config]))
        else:
            with tempfile.TemporaryDirectory(prefix=f"spa-baseline-{config}-") as tmp:
                run(config, Path(tmp) / "results")
                new = digests(Path(tmp) / "results")
        file = BASELINE / f"outputs-{config}.sha256"
        if args.write:
            file.write_text("".join(f"{d}  {k}\n" for k, d in new.items()), encoding="utf-8")
            print(f"{config}: {len(new)} outputs -> {file.relative_to(ROOT)}")
            continue
        lines = compare(read(file), new)
        differ |= bool(lines)
        print(f"{config}: {len(new)} outputs, {len(lines)} differ from the baseline")
        print("\n".join(f"  {line}" for line in lines))
    ids, file = test_ids(), BASELINE / "test-ids.txt"
    if args.write:
        file.write_text("".join(f"{i}\n" for i in ids), encoding="utf-8")
        print(f"tests: {len(ids)} ids -> {file.relative_to(ROOT)}")
        return 0
    old = file.read_text(encoding="utf-8").splitlines()
    lines = [f"- {i}" for i in sorted(set(old) - set(ids))]
    lines += [f"+ {i}" for i in sorted(set(ids) - set(old))]
    differ |= bool(lines)
    print(f"tests: {len(ids)} ids, {len(lines)} differ from the baseline")
    print("\n".join(f"  {line}" for line in lines))
    return int(differ)


if __name__ == "__main__":
    sys.exit(main())
