"""Identification, and a designed controller, on physical plants that are not the model.

Draws ``--n`` plants with :func:`spa.synthetic.physical.random_plant` (supply 0.5-6 bar
gauge, dead times 2-25 ms with opening != closing, 30-100 % volume growth over the range,
sensor lag up to 5 ms; seeded), and for each:

1. generates a dataset made by the plant: the identification experiments (durations from
   ``spa.synthetic.identification_experiment_for`` on the plant's equivalent model) and a
   staircase of the input fraction (0 -> 1 by 0.1, each level held ``max(3 s, 5 tau2)``)
   through PWM 20 Hz, IIPFM 20 ms G 1.15 and DSM 20 ms, logged at 1 kHz;
2. identifies the valve with the configuration's ``identification:`` (the charge, discharge
   and pulse fits, then the refinement on every run with a valve command);
3. scores the identified model on each staircase: held out (leave one run out) and with the
   FIT of ``validation/fit.csv``;
4. with ``--closed-loop``: designs a fixed PI at the identified valve for PWM (20 Hz, slower
   when the identified delays need it; ``spa.closedloop.export.export_designed``, levels at
   20/40/60 % of the identified supply that it holds, each held as long as a staircase
   level), closes the exported ``controller.h``
   on the plant in C (``spa.synthetic.physical.close_loop_in_c``) and measures the staircase
   as spa measures its own (``measure_staircase``): worst overshoot, unsettled steps, worst
   error and ripple.

5. with ``--promise``: reads the adequacy verdict, runs the ``closed_loop`` stage's design
   for the dataset (``spa.closedloop.promise.design_for_dataset``: the config's
   ``analytic.selected``, its ``closed_loop:``, the model error of the staircases, the promise
   over the merged box), closes the exported header on the plant in C over the promise's
   levels and hold (settled at the first level) and checks the promise
   (``spa.closedloop.promise.promise_kept``).

Identification gets the runs' modulators and the command's step, as the pipeline does; the
held-out staircase FIT is each staircase's leave-one-run-out FIT of the cycle means
(``refinement.fit_heldout``, or the laws' ``laws.fit_identified`` when the actuator's own
laws were chosen: identification runs with the configuration's ``identification.laws``,
``auto``, and every score uses the valve the stages get, ``read_identified`` of the record);
``fit_<run>`` is the identified model's FIT on the raw pressure
(``validation/fit.csv``'s, in-sample since the refinement sees every run). One CSV row per
plant, with its ``seed``, ``laws`` chosen and whether it is ``compliant_low_supply``
(``spa.synthetic.balloons.compliant_low_supply``), so that
``benchmarks/physical_pair.py`` can pair two tables plant by plant; a summary on stdout
(targets: held-out median staircase FIT >= 85 %, promise kept on >= 90 % of plants, at
most 10 % unverified).

Run:  nice .venv/bin/python benchmarks/physical_plants.py [--n 20] [--seed 1]
      [--closed-loop] [--promise] [--csv /tmp/physplant/plants.csv]
"""

from __future__ import annotations

import argparse
import math
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pandas as pd
import yaml

from spa.identification import identify_with_config
from spa.identification.identified import read_identified
from spa.synthetic.balloons import compliant_low_supply
from spa.synthetic.physical import (
    PHYSICAL_KEYS,
    close_loop_in_c,
    measure_staircase,
    random_plant,
)
from spa.synthetic.session import plant_session, staircase_hold
from spa.validation import validate_run

ROOT = Path(__file__).resolve().parents[1]
MODULATORS = (
    {"type": "pwm", "f_w": 20.0},
    {"type": "iipfm", "t_l": 0.020, "gain": 1.15},
    {"type": "dsm", "period": 0.020},
)
DT = 1e-3
NAMES = ("c1", "k2", "tau2", "t_on", "t_off")


