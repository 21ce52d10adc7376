"""Why SIMC's closed-loop time constant defaults to 0.2 s (spa.closedloop.design.DEFAULT_TAU_C).

For the nominal valve and the paper's five settings, design the fixed and the gain-scheduled
PI for several tau_c, simulate the full config's set-point staircase (0.05 -> 0.75 bar by
0.1 bar, 3 s a level, up and down) exactly, and print the range over the 14 steps of the rise
time (10-90 %) and of the overshoot, per controller.

Run:  PYTHONPATH=. .venv/bin/python benchmarks/sweep_tau_c.py
"""

from __future__ import annotations

import numpy as np

from spa.closedloop.design import design_pi
from spa.closedloop.experiments import LoopUnderTest, Staircase, run_staircase
from spa.model.modulators import Modulator
from spa.model.params import ValveParams

LEVELS = [0.05, 0.15, 0.25, 0.35, 0.45, 0.55, 0.65, 0.75]
SETTINGS = [
    {"type": "pwm", "f_w": 20.0},
    {"type": "ipfm", "t_h": 0.02},
    {"type": "iipfm", "t_l": 0.02},
    {"type": "iipfm", "t_l": 0.02, "gain": 1.15},
    {"type": "dsm", "period": 0.02},
]
TAU_C = (0.05, 0.1, 0.2, 0.3, 0.5)


def main() -> None:
    params = ValveParams()
    print("| tau_c (s) | setting | controller | rise time, s (min-max, spread) | overshoot, % |")
    print("|---|---|---|---|---|")
    for tau_c in TAU_C:
        for setting in SETTINGS:
            mod = Modulator.from_mapping(setting)
            for name, ctrl in design_pi(mod, params, levels=LEVELS, tau_c=tau_c).items():
                _, m = run_staircase(LoopUnderTest(mod, ctrl, params), Staircase(LEVELS, 3.0, 1e-3))
                rise, over = m["rise_time"].to_numpy(), m["overshoot"].to_numpy()
                lo, hi = np.nanmin(rise), np.nanmax(rise)
                print(
                    f"| {tau_c:g} | {mod.label} | {name} | {lo:.2f}-{hi:.2f} ({hi - lo:.2f}) "
                    f"| {over.min():.1f}-{over.max():.1f} |"
                )


if __name__ == "__main__":
    main()
