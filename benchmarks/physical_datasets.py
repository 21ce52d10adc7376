"""The full config's physical-plant datasets: does each exported controller keep its promise?

Runs ``snakemake reproduce-all`` on the full config with only the datasets made by a physical
plant (``simulated.<name>.plant``; the model's simulated datasets and the bench datasets of
``raw/`` left out, no figures) into ``--results``, then for each dataset:

1. reads ``identification/params.yaml`` (convention, held-out staircase FIT, adequacy) and
   ``closed_loop/controllers.yaml`` (the shipped loop and its promise);
2. compiles the exported ``closed_loop/controller.h`` with the dataset's plant in C
   (``spa.synthetic.physical.close_loop_in_c``), runs the promise's staircase up and down
   with each level held the promise's hold (settled at the first level), and measures it as
   spa measures its own (``measure_staircase``, each step's cycle-mean window the
   modulator's cycle at its level; the limit cycle on the actuator's pressure ``p_true``);
3. checks the promise (``spa.closedloop.promise.promise_kept``): made and within
   ``closed_loop.max_overshoot``, verified, worst overshoot within 5 points of it, every
   level within 2 % of its step at the end of its hold, ripple at most twice the promised.

Run:  nice .venv/bin/python benchmarks/physical_datasets.py [--results /tmp/phys-res]
      [--skip-run] [--cores 2]
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
import pandas as pd
import yaml

from spa.closedloop.experiments import step_periods
from spa.closedloop.promise import promise_kept
from spa.identification.results import load_params
from spa.model.modulators import Modulator
from spa.synthetic.physical import PhysicalPlant, close_loop_in_c, measure_staircase

ROOT = Path(__file__).resolve().parents[1]
DT = 1e-3


def physical_only(config: dict) -> dict:
    """The overrides that keep only the datasets a physical plant makes."""
    simulated = config.get("simulated") or {}
    return {
        "simulated": {k: None for k, v in simulated.items() if not (v or {}).get("plant")},
        "datasets": {"exclude": ["example"]},
        "figures": "none",
    }


def check(results: Path, name: str, config: dict) -> dict:
    """One dataset's row: identification, promise and what its header does on the plant."""
    folder = results / name
    params = yaml.safe_load((folder / "identification" / "params.yaml").read_text())
    ctl = yaml.safe_load((folder / "closed_loop" / "controllers.yaml").read_text())
    valve = load_params(params)
    kinds = {k: v for k, v in (params.get("refinement") or {}).get("fit_heldout", {}).items()}
    stairs = [v for k, v in kinds.items() if k.startswith("staircase") and v is not None]
    bench = ctl.get("bench") or {}
    promise = bench.get("promise") or {}
    row = {
        "dataset": name,
        "convention": (params.get("delay_convention") or {}).get("chosen"),
        "heldout_staircase_fit_median": float(np.median(stairs)) if stairs else np.nan,
        "setting": Modulator.from_mapping(ctl["setting"]).label if ctl.get("setting") else "",
        "controller": ctl.get("controller", ""),
        "verified": bool(bench.get("verified", False)),
        "promise_overshoot": promise.get("overshoot"),
        "promise_ripple_pp": promise.get("ripple_pp"),
        "promise_tau_c": promise.get("tau_c"),
    }
    if not promise.get("levels") or not ctl.get("setting"):
        return {**row, "kept": False}
    plant = PhysicalPlant.from_mapping(config["simulated"][name]["plant"])
    levels, hold = [float(v) for v in promise["levels"]], float(promise["hold"])
    run = close_loop_in_c(
        folder / "closed_loop" / "controller.h",
        plant,
        levels,
        hold,
        lead=hold,
        rng=np.random.default_rng(1),
    )
    period = step_periods(Modulator.from_mapping(ctl["setting"]), valve, levels, DT)
    _, measured = measure_staircase(run, period, skip=hold, r_initial=levels[0])
    _, actual = measure_staircase(run, period, column="p_true", skip=hold, r_initial=levels[0])
    measured = {**measured, "worst_ripple_pp": actual["worst_ripple_pp"]}
    limit = float((config.get("closed_loop") or {}).get("max_overshoot", 10.0))
    verdict = promise_kept(measured, promise, limit)
    return {
        **row,
        "plant_worst_overshoot": measured["worst_overshoot"],
        "plant_worst_end_error": measured["worst_error"],
        "plant_ripple_pp": measured["worst_ripple_pp"],
        "kept": bool(verdict["kept"] and row["verified"]),
    }


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--results", type=Path, default=Path("/tmp/phys-res"))
    ap.add_argument("--skip-run", action="store_true", help="only check an existing results dir")
    ap.add_argument("--cores", type=int, default=2)
    args = ap.parse_args(argv)
    config = yaml.safe_load((ROOT / "config" / "config.yaml").read_text())
    if not args.skip_run:
        with tempfile.TemporaryDirectory(prefix="spa-phys-") as tmp:
            override = Path(tmp) / "physical.yaml"
            override.write_text(yaml.safe_dump(physical_only(config)))
            cmd = [
                str(ROOT / ".venv" / "bin" / "snakemake"),
                "reproduce-all",
                f"-c{args.cores}",
                "--configfile",
                str(override),
                "--config",
                f"results={args.results}",
            ]
            subprocess.run(cmd, cwd=ROOT, check=True, stdout=subprocess.DEVNULL)
    names = [k for k, v in (config.get("simulated") or {}).items() if (v or {}).get("plant")]
    table = pd.DataFrame([check(args.results, name, config) for name in names])
    with pd.option_context("display.width", 200, "display.max_columns", 20):
        print(table.round(3).to_string(index=False))
    print(f"promise kept on the plant: {int(table['kept'].sum())} of {len(table)}")
    return 0 if bool(table["kept"].all()) else 1


if __name__ == "__main__":
    sys.exit(main())
