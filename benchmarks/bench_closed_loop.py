"""Benchmark: the compiled closed loop (spa.simulate_closed_loop) on one core.

For each modulator at the paper's settings, a PI (Kp = 1.2 /bar, Ki = 2.5 /(bar s)) tracks a
set-point staircase 0.05 -> 0.75 bar (steps of 0.1 bar every 5 s, repeated to 10 M samples at
dt = 1e-4 s). Reports, per modulator:

* numba's compile time: the first call in a fresh process (after the imports) with the on-disk
  cache cleared, and the first call when the cache is warm (loading the cached machine code);
* the loop's throughput, median of 5 calls after warm-up, in samples per second;
* the same loop body run by the Python interpreter (numba's ``py_func``; the per-step kernel
  calls stay compiled) on 200,000 samples, for scale.

With ``--stage``, instead: the ``closed_loop`` stage of one dataset as the workflow runs it
(a fresh process: imports, numba's cached code, the designs and exact simulations of the
full config's ``closed_loop:`` section for the paper's five settings plus a recommended one,
the tables and both figures with their SVG copies), median of 5 processes.

Run:  PYTHONPATH=. .venv/bin/python benchmarks/bench_closed_loop.py [--cold | --stage]
(``--cold`` deletes spa/closedloop's numba cache first, so the compile time is measured.)
"""

from __future__ import annotations

import statistics
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
SETTINGS = {
    "pwm": {"type": "pwm", "f_w": 20.0},
    "ipfm": {"type": "ipfm", "t_h": 0.020},
    "iipfm": {"type": "iipfm", "t_l": 0.020, "gain": 1.15},
    "dsm": {"type": "dsm", "period": 0.020},
}
DT = 1e-4
N = 10_000_000


def staircase(n: int) -> np.ndarray:
    t = np.arange(n) * DT
    level = np.floor(t / 5.0 + 1e-9) % 8
    return 0.05 + 0.1 * level


def first_call(kind: str) -> float:
    """Seconds for the first (compiling or cache-loading) call, in a new process."""
    code = (
        "import time;"
        "from spa.closedloop.loop import closed_loop_arrays;"
        "from spa.closedloop.controller import PIController;"
        "t0 = time.perf_counter();"
        f"closed_loop_arrays([0.1] * 100, {DT}, {SETTINGS[kind]!r}, PIController(1.2, 2.5));"
        "print(time.perf_counter() - t0)"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True, cwd=ROOT
    )
    return float(out.stdout)


STAGE = """
import sys, tempfile, time, yaml
t0 = time.perf_counter()
from pathlib import Path
from spa.closedloop.comparison import closed_loop, write_controllers
from spa.io import write_csv
from spa.model.params import ValveParams
from spa.plots.closedloop import fig10, fig11
from spa.plots.save import draw
cfg = yaml.safe_load(open("config/config.yaml"))
rec = {"recommended": {"setting": {"type": "iipfm", "t_l": 0.02, "gain": 1.17}}}
res = closed_loop(ValveParams(), cfg["analytic"]["selected"], rec, cfg["closed_loop"])
with tempfile.TemporaryDirectory() as tmp:
    out = Path(tmp)
    write_csv(res.table, out / "table.csv")
    write_controllers(res, out / "controllers.yaml")
    write_csv(res.traces, out / "fig10.csv")
    write_csv(res.steps, out / "fig11.csv")
    if sys.argv[1] == "figures":
        draw(out / "fig10.png", fig10, res.traces)
        draw(out / "fig11.png", fig11, res.steps)
print(time.perf_counter() - t0)
"""


def stage() -> None:
    for figures in ("figures", "none"):
        times = []
        for _ in range(5):
            out = subprocess.run(
                [sys.executable, "-c", STAGE, figures],
                capture_output=True,
                text=True,
                check=True,
                cwd=ROOT,
            )
            times.append(float(out.stdout))
        print(
            f"closed_loop stage, {figures}: median {statistics.median(times):.2f} s "
            f"(min {min(times):.2f}, max {max(times):.2f})"
        )


def main() -> None:
    if "--stage" in sys.argv:
        stage()
        return
    if "--cold" in sys.argv:
        for cache in (ROOT / "spa" / "closedloop").rglob("__pycache__"):
            for f in list(cache.glob("*.nbi")) + list(cache.glob("*.nbc")):
                f.unlink()
        cold = {kind: first_call(kind) for kind in SETTINGS}
        # The shared functions compiled with the first kind; later kinds compile their loop.
        print("first call, cache cleared (compile), s:", cold)
    warm = {kind: first_call(kind) for kind in SETTINGS}
    print("first call, warm cache (load), s:", warm)

    from spa.closedloop.controller import PIController
    from spa.closedloop.loop import closed_loop_arrays

    ctrl = PIController(kp=1.2, ki=2.5)
    r = staircase(N)
    rows = []
    for kind, mod in SETTINGS.items():
        closed_loop_arrays(r[:1000], DT, mod, ctrl)
        times = []
        for _ in range(5):
            t0 = time.perf_counter()
            closed_loop_arrays(r, DT, mod, ctrl)
            times.append(time.perf_counter() - t0)
        med = statistics.median(times)
        m = 200_000
        t0 = time.perf_counter()
        closed_loop_arrays(r[:m], DT, mod, ctrl, compiled=False)
        py = time.perf_counter() - t0
        rows.append((kind, med, N / med / 1e6, m / py / 1e6, py / m * N / med))
    print(
        "| modulator | 10 M samples, s (median of 5) | M samples/s "
        "| plain Python, M samples/s | speed-up |"
    )
    print("|---|---|---|---|---|")
    for kind, med, rate, py_rate, speed in rows:
        print(f"| {kind} | {med:.3f} | {rate:.0f} | {py_rate:.2f} | {speed:.0f}x |")


if __name__ == "__main__":
    main()
