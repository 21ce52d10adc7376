"""False-choice rate of the laws' choice rule on data made with the paper's laws.

For each seed: a valve drawn around the paper's (c1 in [0.3, 0.8] s·bar^-1/2, k2 in
[0.5, 1.5] bar, tau2 in [0.3, 1.5] s, t_on in [1, 5] ms, t_off in [2, 10] ms), a bench of
six runs made with the paper's laws (charge, discharge, and PWM, IIPFM, ΔΣM and IPFM
staircases and sines, 12 s each at 1 kHz, 2 mbar noise), the refinement from a start 10 %
off, then :func:`spa.identification.laws_fit.choose_laws` with the refinement's held-out
FITs for the paper's laws. Prints each seed's gain and choice, and the count of seeds where
the identified laws were chosen (the target: fewer than 5 of 100).

Run:  nice .venv/bin/python benchmarks/laws_choice.py [datasets=100]
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from _laws_data import bench_runs

from spa.identification.laws_fit import choose_laws
from spa.identification.refine import refine
from spa.model.params import ValveParams


def draw(rng: np.random.Generator) -> ValveParams:
    return ValveParams(
        c1=rng.uniform(0.3, 0.8),
        k2=rng.uniform(0.5, 1.5),
        tau2=rng.uniform(0.3, 1.5),
        t_on=rng.uniform(0.001, 0.005),
        t_off=rng.uniform(0.002, 0.010),
    )


def main(datasets: int) -> None:
    chosen = 0
    t_all = time.perf_counter()
    for seed in range(datasets):
        rng = np.random.default_rng(1000 + seed)
        truth = draw(rng)
        runs = bench_runs(truth, rng)
        off = ValveParams(
            c1=truth.c1 * 1.1,
            k2=truth.k2 * 0.95,
            tau2=truth.tau2 * 0.9,
            t_on=truth.t_on,
            t_off=truth.t_off,
        )
        rf = refine(runs, off)
        t0 = time.perf_counter()
        ch = choose_laws(runs, rf.params, paper_heldout=rf.fit_heldout)
        chosen += ch.laws == "identified"
        print(
            f"seed {seed:3d}: gain {ch.gain:+6.2f} se {ch.se:5.2f} -> {ch.laws:10s} "
            f"({time.perf_counter() - t0:.1f} s)",
            flush=True,
        )
    print(
        f"identified laws chosen on {chosen} of {datasets} paper-law datasets "
        f"({100 * chosen / datasets:.1f} %), {time.perf_counter() - t_all:.0f} s"
    )


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 100)
