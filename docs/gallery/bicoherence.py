"""The bicoherence of a chirp.

The paper's nonlinearity test: a chirp of the input fraction (0.5 ± 0.25, 0.1 to 100 Hz in
60 s) through PWM at 20 Hz on the nominal valve, the pressure logged with a little sensor
noise, and its bicoherence over the principal domain. A bin above the significance
threshold is a pair of frequencies whose sum the valve couples: a linear plant would light
up about 1 % of the map.
"""

import sys

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd

import spa
from spa.synthetic import chirp_input

dt = 1e-3  # 1 kHz logging
t = np.arange(round(60 / dt)) * dt
xi = chirp_input(t)
u = spa.modulate("pwm", xi, dt, f_w=20.0)
p = spa.simulate(u, dt, spa.ValveParams()) + np.random.default_rng(0).normal(0, 0.002, t.size)
run = pd.DataFrame({"t": t, "p": p, "u": xi, "valve": u})

freqs, b2, summary = spa.chirp_analysis(run, decimate=4)  # 250 Hz, as the paper
print(f"significance threshold {summary['threshold']:.3f} over {summary['n_segments']} segments")

fig, ax = plt.subplots(figsize=(5.5, 4.5))
mesh = ax.pcolormesh(freqs, freqs, b2.T, shading="auto", cmap="viridis", vmin=0, vmax=1)
fig.colorbar(mesh, label="bicoherence $b^2$")
fs = summary["fs"]
ax.set(xlabel="$f_1$ (Hz)", ylabel="$f_2$ (Hz)", title="Bicoherence, PWM 20 Hz chirp",
       xlim=(0, fs / 2), ylim=(0, fs / 4))
fig.tight_layout()
fig.savefig(sys.argv[1] if len(sys.argv) > 1 else "bicoherence.png", dpi=100)
