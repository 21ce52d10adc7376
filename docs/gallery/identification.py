"""Identify a valve from a bench's files.

`spa example` writes a bench export like a lab's logger would (CSV in ms and kPa, a MATLAB
file, a Parquet file, and the `dataset.yaml` that describes them). The dataset is checked
and read into run tables, the valve's five parameters are identified with their 95 %
intervals, and the identified model replays the charge and discharge runs beside the
measurement.
"""

import subprocess
import sys
import tempfile
from pathlib import Path

import matplotlib.pyplot as plt

import spa

folder = Path(tempfile.mkdtemp()) / "raw" / "mybench"
spa_example = [sys.executable, "-m", "spa", "example", str(folder)]  # `spa example FOLDER`
subprocess.run(spa_example, check=True, capture_output=True)

assert spa.validate_dataset(folder) == []  # every problem at once; none here
runs, metas = spa.read_runs(spa.ingest_dataset(folder, folder.parents[1] / "out")[0].parent)
result = spa.identify_runs(runs, {r: m["kind"] for r, m in metas.items()})
valve = result.to_valve_params()
for name in ("c1", "k2", "tau2", "t_on", "t_off"):
    p = result.to_dict()[name]
    print(f"{name:6s} {p['value']:.4g} {p['unit']}  (95 %: {p['lo']:.4g} to {p['hi']:.4g})")

fig, axes = plt.subplots(1, 2, figsize=(8, 3.4), sharey=True)
for ax, run_id in zip(axes, ("charge", "discharge"), strict=True):
    run = runs[run_id]
    dt = float(run["t"].diff().median())
    model = spa.simulate(run["valve"].to_numpy(dtype="int8"), dt, valve, p0=float(run["p"].iloc[0]))
    ax.plot(run["t"], run["p"], ".", ms=1.5, color="0.6", label="bench")
    ax.plot(run["t"], model[: len(run)], color="#0072B2", label="identified model")
    ax.set(title=run_id, xlabel="time (s)")
axes[0].set_ylabel("pressure (bar)")
axes[0].legend()
fig.tight_layout()
fig.savefig(sys.argv[1] if len(sys.argv) > 1 else "identification.png", dpi=100)
