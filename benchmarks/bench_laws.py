"""Benchmark: spa.simulate on a valve with general two-mode laws against the paper's laws.

For each modulator at the paper's settings, a 55 s staircase (xi from 0 to 1 by 0.1 every
5 s) at dt = 1e-4 s (550,000 samples), simulated under both delay conventions with

* the paper's laws (closed forms), and
* non-monotone laws with m = 0.7 (spa.model.laws: the time maps, built once per valve and
  cached; the build is timed separately).

Reports spa's throughput in samples per second on one core (best of 7) and the ratio.

Run:  .venv/bin/python benchmarks/bench_laws.py
"""

from __future__ import annotations

import time

import numpy as np

from spa import ValveParams, modulate, simulate
from spa.model.laws import Laws
from spa.model.laws.timemap import law_tables

DT = 1e-4
SETTINGS = {
    "pwm": {"f_w": 20.0},
    "ipfm": {"t_h": 0.020},
    "iipfm": {"t_l": 0.020, "gain": 1.15},
    "dsm": {"period": 0.020},
}
LAWS = Laws(log_g=(0.3, -0.9, 0.1, 0.4), log_h=(0.1, 0.8, -0.3, 0.2), m=0.7)


def best(fn, repeats: int = 7) -> float:
    out = np.inf
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        out = min(out, time.perf_counter() - t0)
    return out


def main() -> None:
    t = np.arange(round(55.0 / DT)) * DT
    xi = np.minimum(np.floor(t / 5.0 + 1e-9) / 10.0, 1.0)
    paper, laws = ValveParams(), ValveParams(laws=LAWS)
    t0 = time.perf_counter()
    law_tables(laws)
    print(f"time maps built in {time.perf_counter() - t0:.3f} s (once per valve)")
    print(f"{'modulator':10s} {'delay':10s} {'paper M/s':>10s} {'laws M/s':>10s} {'ratio':>6s}")
    for kind, settings in SETTINGS.items():
        u = modulate(kind, xi, DT, **settings)
        for delay in ("hold", "transport"):
            a = best(lambda u=u, d=delay: simulate(u, DT, paper, delay=d))
            b = best(lambda u=u, d=delay: simulate(u, DT, laws, delay=d))
            print(
                f"{kind:10s} {delay:10s} {u.size / a / 1e6:10.1f} {u.size / b / 1e6:10.1f} "
                f"{b / a:6.2f}"
            )


if __name__ == "__main__":
    main()
