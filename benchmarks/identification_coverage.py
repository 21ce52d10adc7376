"""Coverage of the identification's 95 % intervals across the physical valve range.

Draws ``--n`` valves (seeded, log-uniform over c1 0.1-2 s*bar^-1/2, k2 0.2-6 bar, tau2
0.05-3 s, t_on 0.5-20 ms, t_off 1-40 ms), simulates each valve's identification experiments
(charge, discharge, pulse train; durations from
``spa.synthetic.identification_experiment_for``, logged at 1 kHz through the simulated sensor
of ``config/config.yaml``'s ``sim`` dataset: 5 mbar noise, 1 mbar ADC step, 10 mbar ringing),
identifies them with the config's ``identification:`` settings (the charge, discharge and
pulse fits, then the output-error refinement on every run) and reports, per parameter, the
fraction of 95 % intervals that contain the truth with a two-sided binomial test of the
nominal 95 % at the 1 % level (target: >= 93 % each, or the test does not reject), the median
relative error (median absolute error in ms for the delays) and the median interval width;
then every failure with its reason. ``--fs`` logs at another rate (e.g. 500 Hz of the 1 kHz
controller: the logging-step rule then applies).

Run:  nice .venv/bin/python benchmarks/identification_coverage.py [--n 100] [--seed 1]
      [--fs 1000] [--csv /tmp/ident/coverage.csv]
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd
import yaml
from scipy.stats import binomtest

from spa.identification import IdentificationError, identify_with_config
from spa.model.params import PHYSICAL_RANGE, ValveParams
from spa.synthetic import Sensor, identification_experiment_for, identification_runs
from spa.synthetic.runs import run_seed, simulate_run

ROOT = Path(__file__).resolve().parents[1]
RANGES = PHYSICAL_RANGE
NAMES = tuple(RANGES)


def draw_valves(n: int, seed: int) -> list[ValveParams]:
    """``n`` valves log-uniform over :data:`RANGES` (independent parameters)."""
    rng = np.random.default_rng(seed)
    cols = {k: np.exp(rng.uniform(math.log(a), math.log(b), n)) for k, (a, b) in RANGES.items()}
    return [ValveParams(**{k: float(cols[k][i]) for k in NAMES}) for i in range(n)]


def one_valve(
    params: ValveParams, index: int, config: dict, seed: int, fs: float | None = None
) -> dict:
    """Simulate and identify one valve; a row of the per-valve table."""
    cfg = config["simulated"]["sim"]
    dt = float(cfg["controller_dt"])
    sensor = Sensor.from_mapping({**cfg["sensor"], **({"fs": fs} if fs else {})})
    specs = identification_runs(params, dt, **identification_experiment_for(params))
    runs = {
        s.id: simulate_run(s, params, dt, sensor, run_seed(seed, f"v{index}", s.id)) for s in specs
    }
    kinds = {s.id: s.kind for s in specs}
    row: dict = {"valve": index, **{f"true_{k}": getattr(params, k) for k in NAMES}}
    start = time.perf_counter()
    try:
        res = identify_with_config(
            runs, kinds, config, seed=seed, command_dt={rid: dt for rid in runs}
        )
    except IdentificationError as err:
        row["error"] = f"IdentificationError: {err}"
    except Exception as err:  # the benchmark reports every failure
        row["error"] = f"{type(err).__name__}: {err}"
    else:
        row["error"] = ""
        for k in NAMES:
            est = getattr(res, k)
            row[f"{k}"], row[f"{k}_lo"], row[f"{k}_hi"] = est.value, est.lo, est.hi
            row[f"{k}_covered"] = est.contains(getattr(params, k))
        row["warnings"] = " | ".join(res.warnings)
    row["seconds"] = time.perf_counter() - start
    return row


def summary(table: pd.DataFrame) -> pd.DataFrame:
    """Per parameter: coverage, median error and interval width over the identified valves."""
    ok = table[table["error"] == ""]
    rows = []
    for k in NAMES:
        truth, est = ok[f"true_{k}"], ok[k]
        width = ok[f"{k}_hi"] - ok[f"{k}_lo"]
        delay = k.startswith("t_")
        hits = int(ok[f"{k}_covered"].astype(bool).sum())
        test = binomtest(hits, len(ok), 0.95) if len(ok) else None
        rows.append(
            {
                "parameter": k,
                "identified": len(ok),
                "coverage_%": 100.0 * hits / len(ok) if len(ok) else math.nan,
                "binomial_p": test.pvalue if test else math.nan,
                "meets_target": bool(test and (hits / len(ok) >= 0.93 or test.pvalue >= 0.01)),
                "median_error": (
                    f"{1e3 * (est - truth).abs().median():.3f} ms"
                    if delay
                    else f"{100 * ((est - truth) / truth).abs().median():.2f} %"
                ),
                "median_width": (
                    f"{1e3 * width.median():.3f} ms"
                    if delay
                    else f"{100 * (width / truth).median():.2f} %"
                ),
            }
        )
    return pd.DataFrame(rows)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=100, help="valves drawn (default 100)")
    ap.add_argument("--seed", type=int, default=1, help="seed of the draw and the noise")
    ap.add_argument("--config", default=str(ROOT / "config" / "config.yaml"))
    ap.add_argument("--csv", default=None, help="write the per-valve table here")
    ap.add_argument("--fs", type=float, default=None, help="logging rate, Hz (default: config)")
    args = ap.parse_args(argv)
    config = yaml.safe_load(Path(args.config).read_text())
    rows = []
    for i, params in enumerate(draw_valves(args.n, args.seed)):
        rows.append(one_valve(params, i, config, args.seed, args.fs))
        if args.csv:  # as it goes, so that an interrupted run keeps its valves
            Path(args.csv).parent.mkdir(parents=True, exist_ok=True)
            pd.DataFrame(rows).to_csv(args.csv, index=False)
        print(
            f"valve {i}: {rows[-1]['error'] or 'ok'} ({rows[-1]['seconds']:.1f} s)", file=sys.stderr
        )
    table = pd.DataFrame(rows)
    if args.csv:
        Path(args.csv).parent.mkdir(parents=True, exist_ok=True)
        table.to_csv(args.csv, index=False)
    print(f"{args.n} valves, seed {args.seed}, {int((table['error'] == '').sum())} identified")
    print(summary(table).to_markdown(index=False, floatfmt=".3g"))
    failed = table[table["error"] != ""]
    for _, r in failed.iterrows():
        truth = ", ".join(f"{k}={r[f'true_{k}']:.4g}" for k in NAMES)
        print(f"- valve {r['valve']} ({truth}): {r['error']}")
    ok = table[table["error"] == ""]
    for k in NAMES:
        miss = ok[~ok[f"{k}_covered"].astype(bool)]
        for _, r in miss.iterrows():
            print(
                f"  {k} not covered, valve {r['valve']}: true {r[f'true_{k}']:.5g}, "
                f"est {r[k]:.5g} [{r[f'{k}_lo']:.5g}, {r[f'{k}_hi']:.5g}]"
            )
    return 0


if __name__ == "__main__":
    sys.exit(main())