def one_plant(
    index: int, seed: int, config: dict, closed_loop: bool, promise: bool = False
) -> dict:
    """Generate, identify and score one plant; a row of the table."""
    rng = np.random.default_rng([seed, index])
    plant = random_plant(rng)
    start = time.perf_counter()
    session = plant_session(plant, MODULATORS, seed, f"plant{index}", dt=DT)
    generate_s = time.perf_counter() - start
    eq = session.params  # the plant's equivalent valve, which the experiments were designed for
    row: dict = {
        "seed": seed,
        "plant": index,
        "compliant_low_supply": bool(
            compliant_low_supply(plant.supply, plant.volume, plant.compliance)
        ),
        **{f"plant_{k}": getattr(plant, k) for k in PHYSICAL_KEYS},
    }
    row.update({f"eq_{k}": getattr(eq, k) for k in NAMES})
    hold = staircase_hold(eq)
    runs, kinds, metas = session.runs, session.kinds, session.metas
    mods = {s.id: s.modulator for s in session.specs}
    row["generate_s"] = generate_s
    start = time.perf_counter()
    try:
        res = identify_with_config(
            runs, kinds, {**config, "seed": seed}, **session.identify_kwargs()
        )
    except Exception as err:  # the benchmark reports every failure
        row["error"] = f"{type(err).__name__}: {err}"
        return row
    row["error"] = ""
    row["identify_s"] = time.perf_counter() - start
    identified = res.to_dict()
    # the valve every stage gets: read_identified of the identification's record (with the
    # actuator's own laws when they were chosen)
    ident = read_identified(identified).params
    row.update({k: getattr(ident, k) for k in NAMES})
    laws = identified.get("laws") or {}
    row["laws"] = laws.get("chosen", "paper")
    row["laws_valve"] = ident.laws is not None
    row["laws_gain"] = laws.get("gain")
    fits = []
    for rid, kind in kinds.items():
        if kind == "staircase":
            fit = validate_run(runs[rid], ident, mods[rid]).fit_percent
            row[f"fit_{rid}"] = fit
            fits.append(fit)
    row["insample_median_fit"] = float(np.median(fits))
    ref = identified.get("refinement") or {}
    # held out under the laws chosen: the laws' own leave-one-run-out FIT when identified
    heldout = laws.get("fit_identified") if row["laws"] == "identified" else ref.get("fit_heldout")
    held = {k: v for k, v in (heldout or {}).items() if kinds.get(k) == "staircase"}
    for rid, fit in held.items():
        row[f"heldout_{rid}"] = fit
    vals = [v for v in held.values() if v is not None and math.isfinite(v)]
    row["heldout_median_fit"] = float(np.median(vals)) if vals else math.nan
    adequacy = identified.get("adequacy") or {}
    row["adequate"] = bool(adequacy.get("adequate", False))
    row["adequacy_heldout_median"] = (adequacy.get("heldout_fit") or {}).get("median")
    convention = identified.get("delay_convention") or {}
    row["convention"] = convention.get("chosen")
    for d, v in (convention.get("heldout_fit_modulated") or {}).items():
        row[f"heldout_modulated_{d}"] = v
    if closed_loop:
        row.update(_closed_loop(plant, ident, rng, hold))
    if promise:
        row.update(_promise(plant, identified, runs, metas, config, rng))
    return row


