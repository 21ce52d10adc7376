"""Benchmark: spa.bicoherence against the literal double loop over (f1, f2).

Signal: the paper's chirp experiment (docs/model.md section 5), simulated. Input fraction
``0.5 + 0.25*chirp(0.1 -> 100 Hz)`` over 60 s, IIPFM (t_l = 20 ms, G = 1.15) at 1 kHz, the
exact plant, pressure sampled at 1 kHz: 60,000 samples. Bicoherence with nfft = 256 and 50 %
overlap (467 segments).

* spa: ``spa.openloop.spectra.bicoherence`` with its default, bounded (Kim & Powers)
  normalisation (numerator once per symmetry orbit, vectorised over segments and f2, one
  einsum per f1 row; the denominator's <|Y1 Y2|^2> one matrix product). Timed cold (first
  call in the process, which builds the cached orbit table for this nfft) and warm (best of
  several repeats).
* loop: ``bicoher_loop`` from tests/test_spectra.py, written literally: one FFT per segment,
  then a Python double loop over the nfft x nfft pairs, each pair a numpy mean over the
  segments, with the same normalisation. Timed once (best of two with --repeat-loop).

Prints the wall times, speed-ups and the largest absolute difference between the two maps,
and the same difference for HOSA's normalisation (``normalisation="hosa"``).

Run:  .venv/bin/python benchmarks/bench_bicoherence.py
"""

from __future__ import annotations

import platform
import sys
import time
from pathlib import Path

import numpy as np
from scipy.signal import chirp

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from test_spectra import bicoher_loop

from spa import ValveParams, modulate, simulate
from spa.openloop.spectra import bicoherence, mean_bicoherence

FS = 1000.0
DURATION = 60.0
NFFT = 256
OVERLAP = 0.5


def chirp_pressure() -> np.ndarray:
    """Pressure response (bar) to the paper's chirp input through IIPFM and the exact plant."""
    dt = 1.0 / FS
    t = np.arange(round(DURATION * FS)) * dt
    xi = 0.5 + 0.25 * chirp(t, f0=0.1, t1=DURATION, f1=100.0, method="linear")
    u = modulate("iipfm", xi, dt, t_l=0.020, gain=1.15)
    return simulate(u, dt, ValveParams(), p0=0.0)


def main() -> None:
    p = chirp_pressure()
    print(f"signal: {p.size} samples at {FS:g} Hz, nfft = {NFFT}, overlap = {OVERLAP}")

    t0 = time.perf_counter()
    f, bic = bicoherence(p, FS, nfft=NFFT, overlap=OVERLAP)
    cold = time.perf_counter() - t0
    warm = min(_timed(lambda: bicoherence(p, FS, nfft=NFFT, overlap=OVERLAP)) for _ in range(7))

    repeats = 2 if "--repeat-loop" in sys.argv else 1
    loop = np.inf
    for _ in range(repeats):
        t0 = time.perf_counter()
        f_ref, bic_ref, _ = bicoher_loop(p, FS, NFFT, OVERLAP, "bounded")
        loop = min(loop, time.perf_counter() - t0)

    assert np.array_equal(f, f_ref)
    diff = float(np.max(np.abs(bic - bic_ref)))
    _, hosa = bicoherence(p, FS, nfft=NFFT, overlap=OVERLAP, normalisation="hosa")
    _, hosa_ref, _ = bicoher_loop(p, FS, NFFT, OVERLAP, "hosa")
    diff_hosa = float(np.max(np.abs(hosa - hosa_ref)))
    print(f"python {platform.python_version()}, numpy {np.__version__}, {platform.machine()}")
    print(f"spa.bicoherence cold (first call): {cold * 1e3:8.1f} ms   speed-up {loop / cold:6.1f}x")
    print(f"spa.bicoherence warm (best of 7):  {warm * 1e3:8.1f} ms   speed-up {loop / warm:6.1f}x")
    print(f"literal double loop:               {loop * 1e3:8.1f} ms")
    print(f"max |spa - loop| = {diff:.2e} (bic max {bic.max():.3f})")
    print(f"HOSA normalisation: max |spa - loop| = {diff_hosa:.2e} (max {hosa.max():.3f})")
    print(f"mean bicoherence over the principal domain: {mean_bicoherence(f, bic):.4f}")


def _timed(fn) -> float:
    t0 = time.perf_counter()
    fn()
    return time.perf_counter() - t0


if __name__ == "__main__":
    main()
