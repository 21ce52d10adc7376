"""Does identification name a second state where there is one, and only there?

Identifies (the full config's ``identification:``, ``laws: auto`` unless stated) and reads
``checks`` of the result: Ljung's whiteness of the closed forms (``white``) and the history
test (:func:`spa.identification.history.history_test`: ``p_history``, ``history_share``,
``second_state``; ``pressure_laws`` when the rates depend on the pressure otherwise than the
paper's laws), with the history test's own CPU time on the dataset.

Datasets:

* ``balloon-06`` (the full config's fixture) plain, with wall heat exchange (``heat_tau``
  2 s, adiabatic gas) and with a creeping chamber (``creep`` 15 cm3/bar in 2 s), each with
  ``laws: auto`` and ``laws: paper`` (the runs ``tests/test_laws_bench.py`` makes);
* the full config's ``sim`` (the paper's valve, made by the model) and ``phys-balloon``;
* the bundled bench dataset ``raw/example`` (copied to a temporary folder);
* ``--n`` random physical plants (:func:`spa.synthetic.draws.random_plant`, seed
  ``--seed``), each three ways: without wall heat exchange or creep (``plain``: the other
  effects as drawn), with heat exchange (``heat_tau`` 0.3-5 s, adiabatic gas) and with creep
  (10-50 % of the compliance in 0.3-5 s), the runs of ``benchmarks/physical_plants.py``.

A hit is ``second_state`` on a ``heat`` or ``creep`` plant, a false alarm on a ``plain`` one.

Run:  nice .venv/bin/python benchmarks/bench_second_state.py [--n 10] [--seed 1]
      [--csv /tmp/second_state.csv] [--skip-random | --random-only]
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import shutil
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pandas as pd
import yaml

from spa.identification import identify_with_config
from spa.identification.history import full_rate_records, history_test
from spa.identification.identify import run_context
from spa.identification.refine import prepare_runs
from spa.synthetic.balloons import compliant_balloons
from spa.synthetic.draws import random_plant
from spa.synthetic.physical import equivalent_params
from spa.synthetic.session import plant_session, staircase_hold

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))
DT = 1e-3
BALLOON_STATES = {
    "plain": {},
    "heat": {"heat_tau": 2.0, "polytropic": 1.4},
    "creep": {"creep": 15.0, "creep_tau": 2.0},
}


def _config() -> dict:
    return yaml.safe_load((ROOT / "config" / "config.yaml").read_text(encoding="utf-8"))


def _row(name: str, state: str, laws: str, runs, kinds, config, **kw) -> dict:
    """Identify one dataset and time its history test alone."""
    ident = {**config["identification"], "laws": laws}
    res = identify_with_config(runs, kinds, {"identification": ident}, **kw)
    d = res.to_dict()
    checks = d.get("checks") or {}
    hist = checks.get("history") or {}
    valve = res.to_valve_params()
    mods, steps = kw.get("modulators"), kw.get("command_dt")
    if "metas" in kw:
        mods, steps = run_context(kw["metas"])
    prepared = prepare_runs(runs, kinds, mods, steps)
    cpu = math.nan
    if prepared:
        start = time.process_time()
        history_test(full_rate_records(runs, prepared), valve)
        cpu = time.process_time() - start
    return {
        "dataset": name,
        "state": state,
        "laws_setting": laws,
        "laws": (d.get("laws") or {}).get("chosen", "paper"),
        "white": bool(checks.get("white", True)),
        "p_history": hist.get("p_history"),
        "history_share": hist.get("history_share"),
        "p_pressure": hist.get("p_pressure"),
        "pressure_share": hist.get("pressure_share"),
        "second_state": bool(checks.get("second_state", False)),
        "pressure_laws": bool(hist.get("pressure_laws", False)),
        "history_cpu_s": cpu,
        "sentences": " | ".join(
            s
            for s in d.get("warnings", ())
            if "second state" in s or "not white" in s or "paper's laws" in s
        ),
    }


def plant_runs(plant, modulators, experiments, seed: int, tag: str):
    """The runs a physical plant makes: identification experiments and ``experiments``."""
    session = plant_session(plant, modulators, seed, tag, experiments, dt=DT)
    return session.runs, session.kinds, session.identify_kwargs()


def balloon_rows(config: dict) -> list[dict]:
    mods = [
        {"type": "pwm", "f_w": 5.0},
        {"type": "iipfm", "t_l": 0.06, "gain": 1.25},
        {"type": "dsm", "period": 0.05},
    ]
    rows = []
    for state, change in BALLOON_STATES.items():
        plant = dataclasses.replace(compliant_balloons()["balloon-06"], **change)
        runs, kinds, kw = plant_runs(plant, mods, {"staircase": {"step": 0.1, "hold": 3.0}},
                                     1, "two")  # fmt: skip
        for laws in ("auto", "paper"):
            rows.append(_row("balloon-06", state, laws, runs, kinds, config, **kw))
            print(rows[-1], flush=True)
    return rows


def config_rows(config: dict, tmp: Path) -> list[dict]:
    from spa.datasets import ingest_dataset, read_runs
    from spa.synthetic.runs import generate_dataset

    rows = []
    for name in ("sim", "phys-balloon"):
        entry = config["simulated"][name]
        out = tmp / name
        generate_dataset(name, entry, config["experiments"], config.get("seed", 0), out)
        runs, metas = read_runs(out)
        kinds = {k: m["kind"] for k, m in metas.items()}
        rows.append(_row(name, "config", "auto", runs, kinds, config, metas=metas))
        print(rows[-1], flush=True)
    copy = tmp / "raw" / "example"
    shutil.copytree(ROOT / "raw" / "example", copy)
    ingest_dataset(copy, tmp / "example-runs")
    runs, metas = read_runs(tmp / "example-runs")
    kinds = {k: m["kind"] for k, m in metas.items()}
    rows.append(_row("raw/example", "bench", "auto", runs, kinds, config, metas=metas))
    print(rows[-1], flush=True)
    return rows


def random_rows(config: dict, n: int, seed: int) -> list[dict]:
    from physical_plants import MODULATORS

    rows = []
    for i in range(n):
        rng = np.random.default_rng([seed, i])
        drawn = random_plant(rng)
        plain = dataclasses.replace(drawn, heat_tau=0.0, creep=0.0, creep_tau=0.0)
        extra = np.random.default_rng([seed, i, 7]).uniform(size=3)
        growth = max(plain.compliance, 0.05 * plain.volume)
        variants = {
            "plain": plain,
            "heat": dataclasses.replace(plain, heat_tau=0.3 + 4.7 * extra[0], polytropic=1.4),
            "creep": dataclasses.replace(plain, creep=(0.1 + 0.4 * extra[1]) * growth,
                                         creep_tau=0.3 + 4.7 * extra[2]),
        }  # fmt: skip
        eq = equivalent_params(plain, DT)
        hold = staircase_hold(eq)
        for state, plant in variants.items():
            runs, kinds, kw = plant_runs(plant, MODULATORS,
                                         {"staircase": {"step": 0.1, "hold": hold}},
                                         seed, f"plant{i}")  # fmt: skip
            try:
                row = _row(f"random-{seed}-{i}", state, "auto", runs, kinds, config, **kw)
            except Exception as err:  # the benchmark reports every failure
                row = {"dataset": f"random-{seed}-{i}", "state": state, "error": str(err)}
            row.update({
                "supply": plant.supply, "heat_tau": plant.heat_tau, "creep": plant.creep,
                "creep_tau": plant.creep_tau, "compliance": plant.compliance,
                "other_effects": ",".join(k for k in ("leak", "tube_tau", "hose_volume",
                                                      "bounce") if getattr(plant, k) > 0),
            })  # fmt: skip
            rows.append(row)
            print(row, flush=True)
    return rows


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=10)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--csv", type=Path, default=None)
    ap.add_argument("--skip-random", action="store_true")
    ap.add_argument("--random-only", action="store_true", help="only the random plants")
    args = ap.parse_args(argv)
    config = _config()
    rows = []
    if not args.random_only:
        with tempfile.TemporaryDirectory() as tmp:
            rows = balloon_rows(config) + config_rows(config, Path(tmp))
    if not args.skip_random:
        rows += random_rows(config, args.n, args.seed)
    table = pd.DataFrame(rows)
    if args.csv:
        table.to_csv(args.csv, index=False)
    cols = ["dataset", "state", "laws", "white", "p_history", "history_share", "second_state",
            "pressure_laws", "history_cpu_s"]  # fmt: skip
    print(table[[c for c in cols if c in table]].to_string(index=False))
    rand = table[table["dataset"].str.startswith("random")]
    if len(rand):
        named = rand["second_state"].fillna(False).astype(bool)
        for state in ("heat", "creep", "plain"):
            sel = rand["state"] == state
            what = "false alarms" if state == "plain" else "hits"
            print(f"random {state}: {what} {int(named[sel].sum())}/{int(sel.sum())}")
    print(f"history test CPU: max {table['history_cpu_s'].max():.3f} s per dataset")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
