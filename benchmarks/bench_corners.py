"""The tuning's box corners (``spa.tuning.tables._corner_optima``): every corner's ΔΣ orbits
in one Newton iteration against one call a corner, on an identified valve of the pipeline.

    .venv/bin/python benchmarks/bench_corners.py results/sim/identification/params.yaml \\
        --config config/small.yaml --repeat 5

CPU seconds, best of ``--repeat``, in one warm process; the two results must be identical.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from spa.identification.identified import read_identified
from spa.io import read_yaml
from spa.tuning.cost import check_sweeps
from spa.tuning.intervals import box_points
from spa.tuning.tables import _corner_optima


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("params", type=Path, help="a params.yaml with intervals")
    parser.add_argument("--config", type=Path, default=Path("config/small.yaml"))
    parser.add_argument("--repeat", type=int, default=5)
    args = parser.parse_args()
    analytic = read_yaml(args.config)["analytic"]
    identified = read_identified(args.params)
    grids = check_sweeps(analytic["sweeps"], identified.params)
    n_xi = analytic["n_xi"]
    points = box_points(identified.params, identified.intervals)
    _corner_optima(grids, points[:2], n_xi)  # warm
    best = {"one call": np.inf, "a call a corner": np.inf}
    for _ in range(args.repeat):
        start = time.process_time()
        batch = _corner_optima(grids, points, n_xi)
        best["one call"] = min(best["one call"], time.process_time() - start)
        start = time.process_time()
        alone = np.stack([_corner_optima(grids, [q], n_xi)[0] for q in points])
        best["a call a corner"] = min(best["a call a corner"], time.process_time() - start)
    same = np.array_equal(batch, alone)
    print(
        f"{len(points)} valves, {len(grids)} modulators, {args.config}: one call "
        f"{best['one call']:.3f} s, a call a corner {best['a call a corner']:.3f} s, "
        f"identical: {same}"
    )


if __name__ == "__main__":
    main()