def _promise(plant, identified, runs, metas, config, rng) -> dict:
    """The closed-loop stage's design for this dataset (its choice, the promise over the box
    merged with the measured model error, the header), then the header closed on the plant
    in C over the promise's staircase, settled at its first level, measured as spa measures
    (``spa.closedloop.promise.promise_kept``)."""
    from spa.closedloop.experiments import step_periods
    from spa.closedloop.promise import design_for_dataset, promise_kept
    from spa.model.modulators import Modulator

    start = time.perf_counter()
    cfg = config.get("closed_loop") or {}
    try:
        result, bench = design_for_dataset(
            identified, runs, metas, config["analytic"]["selected"], cfg
        )
    except Exception as err:
        return {"promise_error": f"{type(err).__name__}: {err}"}
    summary = bench.summary or {}
    promise = summary.get("promise") or {}
    out: dict = {
        "design_s": time.perf_counter() - start,
        "promise_error": "",
        "chosen": Modulator.from_mapping(result.controllers["setting"]).label
        if result.controllers.get("setting")
        else "",
        "verified": bool(summary.get("verified", False)),
        "adequacy_clause": summary.get("adequacy_clause", ""),
        "sentence": bench.sentence,
        "promise_made": bool(promise.get("kept", False)),
        "promise_tau_c": promise.get("tau_c"),
        "promise_overshoot": promise.get("overshoot"),
        "promise_ripple_pp": promise.get("ripple_pp"),
        "promise_hold": promise.get("hold"),
    }
    if not promise or not result.controllers.get("setting"):
        return {**out, "kept": False}
    levels, hold = [float(v) for v in promise["levels"]], float(promise["hold"])
    mod = Modulator.from_mapping(result.controllers["setting"])
    period = step_periods(mod, res_params(identified), levels, DT)
    with tempfile.TemporaryDirectory(prefix="spa-bench-") as tmp:
        header = Path(tmp) / "controller.h"
        header.write_text(bench.header)
        try:
            run = close_loop_in_c(header, plant, levels, hold, lead=hold, rng=rng)
        except Exception as err:
            return {**out, "kept": False, "promise_error": f"{type(err).__name__}: {err}"}
    _, measured = measure_staircase(run, period, skip=hold, r_initial=levels[0])
    # the limit cycle is the actuator's: its ripple from the true pressure (the log adds the
    # sensor's noise and mains pickup)
    _, actual = measure_staircase(run, period, column="p_true", skip=hold, r_initial=levels[0])
    measured = {**measured, "worst_ripple_pp": actual["worst_ripple_pp"]}
    verdict = promise_kept(measured, promise, float(cfg.get("max_overshoot", 10.0)))
    return {
        **out,
        **{f"plant_{k}": v for k, v in measured.items()},
        **{f"check_{k}": v for k, v in verdict.items()},
        "kept": verdict["kept"] and out["verified"],
    }


def res_params(identified: dict):
    """The identified valve of a ``params.yaml`` mapping."""
    from spa.identification.identified import read_identified

    return read_identified(identified).params


