"""Benchmark: the tuning stage for one dataset on the full grids (issue 14: at most 5 s).

What the rule `tune` does for one dataset, in one process:

* ``spa.tuning.tune`` on the paper's grids (PWM 1-80 Hz by 0.1 Hz, the others 12.5-1000 ms
  by 1 ms: 3,755 settings) with N = 100 input fractions: J (Eq. 25) and J_exact (the exact
  periodic steady state) for every setting, the constraint metrics of every candidate, the
  2**5 = 32 corners of the identification's 95 % box (each re-optimised, J_exact at each
  corner's optimum), Fig. 5's curves and the predicted staircase of the four recommended
  settings;
* then writing Table 1, Table 2, Fig. 4 and Fig. 5 (CSV and PNG) and recommendation.yaml.

The valve is raw/example's as identified by the full config (its point estimates and 95 %
intervals, below), or the params.yaml given with ``--params``. Times are wall-clock; "cold"
is the first call in the process, then the best of ``--repeat`` calls.

With ``--laws`` the same valve carries its own charge and discharge laws (:data:`LAWS`, rates
that vary with pressure and a discharge exponent m = 0.8): every P_eq, tau_m and orbit then
goes through the laws' root-finding and time maps instead of the paper's closed forms.

Run:  .venv/bin/python benchmarks/bench_tuning.py [--params PARAMS.yaml] [--laws]
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import yaml

from spa.identification.identified import read_identified
from spa.io import write_csv
from spa.model.laws import Laws
from spa.plots.save import save_figure
from spa.plots.tuning import plot_tuning_equilibrium, plot_tuning_sweeps
from spa.tuning import DEFAULT_SWEEPS, tune

#: raw/example as the full config identifies it (results/example/identification/params.yaml).
EXAMPLE = {
    "c1": {"value": 0.44944390109581195, "lo": 0.4486609666047503, "hi": 0.45024257004553453},
    "k2": {"value": 1.0498750895134736, "lo": 1.0495666486229196, "hi": 1.0501511251899507},
    "tau2": {"value": 0.6985864121292761, "lo": 0.6965358517572442, "hi": 0.70063816818187},
    "t_on": {"value": 0.003847310276742595, "lo": 0.003449872147659915, "hi": 0.004244748405825275},
    "t_off": {
        "value": 0.009051379743854594,
        "lo": 0.008969315228783036,
        "hi": 0.009133444258926152,
    },
}

#: The laws of ``--laws``: a compliant chamber's rates, relative to the paper's (knots at 0,
#: 1/3, 2/3 and 1 of k2).
LAWS = Laws(log_g=(0.0, 0.3, 0.5, 0.2), log_h=(0.0, -0.2, -0.4, -0.5), m=0.8)


def stage(source, folder: Path) -> tuple[float, float]:
    """Run the tuning stage once, writing its outputs into ``folder``.

    Returns wall-clock and CPU seconds of this process (CPU time is what the machine's load
    does not inflate).
    """
    start, cpu = time.perf_counter(), time.process_time()
    result = tune(source, sweeps=DEFAULT_SWEEPS, n_xi=100)
    write_csv(result.table1, folder / "table1.csv")
    write_csv(result.table2, folder / "table2.csv")
    write_csv(result.sweeps, folder / "fig4.csv")
    save_figure(plot_tuning_sweeps(result.sweeps, title="bench"), folder / "fig4.png")
    write_csv(result.curves, folder / "fig5.csv")
    save_figure(plot_tuning_equilibrium(result.curves), folder / "fig5.png")
    with open(folder / "recommendation.yaml", "w") as fh:
        yaml.safe_dump(dict(result.recommendation), fh, sort_keys=False, allow_unicode=True)
    return time.perf_counter() - start, time.process_time() - cpu


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--params", help="an identification's params.yaml (default: example)")
    parser.add_argument("--repeat", type=int, default=3, help="warm repeats (default 3)")
    parser.add_argument("--laws", action="store_true", help="the valve with its own laws")
    parser.add_argument("--once", metavar="DIR", help=argparse.SUPPRESS)  # the job's process
    args = parser.parse_args()
    source = read_identified(args.params if args.params else EXAMPLE)
    if args.laws:
        source = replace(source, params=replace(source.params, laws=LAWS))
    if args.once:
        stage(source, Path(args.once))
        return
    with tempfile.TemporaryDirectory() as tmp:  # like the rule's job: a fresh Python
        command = [sys.executable, __file__, "--once", tmp]
        if args.params:
            command += ["--params", args.params]
        if args.laws:
            command += ["--laws"]
        start = time.perf_counter()
        subprocess.run(command, check=True)
        job = time.perf_counter() - start
    print(f"valve: {source.params}")
    print(f"intervals: {len(source.intervals)} parameters, {2 ** len(source.intervals)} corners")
    print(f"cores: {os.cpu_count()}, load average {os.getloadavg()[0]:.2f}")
    with tempfile.TemporaryDirectory() as tmp:
        cold_stage = stage(source, Path(tmp))  # first call: includes lazy imports
        warm_stage = [stage(source, Path(tmp)) for _ in range(args.repeat)]
    warm_tune = []
    for _ in range(args.repeat):
        start = time.perf_counter()
        result = tune(source, sweeps=DEFAULT_SWEEPS, n_xi=100)
        warm_tune.append(time.perf_counter() - start)

    print(f"settings: {len(result.sweeps)} swept, {len(result.candidates)} candidates")
    best = min(warm_stage)
    print("                                          wall    CPU")
    print(f"whole job (new process, imports, stage): {job:5.2f} s")
    print(f"stage with outputs, cold (first call):   {cold_stage[0]:5.2f} s {cold_stage[1]:5.2f} s")
    print(f"stage with outputs, best of {args.repeat}:         {best[0]:5.2f} s {best[1]:5.2f} s")
    print(f"tune() alone, best of {args.repeat}:               {min(warm_tune):5.2f} s")
    print(f"load average after: {os.getloadavg()[0]:.2f}; target: the stage <= 5 s")
    print(f"recommendation: {result.sentence}")


if __name__ == "__main__":
    main()
