"""Wall time and peak memory of ingesting one long recording written in each bench format.

For each format in :data:`FORMATS` (a writer function and the ``dataset.yaml`` lines it
needs), writes one hour at 10 kHz (36,000,000 rows of ``t`` s, ``p`` bar, ``valve``, ``u``:
a 20 Hz PWM staircase with sensor noise) into a temporary dataset, runs
``spa.cli.main(["ingest", ...])`` in a fresh Python process and reports its wall time and
peak resident memory (that process's ``ru_maxrss``), then checks the run table.

    .venv/bin/python benchmarks/bench_ingest_formats.py                  # every format, 1 h
    .venv/bin/python benchmarks/bench_ingest_formats.py --hours 0.01 --only tsv

Adding a format: a function ``write(path, tables) -> None`` taking the chunks as
``pyarrow.Table`` (columns t, p, valve, u), and one entry in :data:`FORMATS`.
"""

from __future__ import annotations

import argparse
import platform
import shutil
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.csv as pacsv
import pyarrow.parquet as pq

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_ingest import signal_chunks

SPEC = """\
name: bench_formats
description: One long PWM staircase recording, generated to benchmark ingest of a format.
origin: synthetic
rig: {{valve: on/off solenoid, actuator: PneuNet, sensors: 0-2 bar, controller: 10 kHz}}
{extra}runs:
  - id: staircase_long
    kind: staircase
    file: {file}
    modulator: {{type: pwm, f_w: 20}}
"""


def tables(rows: int, rate: float) -> Iterator[pa.Table]:
    """The recording as tables of t (s), p (bar), valve and u, ``CHUNK`` rows at a time."""
    for k, p_kpa, valve, xi in signal_chunks(rows, rate):
        yield pa.table({"t": k / rate, "p": np.round(p_kpa / 100.0, 4), "valve": valve, "u": xi})


def _text(tables: Iterator[pa.Table], sep: str, decimal: str = ".") -> Iterator[bytes]:
    """The chunks as delimited text without a header, ``decimal`` as the decimal mark."""
    options = pacsv.WriteOptions(include_header=False, delimiter=sep)
    for table in tables:
        sink = pa.BufferOutputStream()
        pacsv.write_csv(table, sink, write_options=options)
        data = sink.getvalue().to_pybytes()
        yield data.replace(b".", decimal.encode()) if decimal != "." else data


def write_european_csv(path: Path, tables: Iterator[pa.Table]) -> None:
    """A European spreadsheet export: cp1252, two lines of metadata, a units row, ``;``
    between fields and ``,`` as decimal mark."""
    with path.open("wb") as fh:
        fh.write("Prüfstand: Ventil 3/2\r\nDatum: 23.11.2026\r\n".encode("cp1252"))
        fh.write(b"t;p;valve;u\r\ns;bar;-;-\r\n")
        for data in _text(tables, ";", ","):
            fh.write(data)


def write_csv(path: Path, tables: Iterator[pa.Table]) -> None:
    """Plain CSV (``,`` and ``.``, UTF-8): the reference the other formats are held to."""
    with path.open("wb") as fh:
        fh.write(b"t,p,valve,u\n")
        for data in _text(tables, ","):
            fh.write(data)


def write_tsv(path: Path, tables: Iterator[pa.Table]) -> None:
    """Tab-separated values with one header line."""
    with path.open("wb") as fh:
        fh.write(b"t\tp\tvalve\tu\n")
        for data in _text(tables, "\t"):
            fh.write(data)


@dataclass(frozen=True)
class Format:
    """A format to benchmark: its file name, writer and the lines ``dataset.yaml`` needs."""

    file: str
    write: Callable[[Path, Iterator[pa.Table]], None]
    spec: str = ""


#: format name -> how to write it
FORMATS: dict[str, Format] = {
    "csv": Format("run.csv", write_csv),
    "csv ; ,": Format(
        "run.csv",
        write_european_csv,
        "csv: {sep: ';', decimal: ',', encoding: cp1252, skip_rows: 2, units_row: true}\n",
    ),
    "tsv": Format("run.tsv", write_tsv),
}

