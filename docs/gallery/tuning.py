"""A tuning sweep: the linearity cost of every setting.

For the paper's nominal valve, the linearity cost of every setting of every modulator on a
coarse grid: J_exact, how far the mean pressure of the exact periodic orbit is from the line
k2·ξ, summed over 100 input fractions (J, the same on the averaged model, is zero for LPWM
by construction). The tuning's sentence names the setting to use.
"""

import sys

import matplotlib.pyplot as plt

import spa
from spa.model.modulators import get_kind

grids = {  # coarse grids: a few seconds (the pipeline's are finer)
    "pwm": {"start": 2.0, "stop": 70.0, "step": 2.0},
    "ipfm": {"start": 0.0125, "stop": 0.2, "step": 0.005},
    "iipfm": {"start": 0.0125, "stop": 0.2, "step": 0.005},
    "dsm": {"start": 0.0125, "stop": 0.2, "step": 0.005},
    "lpwm": {"start": 2.0, "stop": 70.0, "step": 2.0},
}
result = spa.tune(spa.ValveParams(), sweeps=grids)
print(result.sentence)

fig, ax = plt.subplots(figsize=(7, 4))
for kind, sweep in result.sweeps.groupby("modulator", sort=False):
    k = get_kind(kind)
    ax.plot(sweep["x_ms"], sweep["J_exact"], "o-", ms=3, color=k.colour, label=k.name)
ax.set(xlabel="period or pulse width (ms)", ylabel="linearity cost J_exact (bar)",
       xscale="log", yscale="log", title="Tuning sweep, nominal valve")
ax.legend()
fig.tight_layout()
fig.savefig(sys.argv[1] if len(sys.argv) > 1 else "tuning.png", dpi=100)
