"""A closed-loop design and its C export.

A PI for the nominal valve driven through inverse IPFM (20 ms, the gain that removes its
dead-zone): fixed and gain-scheduled with feed-forward, designed from the averaged model at
three set-points, simulated exactly through the modulator on a set-point staircase, and the
second exported as a C99 header and an Arduino-style sketch for a board.
"""

import sys
import tempfile

import matplotlib.pyplot as plt
import numpy as np

import spa

valve = spa.ValveParams()
setting = {"type": "iipfm", "t_l": 0.02, "gain": 1 + valve.t_on / 0.02}  # Eq. 17's gain
levels = [0.2, 0.4, 0.6]
designs = spa.design_pi(setting, valve, levels=levels, tau_c=0.2)

dt = 1e-3  # controller step, s
t = np.arange(round(12 / dt)) * dt
reference = np.array(levels)[np.minimum((t // 4).astype(int), 2)]  # 4 s a level

fig, ax = plt.subplots(figsize=(7, 4))
ax.plot(t, reference, "k--", lw=1, label="set-point")
for name, colour in (("fixed", "#E69F00"), ("scheduled_ff", "#0072B2")):
    run = spa.simulate_closed_loop(reference, dt, setting, designs[name], valve)
    ax.plot(run["t"], run["p"], lw=0.8, color=colour, label=f"{name} PI")
ax.set(xlabel="time (s)", ylabel="pressure (bar)", title="PI through IIPFM 20 ms")
ax.legend()
fig.tight_layout()
fig.savefig(sys.argv[1] if len(sys.argv) > 1 else "closed_loop.png", dpi=100)

header, sketch = spa.export_designed(tempfile.mkdtemp(), valve, setting,
                                     controller="scheduled_ff", levels=levels, dt=dt)
print(header.read_text()[:600])
