"""CPU cost of the closed_loop stage on one processed dataset: the designs and tables, then
the promise over the box merged with the measured model error (bench outputs).

Run (after a small-config run into RESULTS):
    nice .venv/bin/python benchmarks/bench_closed_loop_stage.py RESULTS/sim [--config small]

Prints the CPU seconds of each part (numba warmed up first).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import yaml

ROOT = Path(__file__).resolve().parents[1]


def _merge(a: dict, b: dict) -> dict:
    out = dict(a)
    for k, v in b.items():
        out[k] = _merge(out[k], v) if isinstance(v, dict) and isinstance(out.get(k), dict) else v
    return out


def main(argv: list[str] | None = None) -> int:
    from spa.closedloop.bench import adequacy_of, bench_outputs, sensor_noise
    from spa.closedloop.comparison import closed_loop
    from spa.closedloop.model_error import dataset_error
    from spa.datasets import read_runs
    from spa.identification.identified import read_identified

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("dataset", type=Path, help="results/<dataset> of a processed dataset")
    ap.add_argument("--config", default="small", help="config/<name>.yaml over config.yaml")
    args = ap.parse_args(argv)
    cfg = yaml.safe_load((ROOT / "config" / "config.yaml").read_text())
    if args.config != "config":
        cfg = _merge(cfg, yaml.safe_load((ROOT / "config" / f"{args.config}.yaml").read_text()))
    d = args.dataset
    identified = yaml.safe_load((d / "identification" / "params.yaml").read_text())
    valve = read_identified(identified)
    rec = yaml.safe_load((d / "tuning" / "recommendation.yaml").read_text())
    c, selected = cfg["closed_loop"], cfg["analytic"]["selected"]
    closed_loop(valve.params, selected[:1], None, {**c, "step_hold": 0.5})  # numba warm-up
    t0 = time.process_time()
    result = closed_loop(valve.params, selected, rec, c)
    t1 = time.process_time()
    runs, metas = read_runs(d / "runs")
    with_ff = result.controllers.get("controller") == "scheduled_ff"
    error = dataset_error(runs, metas, valve.params, equilibrium=with_ff)
    t2 = time.process_time()
    bench_outputs(
        result,
        valve.params,
        valve.intervals,
        c,
        sensor_noise(identified),
        model_error=error,
        adequacy=adequacy_of(identified),
    )
    t3 = time.process_time()
    print(
        f"{d.name}: designs and tables {t1 - t0:.2f} CPU-s, model error {t2 - t1:.2f} CPU-s, "
        f"promise and disturbances {t3 - t2:.2f} CPU-s, total {t3 - t0:.2f} CPU-s"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
