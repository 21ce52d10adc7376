"""Peak memory and wall time of ingesting a long bench recording.

Generates, chunk by chunk, a CSV recording of ``--hours`` at ``--rate`` Hz (default one hour
at 10 kHz: 36 million rows) in a temporary dataset folder (time in ms, pressure in kPa,
renamed columns, a PWM staircase), then runs ``python -m spa ingest`` on it in a subprocess
and reports that subprocess's wall time and peak resident memory
(``resource.getrusage(RUSAGE_CHILDREN).ru_maxrss``), and checks the run table it wrote.

    .venv/bin/python benchmarks/bench_ingest.py             # the full hour
    .venv/bin/python benchmarks/bench_ingest.py --hours 0.01  # a quick check
"""

from __future__ import annotations

import argparse
import platform
import resource
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.csv as pacsv
import pyarrow.parquet as pq
from scipy.signal import lfilter

CHUNK = 1_000_000  # rows generated per write

SPEC = """\
name: bench_ingest
description: One long PWM staircase recording, generated to benchmark ingest.
origin: synthetic
rig:
  valve: on/off solenoid
  actuator: PneuNet
  sensors: 0-200 kPa transducer
  controller: dSpace at {rate:g} Hz
units: {{time: ms, pressure: kPa}}
columns: {{t: time_ms, p: P_kPa, valve: valve_cmd, u: xi}}
runs:
  - id: staircase_long
    kind: staircase
    file: staircase_long.csv
    modulator: {{type: pwm, f_w: 20}}
"""


def signal_chunks(
    rows: int, rate: float
) -> Iterator[tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]]:
    """The recording, ``CHUNK`` rows at a time: sample index, pressure in kPa (2 decimals),
    valve command and input fraction of a 20 Hz PWM staircase (5 s per level)."""
    rng = np.random.default_rng(20251128)
    hold = int(5 * rate)  # 5 s per level of the staircase
    period = int(rate / 20)  # 20 Hz PWM
    p = 0.0
    for start in range(0, rows, CHUNK):
        k = np.arange(start, min(start + CHUNK, rows))
        xi = np.minimum(((k // hold) % 11) * 0.1, 1.0).round(1)
        valve = ((k % period) < xi * period).astype(np.int8)
        # first-order pressure response to the valve, 80 kPa supply, tau = 0.8 s
        alpha = 1.0 - np.exp(-1.0 / (0.8 * rate))
        target = 80.0 * valve
        # p[i] = p[i-1] + alpha*(target[i] - p[i-1]), carried across chunks
        resp, _ = lfilter([alpha], [1.0, alpha - 1.0], target, zi=[p * (1.0 - alpha)])
        p = float(resp[-1])
        yield k, np.round(resp + rng.normal(0.0, 0.2, k.size), 2), valve, xi


def generate(folder: Path, rows: int, rate: float) -> int:
    """Write ``dataset.yaml`` and the CSV, ``CHUNK`` rows at a time; return the CSV's size."""
    folder.mkdir(parents=True)
    (folder / "dataset.yaml").write_text(SPEC.format(rate=rate))
    path = folder / "staircase_long.csv"
    with path.open("wb") as fh:
        fh.write(b"time_ms,P_kPa,valve_cmd,xi\n")
        options = pacsv.WriteOptions(include_header=False)
        for k, noisy, valve, xi in signal_chunks(rows, rate):
            table = pa.table(
                {"time_ms": k * (1000.0 / rate), "P_kPa": noisy, "valve_cmd": valve, "xi": xi}
            )
            pacsv.write_csv(table, fh, write_options=options)
    return path.stat().st_size


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--hours", type=float, default=1.0)
    parser.add_argument("--rate", type=float, default=10_000.0, help="sample rate, Hz")
    parser.add_argument("--keep", type=Path, help="work here instead of a temporary folder")
    args = parser.parse_args()
    rows = round(args.hours * 3600 * args.rate)

    with tempfile.TemporaryDirectory() as tmp:
        work = args.keep or Path(tmp)
        folder = work / "raw" / "bench_ingest"
        out = work / "runs"
        t0 = time.perf_counter()
        size = generate(folder, rows, args.rate)
        t_gen = time.perf_counter() - t0

        cmd = [sys.executable, "-m", "spa", "ingest", str(folder), str(out)]
        t0 = time.perf_counter()
        done = subprocess.run(cmd, capture_output=True, text=True, check=False)
        wall = time.perf_counter() - t0
        peak_kib = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss  # KiB on Linux
        if done.returncode != 0:
            print(done.stdout, done.stderr, sep="\n")
            return 1
        result = out / "staircase_long.parquet"
        meta = pq.ParquetFile(result).metadata
        assert meta.num_rows == rows, (meta.num_rows, rows)
        schema = pq.read_schema(result)
        print(f"rows: {rows:,} ({args.hours:g} h at {args.rate:g} Hz)")
        print(f"CSV: {size / 1e9:.2f} GB, generated in {t_gen:.0f} s")
        print(f"ingest wall time: {wall:.1f} s ({rows / wall / 1e6:.2f} M rows/s)")
        print(f"ingest peak RSS: {peak_kib / 1024:.0f} MiB")
        print(
            f"run table: {result.stat().st_size / 1e9:.2f} GB, {meta.num_row_groups} row "
            f"groups, columns {schema.names} {[str(t) for t in schema.types]}"
        )
        print(
            f"python {platform.python_version()}, numpy {np.__version__}, "
            f"pyarrow {pa.__version__}, {platform.machine()}"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