# The peak is the child's VmHWM: its own high-water mark since exec. (``ru_maxrss`` is not:
# on Linux it keeps the peak of the process it was forked from, here the benchmark itself.)
CHILD = """\
import re, resource, sys, time
from pathlib import Path
from spa.cli import main
t0 = time.perf_counter()
code = main(["ingest", sys.argv[1], sys.argv[2]])
wall = time.perf_counter() - t0
hwm = re.search(r"VmHWM:\\s+(\\d+) kB", Path("/proc/self/status").read_text()).group(1)
use = resource.getrusage(resource.RUSAGE_SELF)
print(code, wall, use.ru_utime + use.ru_stime, hwm)
"""


def run(name: str, fmt: Format, work: Path, rows: int, rate: float) -> dict[str, float]:
    """Write the recording in ``fmt``, ingest it in a new process, return the figures."""
    folder = work / "raw" / "bench_formats"
    out = work / "runs"
    shutil.rmtree(work / "raw", ignore_errors=True)
    shutil.rmtree(out, ignore_errors=True)
    folder.mkdir(parents=True)
    (folder / "dataset.yaml").write_text(SPEC.format(extra=fmt.spec, file=fmt.file))
    t0 = time.perf_counter()
    fmt.write(folder / fmt.file, tables(rows, rate))
    t_gen = time.perf_counter() - t0
    size = (folder / fmt.file).stat().st_size
    t0 = time.perf_counter()
    cmd = [sys.executable, "-c", CHILD, str(folder), str(out)]
    done = subprocess.run(cmd, capture_output=True, text=True, check=False)
    total = time.perf_counter() - t0
    if done.returncode != 0 or not done.stdout.strip():
        raise SystemExit(f"{name}: ingest failed\n{done.stdout}\n{done.stderr}")
    code, wall, cpu, peak_kib = done.stdout.split()[-4:]
    if code != "0":
        raise SystemExit(f"{name}: ingest failed\n{done.stdout}\n{done.stderr}")
    start = 0
    for batch in pq.ParquetFile(out / "staircase_long.parquet").iter_batches(columns=["t"]):
        t = batch.column(0).to_numpy()  # exactly k / rate: the file held the shortest repr
        assert np.array_equal(t, np.arange(start, start + len(t)) / rate), start
        start += len(t)
    assert start == rows, (start, rows)
    return {
        "size_gb": size / 1e9,
        "gen_s": t_gen,
        "wall_s": float(wall),
        "cpu_s": float(cpu),
        "process_s": total,
        "peak_mib": int(peak_kib) / 1024,
    }


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--hours", type=float, default=1.0)
    parser.add_argument("--rate", type=float, default=10_000.0, help="sample rate, Hz")
    parser.add_argument(
        "--only",
        action="append",
        choices=list(FORMATS),
        help="benchmark only this format (repeatable)",
    )
    args = parser.parse_args()
    rows = round(args.hours * 3600 * args.rate)
    print(
        f"rows: {rows:,} ({args.hours:g} h at {args.rate:g} Hz); python "
        f"{platform.python_version()}, numpy {np.__version__}, pyarrow {pa.__version__}, "
        f"{platform.machine()}"
    )
    print("| format | file | ingest wall | ingest CPU | whole process | peak RSS | rows/s |")
    print("|---|---:|---:|---:|---:|---:|---:|")
    with tempfile.TemporaryDirectory() as tmp:
        for name in args.only or list(FORMATS):
            r = run(name, FORMATS[name], Path(tmp), rows, args.rate)
            print(
                f"| {name} | {r['size_gb']:.2f} GB | {r['wall_s']:.1f} s | {r['cpu_s']:.1f} s | "
                f"{r['process_s']:.1f} s | {r['peak_mib']:.0f} MiB | "
                f"{rows / r['wall_s'] / 1e6:.2f} M |",
                flush=True,
            )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
