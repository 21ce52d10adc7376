"""Every modulator on one staircase.

The same staircase of the input fraction (0 to 1 by 0.2, 2 s a level) drives each
registered modulator at its reference setting; the exact simulator gives the pressure of
the nominal valve. The dead-zone shows as levels that never charge, the saturation as levels
stuck at the supply, and the chattering as the width of each trace.
"""

import sys

import matplotlib.pyplot as plt
import numpy as np

import spa
from spa.model.modulators import get_kind, kinds

dt = 1e-4  # controller step, s
t = np.arange(round(12 / dt)) * dt
xi = np.minimum(np.floor(t / 2) * 0.2, 1.0)  # 0 -> 1 by 0.2 every 2 s
valve = spa.ValveParams()  # the paper's nominal valve

fig, ax = plt.subplots(figsize=(7, 4))
for kind in kinds():
    k = get_kind(kind)
    setting = spa.Modulator.from_mapping({"type": kind, k.parameter: k.reference})
    u = spa.modulate(kind, xi, dt, **{n: v for n, v in setting.items() if n != "type"})
    p = spa.simulate(u, dt, valve)
    ax.plot(t, p, lw=0.8, color=k.colour, label=setting.label)
ax.plot(t, valve.k2 * xi, "k--", lw=1, label="the line $k_2 \\xi$")
ax.set(xlabel="time (s)", ylabel="pressure (bar)", title="One staircase, every modulator")
ax.legend(fontsize=8, loc="upper left")
fig.tight_layout()
fig.savefig(sys.argv[1] if len(sys.argv) > 1 else "modulators.png", dpi=100)
