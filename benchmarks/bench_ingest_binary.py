"""Wall time and peak memory of ingesting one long recording in each bench file format.

For each format in :data:`WRITERS` (format -> writer), writes, chunk by chunk, one dataset
folder holding a recording of ``--hours`` at ``--rate`` Hz (default one hour at 10 kHz: 36
million rows of t, p, valve, u; a 20 Hz PWM staircase with sensor noise), then runs
``spa ingest`` on it in a subprocess that reports its own wall time and peak resident memory
(``ru_maxrss`` of that process alone), and checks the number of rows of the run table.

    .venv/bin/python benchmarks/bench_ingest_binary.py                 # every format, 1 h
    .venv/bin/python benchmarks/bench_ingest_binary.py --hours 0.01 --formats lvm tdms
"""

from __future__ import annotations

import argparse
import json
import platform
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
from scipy.signal import lfilter

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from file_writers import mat73_file, write_lvm, write_tdms

CHUNK = 1_000_000  # rows generated per write
PSI = 0.0689475729  # bar per psi

SPEC = """\
name: {name}
description: One long PWM staircase recording, generated to benchmark ingest.
origin: synthetic
rig: {{valve: on/off solenoid, actuator: PneuNet, sensors: transducer, controller: bench}}
units: {{time: s, pressure: {unit}}}
columns: {{p: p_act}}
runs:
  - id: staircase_long
    kind: staircase
    file: {file}
    modulator: {{type: pwm, f_w: 20}}
"""

# The ingest in the subprocess: wall time and its own peak RSS, as JSON on the last line.
CHILD = """\
import json, resource, sys, time
t0 = time.perf_counter()
from spa.cli import main
rc = main(["ingest", sys.argv[1], sys.argv[2]])
print(json.dumps({"rc": rc, "wall": time.perf_counter() - t0,
                  "peak_mib": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024}))
"""


def chunks(rows: int, rate: float) -> Iterator[dict[str, np.ndarray]]:
    """The recording, ``CHUNK`` rows at a time: t (s), p_act (bar), valve, u."""
    rng = np.random.default_rng(20251128)
    hold, period = int(5 * rate), int(rate / 20)
    alpha = 1.0 - np.exp(-1.0 / (0.8 * rate))
    p = 0.0
    for start in range(0, rows, CHUNK):
        k = np.arange(start, min(start + CHUNK, rows))
        u = np.minimum(((k // hold) % 11) * 0.1, 1.0).round(1)
        valve = ((k % period) < u * period).astype(np.float64)
        resp, _ = lfilter([alpha], [1.0, alpha - 1.0], 0.8 * valve, zi=[p * (1.0 - alpha)])
        p = float(resp[-1])
        noisy = np.round(resp + rng.normal(0.0, 0.002, k.size), 4)
        yield {"t": k / rate, "p_act": noisy, "valve": valve, "u": u}


def _mat73(path: Path, rows: int, rate: float) -> str:
    with mat73_file(path) as f:
        out = {}
        for name in ("t", "p_act", "valve", "u"):
            out[name] = f.create_dataset(name, shape=(1, rows), dtype=np.float64)
            out[name].attrs["MATLAB_class"] = np.bytes_("double")
        for i, chunk in enumerate(chunks(rows, rate)):
            for name, values in chunk.items():
                data = values / PSI if name == "p_act" else values
                out[name][0, i * CHUNK : i * CHUNK + len(values)] = data
    return "psi"


def _lvm(path: Path, rows: int, rate: float) -> str:
    def renamed() -> Iterator[dict[str, np.ndarray]]:
        for chunk in chunks(rows, rate):
            yield {"X_Value": chunk.pop("t"), **chunk}

    write_lvm(path, [renamed()], decimal=",")
    return "bar"


def _tdms(path: Path, rows: int, rate: float) -> str:
    data = ({k: v for k, v in c.items() if k != "t"} for c in chunks(rows, rate))
    write_tdms(path, "Measured", data, waveform=(0.0, 1.0 / rate))
    return "bar"


#: Format -> (file name, writer of the recording returning the pressure unit).
WRITERS: dict[str, tuple[str, Callable[[Path, int, float], str]]] = {
    "mat73": ("rec.mat", _mat73),
    "lvm": ("rec.lvm", _lvm),
    "tdms": ("rec.tdms", _tdms),
}


def run(fmt: str, work: Path, rows: int, rate: float) -> dict[str, float]:
    """Write the recording as ``fmt``, ingest it in a subprocess; return the figures."""
    file, writer = WRITERS[fmt]
    folder = work / "raw" / f"bench_{fmt}"
    folder.mkdir(parents=True)
    t0 = time.perf_counter()
    unit = writer(folder / file, rows, rate)
    t_gen = time.perf_counter() - t0
    (folder / "dataset.yaml").write_text(SPEC.format(name=folder.name, unit=unit, file=file))
    out = work / "runs" / fmt
    cmd = [sys.executable, "-c", CHILD, str(folder), str(out)]
    done = subprocess.run(cmd, capture_output=True, text=True, check=False)
    if done.returncode != 0 or not done.stdout.strip():
        raise SystemExit(f"{fmt}: ingest failed\n{done.stdout}\n{done.stderr}")
    figures = json.loads(done.stdout.strip().splitlines()[-1])
    if figures["rc"] != 0:
        raise SystemExit(f"{fmt}: ingest failed\n{done.stdout}\n{done.stderr}")
    assert pq.ParquetFile(out / "staircase_long.parquet").metadata.num_rows == rows
    size = (folder / file).stat().st_size
    (folder / file).unlink()
    return {
        "size_gb": size / 1e9,
        "gen": t_gen,
        "wall": figures["wall"],
        "peak_mib": figures["peak_mib"],
    }


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--hours", type=float, default=1.0)
    parser.add_argument("--rate", type=float, default=10_000.0, help="sample rate, Hz")
    parser.add_argument("--formats", nargs="+", default=list(WRITERS), choices=list(WRITERS))
    parser.add_argument("--keep", type=Path, help="work here instead of a temporary folder")
    args = parser.parse_args()
    rows = round(args.hours * 3600 * args.rate)
    print(f"rows: {rows:,} ({args.hours:g} h at {args.rate:g} Hz)")
    print("| format | file | written in | ingest wall time | ingest peak RSS |")
    print("|---|---:|---:|---:|---:|")
    with tempfile.TemporaryDirectory() as tmp:
        work = args.keep or Path(tmp)
        for fmt in args.formats:
            r = run(fmt, work, rows, args.rate)
            print(
                f"| {fmt} | {r['size_gb']:.2f} GB | {r['gen']:.0f} s | {r['wall']:.1f} s "
                f"({rows / r['wall'] / 1e6:.2f} M rows/s) | {r['peak_mib']:.0f} MiB |",
                flush=True,
            )
    print(f"python {platform.python_version()}, numpy {np.__version__}, {platform.machine()}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