def _closed_loop(plant, ident, rng, hold: float) -> dict:
    """A fixed PI designed at the identified valve, exported and closed on the plant in C.

    PWM at 20 Hz, or slower when the identified delays need it (``f_w <= 0.25/(t_on +
    t_off)``); the levels 20/40/60 % of the identified supply that the setting holds on the
    identified valve (``spa.closedloop.design.operating_levels``, spread when fewer fit).
    """
    from spa.closedloop.design import operating_levels
    from spa.closedloop.export import export_designed

    f_w = float(max(1, min(20, math.floor(0.25 / max(ident.t_on + ident.t_off, 1e-3)))))
    setting = {"type": "pwm", "f_w": f_w}
    wanted = [round(f * ident.k2, 3) for f in (0.2, 0.4, 0.6)]
    levels, why = operating_levels(wanted, setting, ident, spread=True)
    out: dict = {"loop_f_w": f_w, "loop_levels": str(levels)}
    if why is not None:
        return {**out, "loop_error": why}
    with tempfile.TemporaryDirectory(prefix="spa-bench-") as tmp:
        try:
            header, _ = export_designed(tmp, ident, setting, controller="fixed", levels=levels)
            run = close_loop_in_c(header, plant, levels, hold, rng=rng)
        except Exception as err:
            return {**out, "loop_error": f"{type(err).__name__}: {err}"}
    _, summary = measure_staircase(run, 1.0 / f_w)
    return {**out, "loop_error": "", **{f"loop_{k}": v for k, v in summary.items()}}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--n", type=int, default=20, help="plants drawn")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--closed-loop", action="store_true", help="also close a designed PI in C")
    ap.add_argument(
        "--promise",
        action="store_true",
        help="the closed-loop stage's design and promise, its header closed on the plant in C",
    )
    ap.add_argument("--csv", type=Path, default=None, help="per-plant table")
    args = ap.parse_args(argv)
    config = yaml.safe_load((ROOT / "config" / "config.yaml").read_text())
    rows = []
    for i in range(args.n):
        row = one_plant(i, args.seed, config, args.closed_loop, args.promise)
        rows.append(row)
        fit = row.get("heldout_median_fit", float("nan"))
        print(
            f"plant {i}: supply {row['plant_supply']:.2f} bar, dead times "
            f"{1e3 * row['plant_t_open']:.1f}/{1e3 * row['plant_t_close']:.1f} ms; identified "
            f"t_on/t_off {1e3 * row.get('t_on', math.nan):.1f}/"
            f"{1e3 * row.get('t_off', math.nan):.1f} ms; held-out median FIT {fit:.1f} %"
            + (f"; loop overshoot {row['loop_worst_overshoot']:.1f} %, "
               f"{row['loop_unsettled']} unsettled" if "loop_worst_overshoot" in row else "")
            + (f"; loop: {row['loop_error']}" if row.get("loop_error") else "")
            + (f"; {row['error']}" if row.get("error") else "")
            + (f"; chose {row.get('chosen')}, verified {row.get('verified')}, promised "
               f"{row.get('promise_overshoot')} % (made {row.get('promise_made')}), on plant "
               f"{row.get('plant_worst_overshoot', math.nan):.1f} %, end error "
               f"{row.get('plant_worst_error', math.nan):.2f} %, ripple "
               f"{1e3 * row.get('plant_worst_ripple_pp', math.nan):.1f} mbar, kept "
               f"{row.get('kept')} {row.get('promise_error') or ''}" if "kept" in row else ""),
            flush=True,
        )  # fmt: skip
    table = pd.DataFrame(rows)
    if args.csv is not None:
        args.csv.parent.mkdir(parents=True, exist_ok=True)
        table.to_csv(args.csv, index=False)
    ok = table[table["error"] == ""]
    print(f"\n{len(ok)} of {len(table)} plants identified")
    if len(ok):
        fits = ok["heldout_median_fit"]
        print(
            f"held-out staircase FIT, median over plants of each plant's median: "
            f"{fits.median():.1f} % (>= 85 %: {100 * (fits >= 85).mean():.0f} % of plants)"
        )
    if "kept" in table:
        n = len(table)
        made = table.get("promise_made", pd.Series(dtype=bool)).fillna(False).astype(bool)
        unver = ~table.get("verified", pd.Series(False, index=table.index)).fillna(False).astype(
            bool
        )
        kept = table["kept"].fillna(False).astype(bool)
        print(
            f"adequate: {int(table['adequate'].fillna(False).astype(bool).sum())} of {n}; "
            f"promise made (kept over the box, meets max_overshoot): {int(made.sum())} of {n}; "
            f"unverified: {int(unver.sum())} of {n} ({100 * unver.mean():.0f} %); "
            f"promise kept on the plant in C (verified, overshoot within 5 points, every level "
            f"within 2 %, ripple within 2x): {int(kept.sum())} of {n} ({100 * kept.mean():.0f} %)"
        )
    if "loop_worst_overshoot" in table:
        loop = table[table.get("loop_error", "") == ""]
        print(
            f"closed loop (fixed PI from the identified valve, PWM, in C): median worst "
            f"overshoot {loop['loop_worst_overshoot'].median():.1f} %, plants with an "
            f"unsettled level {int((loop['loop_unsettled'] > 0).sum())} of {len(loop)}"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
