"""CPU cost of the laws' choice in identification: a dataset identified with
``identification.laws: auto`` against the same dataset with ``laws: paper`` (target: at most
1 CPU-s more).

Simulates each named dataset of the config (default: ``sim`` of config/small.yaml over
config/config.yaml, made with the paper's laws, and the compliant balloon ``balloon-06`` of
the full config, whose laws are not the paper's), identifies it once to compile the kernels,
then times ``spa.identification.identify_with_config`` in CPU seconds
(``time.process_time``) with each ``laws:`` setting, best of ``--repeat``, and prints the
laws chosen and the difference.

Run:  nice .venv/bin/python benchmarks/bench_laws_identify.py [--datasets sim balloon-06]
      [--config config/small.yaml] [--repeat 2]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import yaml

from spa.identification import identify_with_config
from spa.synthetic import Sensor
from spa.synthetic.runs import (
    dataset_experiments,
    dataset_plant,
    dataset_runs,
    run_seed,
    simulate_run,
)

ROOT = Path(__file__).resolve().parents[1]


def _merge(a: dict, b: dict) -> dict:
    out = dict(a)
    for k, v in b.items():
        out[k] = _merge(a[k], v) if isinstance(v, dict) and isinstance(a.get(k), dict) else v
    return out


def dataset(cfg: dict, name: str) -> tuple[dict, dict, dict, dict]:
    """The runs of the configured dataset ``name``, its kinds, modulators and command step."""
    sim = cfg["simulated"][name]
    plant, prm = dataset_plant(sim)
    dt = float(sim["controller_dt"])
    sensor = Sensor.from_mapping(sim["sensor"])
    seed = int(sim.get("seed", cfg["seed"]))
    specs = dataset_runs(sim, dataset_experiments(sim, cfg["experiments"]))
    runs = {
        s.id: simulate_run(s, prm, dt, sensor, run_seed(seed, name, s.id), plant) for s in specs
    }
    kinds = {s.id: s.kind for s in specs}
    mods = {s.id: (s.modulator or {}).get("type", "") for s in specs}
    return runs, kinds, mods, dict.fromkeys(runs, dt)


def identify_cpu(cfg: dict, data: tuple, laws: str, repeat: int) -> tuple[float, dict]:
    """Best CPU seconds of ``repeat`` identifications with ``identification.laws: laws``."""
    runs, kinds, mods, cdt = data
    settings = _merge(cfg, {"identification": {"laws": laws}})
    best, out = float("inf"), {}
    for _ in range(repeat):
        start = time.process_time()
        res = identify_with_config(runs, kinds, settings, modulators=mods, command_dt=cdt)
        best = min(best, time.process_time() - start)
        out = res.to_dict()
    return best, out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--datasets", nargs="+", default=["sim", "balloon-06"])
    ap.add_argument(
        "--config",
        default=str(ROOT / "config" / "small.yaml"),
        help="merged over config/config.yaml for datasets it keeps (the full config's otherwise)",
    )
    ap.add_argument("--repeat", type=int, default=2)
    args = ap.parse_args(argv)
    full = yaml.safe_load((ROOT / "config" / "config.yaml").read_text())
    small = _merge(full, yaml.safe_load(Path(args.config).read_text()))
    for name in args.datasets:
        cfg = small if small["simulated"].get(name) else full
        data = dataset(cfg, name)
        identify_with_config(*data[:2], cfg, modulators=data[2], command_dt=data[3])  # compile
        paper, _ = identify_cpu(cfg, data, "paper", args.repeat)
        auto, rec = identify_cpu(cfg, data, "auto", args.repeat)
        laws = rec.get("laws") or {}
        print(
            f"{name}: {len(data[0])} runs; identification {paper:.2f} CPU-s with the paper's "
            f"laws, {auto:.2f} CPU-s with laws: auto ({auto - paper:+.2f} CPU-s); laws chosen: "
            f"{laws.get('chosen')} (gain {laws.get('gain')}, se {laws.get('se')})",
            flush=True,
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
