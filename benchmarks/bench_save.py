"""What writing a figure and a figure's CSV costs: matplotlib's ``savefig`` of a constrained
figure against :func:`spa.plots.save.save_figure` (its layout computed once, before one
drawing), and pandas' ``to_csv`` against :func:`spa.io.write_csv`; each pair byte-identical.

    .venv/bin/python benchmarks/bench_save.py --repeat 5

The figures have the shapes of the pipeline's: one panel (Fig. 2a), a 2 x 5 grid whose lower
row has log axes (Fig. 5), a 4 x 2 grid of traces (Fig. 10). The table is a run table's size:
550 000 rows of time, pressure, valve and input, plus a run id. CPU seconds, best of
``--repeat``, in one warm process.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pandas as pd

from spa.io import write_csv
from spa.plots.save import PNG_COMPRESS_LEVEL, png_dpi, save_figure
from spa.plots.style import new_figure


def one_panel():
    fig = new_figure(figsize=(5.0, 3.6), layout="constrained")
    ax = fig.subplots()
    p = np.linspace(0.0, 1.2, 2000)
    ax.plot(p, 3.0 * (1.3 - p), label="charge")
    ax.set_xlabel("pressure (bar)")
    ax.set_ylabel("dp/dt (bar/s)")
    ax.legend()
    return fig


def grid_with_log_axes():
    fig = new_figure(figsize=(15.0, 5.2), layout="constrained")
    axes = fig.subplots(2, 5, sharex="col")
    xi = np.linspace(0.0, 1.0, 100)
    for j in range(5):
        for k in range(3):
            axes[0, j].plot(xi, xi ** (1.0 + 0.2 * k), label=f"setting {k}")
        axes[1, j].semilogy(xi, 1e-6 + xi**3, label="ripple")
        axes[0, j].set_title(f"modulator {j}")
        axes[1, j].set_xlabel("input fraction")
    axes[0, 0].set_ylabel("pressure (bar)")
    axes[1, 0].set_ylabel("ripple (bar)")
    axes[0, -1].legend(loc="upper left", bbox_to_anchor=(1.02, 1.0))
    fig.suptitle("equilibrium and ripple")
    return fig


def traces():
    fig = new_figure(figsize=(10.0, 9.8), layout="constrained")
    axes = fig.subplots(4, 2, sharex=True)
    t = np.linspace(0.0, 20.0, 4000)
    for i, ax in enumerate(axes.ravel()):
        ax.plot(t, 0.5 + 0.3 * np.tanh(t - 5), label="reference")
        ax.plot(t, 0.5 + 0.3 * np.tanh(t - 5.3) + 0.01 * np.sin(40 * t), label="pressure")
        ax.set_title(f"loop {i}")
        ax.set_ylabel("p (bar)")
    axes[-1, 0].set_xlabel("time (s)")
    axes[0, 1].legend()
    return fig


FIGURES: dict[str, Callable] = {
    "one panel": one_panel,
    "2 x 5, log": grid_with_log_axes,
    "4 x 2 traces": traces,
}


def plain_savefig(fig, path: Path) -> None:
    """What save_figure did before: savefig runs the layout engine in a first drawing."""
    fig.savefig(
        path,
        dpi=png_dpi(fig),
        metadata={"Software": None},
        pil_kwargs={"compress_level": PNG_COMPRESS_LEVEL},
    )


def best(work: Callable[[], object], repeat: int) -> float:
    times = []
    for _ in range(repeat):
        start = time.process_time()
        work()
        times.append(time.process_time() - start)
    return min(times)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=5)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        print("| figure | savefig (s) | save_figure (s) | ratio | same |")
        print("|---|---:|---:|---:|---|")
        for name, make in FIGURES.items():
            plain_savefig(make(), folder / "warm.png")
            old = best(lambda m=make: plain_savefig(m(), folder / "a.png"), args.repeat)
            new = best(lambda m=make: save_figure(m(), folder / "b.png", vector=False), args.repeat)
            same = (folder / "a.png").read_bytes() == (folder / "b.png").read_bytes()
            print(f"| {name} | {old:.3f} | {new:.3f} | {old / new:.2f} | {same} |")

        n = 550_000
        rng = np.random.default_rng(0)
        table = pd.DataFrame(
            {
                "t": np.arange(n) * 1e-3,
                "p": rng.random(n) * 2.0,
                "valve": (rng.random(n) > 0.5).astype(np.int64),
                "u": np.repeat(np.linspace(0.0, 1.0, 55), 10_000),
                "run": "staircase-pwm-20Hz",
            }
        )

        def pandas_csv() -> None:
            table.to_csv(folder / "a.csv", index=False, float_format="%.10g", lineterminator="\n")

        old = best(pandas_csv, args.repeat)
        new = best(lambda: write_csv(table, folder / "b.csv"), args.repeat)
        same = (folder / "a.csv").read_bytes() == (folder / "b.csv").read_bytes()
        size = (folder / "b.csv").stat().st_size / 2**20
        print(
            f"\n| CSV, {n} rows x 5 ({size:.0f} MiB) | to_csv (s) | write_csv (s) | ratio | same |"
        )
        print("|---|---:|---:|---:|---|")
        print(f"| run table | {old:.3f} | {new:.3f} | {old / new:.2f} | {same} |")


if __name__ == "__main__":
    main()
