"""CPU time and memory of the output-error refinement of one dataset (target: ~1 CPU-s, 300 MB).

Simulates a dataset of the config (default: ``sim`` of config/small.yaml over
config/config.yaml), runs the charge/discharge/pulse fits, then times
``spa.identification.identify.refine_result`` (both delay conventions, adequacy) in CPU
seconds and reports the process's peak resident memory.

Run:  nice .venv/bin/python benchmarks/bench_refine.py [--config config/small.yaml]
      [--dataset sim] [--runs RESULTS/example/runs]
"""

from __future__ import annotations

import argparse
import resource
import sys
import time
import tracemalloc
from pathlib import Path

import yaml

from spa.identification import identify_with_config
from spa.identification.refined import refine_result
from spa.model.params import ValveParams
from spa.synthetic import Sensor
from spa.synthetic.runs import dataset_experiments, dataset_runs, run_seed, simulate_run

ROOT = Path(__file__).resolve().parents[1]


def _merge(a: dict, b: dict) -> dict:
    out = dict(a)
    for k, v in b.items():
        out[k] = _merge(a[k], v) if isinstance(v, dict) and isinstance(a.get(k), dict) else v
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--config", default=str(ROOT / "config" / "small.yaml"))
    ap.add_argument("--dataset", default="sim")
    ap.add_argument(
        "--runs",
        type=Path,
        default=None,
        help="a processed dataset's runs folder (results/<ds>/runs), e.g. a bench dataset's",
    )
    args = ap.parse_args(argv)
    cfg = yaml.safe_load((ROOT / "config" / "config.yaml").read_text())
    if Path(args.config).resolve() != (ROOT / "config" / "config.yaml").resolve():
        cfg = _merge(cfg, yaml.safe_load(Path(args.config).read_text()))
    if args.runs is not None:
        from spa.datasets import read_runs

        runs, metas = read_runs(args.runs)
        kinds = {r: m["kind"] for r, m in metas.items()}
        mods = {r: m["modulator"].kind if m.get("modulator") else "" for r, m in metas.items()}
        cdt = {r: m["controller_dt"] for r, m in metas.items() if m.get("controller_dt")}
    else:
        sim = cfg["simulated"][args.dataset]
        specs = dataset_runs(sim, dataset_experiments(sim, cfg["experiments"]))
        prm, dt = ValveParams(**sim["params"]), float(sim["controller_dt"])
        sensor = Sensor.from_mapping(sim["sensor"])
        runs = {
            s.id: simulate_run(s, prm, dt, sensor, run_seed(1, args.dataset, s.id)) for s in specs
        }
        kinds = {s.id: s.kind for s in specs}
        mods = {s.id: (s.modulator or {}).get("type", "") for s in specs}
        cdt = dict.fromkeys(runs, dt)
    base = identify_with_config(runs, kinds, _merge(cfg, {"identification": {"refine": False}}))
    refine_result(base, runs, kinds, modulators=mods)  # compile the numba kernel first
    start = time.process_time()
    res = refine_result(base, runs, kinds, modulators=mods, command_dt=cdt)
    cpu = time.process_time() - start
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    tracemalloc.start()  # a second, traced run: the memory the refinement itself allocates
    refine_result(base, runs, kinds, modulators=mods, command_dt=cdt)
    own = tracemalloc.get_traced_memory()[1] / 2**20
    tracemalloc.stop()
    samples = sum(len(t) for t in runs.values())
    name = args.runs.parent.name if args.runs else args.dataset
    print(
        f"{name}: {len(runs)} runs, {samples:,} samples; refinement (both conventions, "
        f"adequacy) {cpu:.2f} CPU-s, {res.refinement['simulations']} dataset simulations; "
        f"peak RSS of the process (data included) {peak:.0f} MB, allocated by the refinement "
        f"at its peak {own:.0f} MB"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
