"""Benchmark: one step of the exported C controller (spa.closedloop.export), gcc -O2.

For each modulator kind, the gain-scheduled PI with feed-forward designed by the
``closed_loop`` stage's defaults on the nominal valve (SIMC, tau_c = 0.2 s, levels
0.05-0.75 bar) is written as a header, compiled with ``gcc -std=c99 -O2`` into a loop of
N = 20 M calls of ``spa_ctrl_step`` (set-point staircase, changing every 3000 steps, so the
schedule is interpolated 1 step in 3000; pressure read from a 4096-entry table, so the step
cannot be folded away), timed in CPU time (``clock_gettime(CLOCK_PROCESS_CPUTIME_ID)``: on a
shared machine the other jobs count less than in wall time); median of 5 runs, in ns per
step, against the controller step of 1 ms.

Run:  PYTHONPATH=. .venv/bin/python benchmarks/bench_controller_c.py
"""

from __future__ import annotations

import shutil
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

from spa.closedloop.comparison import DEFAULTS
from spa.closedloop.design import design_pi
from spa.closedloop.export import write_controller

SETTINGS = {
    "pwm": {"type": "pwm", "f_w": 20.0},
    "ipfm": {"type": "ipfm", "t_h": 0.020},
    "iipfm": {"type": "iipfm", "t_l": 0.020, "gain": 1.15},
    "dsm": {"type": "dsm", "period": 0.020},
    "lpwm": {"type": "lpwm", "f_w": 20.0},
}
N = 20_000_000
DT = 0.001

MAIN = r"""
#define _POSIX_C_SOURCE 199309L
#include <stdio.h>
#include <time.h>
#include "controller.h"

int main(void)
{
    static double ptab[4096];
    const double levels[8] = {0.05, 0.15, 0.25, 0.35, 0.45, 0.55, 0.65, 0.75};
    spa_ctrl_state s;
    struct timespec a, b;
    long i, ones = 0;
    double sum = 0.0;
    for (i = 0; i < 4096; ++i) {
        ptab[i] = 0.4 + 0.3 * (double)((i * 2654435761UL) %% 1000) / 1000.0 - 0.15;
    }
    spa_ctrl_init(&s, 0.0);
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &a);
    for (i = 0; i < %(n)d; ++i) {
        spa_ctrl_output o = spa_ctrl_step(&s, levels[(i / 3000) %% 8], ptab[i & 4095]);
        ones += o.valve;
        sum += o.xi;
    }
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &b);
    printf("%%.3f %%ld %%.6f\n",
           ((double)(b.tv_sec - a.tv_sec) * 1e9 + (double)(b.tv_nsec - a.tv_nsec)) / %(n)d.0,
           ones, sum);
    return 0;
}
"""


def main() -> int:
    gcc = shutil.which("gcc")
    if gcc is None:
        print("no gcc on PATH")
        return 1
    levels = [0.05, 0.15, 0.25, 0.35, 0.45, 0.55, 0.65, 0.75]  # bar, on the nominal valve
    print(f"{'kind':6s} {'ns/step':>8s} {'fraction of the 1 ms step':>26s}")
    with tempfile.TemporaryDirectory() as tmp:
        for kind, setting in SETTINGS.items():
            ctrl = design_pi(setting, None, levels=levels, tau_c=DEFAULTS["tau_c"])["scheduled_ff"]
            folder = Path(tmp) / kind
            write_controller(folder, setting, ctrl, DT)
            (folder / "main.c").write_text(MAIN % {"n": N})
            exe = folder / "bench"
            subprocess.run(
                [gcc, "-std=c99", "-O2", str(folder / "main.c"), "-o", str(exe), "-lm"],
                check=True,
            )
            runs = []
            for _ in range(5):
                res = subprocess.run([str(exe)], capture_output=True, text=True, check=True)
                runs.append(float(res.stdout.split()[0]))
            ns = statistics.median(runs)
            print(f"{kind:6s} {ns:8.1f} {ns * 1e-9 / DT:26.1e}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
