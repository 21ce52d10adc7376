"""Benchmark: the closed loop on a valve with its own laws (issue 47, items 5 and 6).

Default run (about a minute):

* ``valve_params`` coercions along the closed-loop stage's work for one dataset
  (``spa.closedloop.promise.design_for_dataset`` on a valve with 95 % intervals on all five
  parameters, settings PWM 20 Hz, IIPFM 20 ms and, with laws, LPWM 14.2 Hz): the distinct
  call sites reached ("stops") and the calls, for the paper's valve and for the same valve
  with hand-made laws;
* LPWM's inverse of the laws: the largest ``|P_eq(d(xi)) - k2*xi|`` over 4001 values of
  ``xi``, hold and transport conventions;
* the closed loop's open-loop pieces (feed-forward only) against ``spa.simulate`` of the
  same command, 3 kinds x 2 conventions, 60 000 samples;
* the closed loop's speed, paper's laws and the valve's own (1 M samples, IIPFM).

``--balloons`` (about 5 minutes): each compliant balloon (``spa.synthetic.balloons``) is
simulated and identified through the identify entry; the laws valve is built from
``params.yaml``'s laws record (``spa.identification.load_params``); the closed-loop stage's
functions design, promise and export on it; the header is closed on the balloon in C over
the promise's staircase and the promise checked (``promise_kept``). The paper's valve of the
same identification is run beside it.

Run:  PYTHONPATH=. .venv/bin/python benchmarks/closed_loop_laws.py [--balloons]
"""

from __future__ import annotations

import argparse
import collections
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
import yaml

import spa
from spa.closedloop.controller import PIController
from spa.closedloop.loop import closed_loop_arrays
from spa.model import averaging
from spa.model import params as model_params
from spa.model.laws import Laws
from spa.model.modulators import Modulator
from spa.model.params import ValveParams

ROOT = Path(__file__).resolve().parents[1]
LAWS = Laws(log_g=(0.0, 0.3, 0.5, 0.2), log_h=(0.0, -0.2, -0.4, -0.5), m=0.8)
VALVE = ValveParams(c1=0.5, k2=0.8, tau2=0.7, t_on=0.004, t_off=0.009, laws=LAWS)
KINDS = {
    "pwm": {"type": "pwm", "f_w": 20.0},
    "iipfm": {"type": "iipfm", "t_l": 0.02, "gain": 1.15},
    "dsm": {"type": "dsm", "period": 0.02},
}


def coercions(laws: Laws | None) -> tuple[int, int, float]:
    """(stops, calls, seconds) of ``valve_params`` in ``design_for_dataset``."""
    from spa.closedloop.promise import design_for_dataset
    from spa.identification.identified import read_identified

    code = model_params.valve_params.__code__
    sites: collections.Counter = collections.Counter()

    def profile(frame, event, arg):
        if event == "call" and frame.f_code is code:
            sites[(frame.f_back.f_code.co_filename, frame.f_back.f_lineno)] += 1

    nominal = ValveParams().as_dict()
    identified = {k: {"value": v, "lo": 0.95 * v, "hi": 1.05 * v} for k, v in nominal.items()}
    cfg = {"levels": [0.2, 0.5], "step_hold": 1.0,
           "sine": {"offset": 0.35, "amplitude": 0.1, "frequency": 0.5, "duration": 3.0,
                    "skip": 1.0}}  # fmt: skip
    selected = [KINDS["iipfm"], {"type": "pwm", "f_w": 20.0}]
    kw = {}
    if laws is not None:
        ident = read_identified(identified)
        kw["valve"] = replace(ident, params=replace(ident.params, laws=laws))
        selected.append({"type": "lpwm", "f_w": 14.2})
    t = time.perf_counter()
    sys.setprofile(profile)
    try:
        design_for_dataset(identified, {}, {}, selected, cfg, **kw)
    finally:
        sys.setprofile(None)
    return len(sites), sum(sites.values()), time.perf_counter() - t


def model_numbers() -> None:
    for laws in (None, LAWS):
        stops, calls, secs = coercions(laws)
        which = "paper's laws" if laws is None else "own laws (+ LPWM)"
        print(f"valve_params on the stage's path, {which}: {stops} stops, {calls} calls, "
              f"{secs:.0f} s")  # fmt: skip
    for delay in ("hold", "transport"):
        v = replace(VALVE, delay=delay)
        mod = Modulator.from_mapping({"type": "lpwm", "f_w": 14.2}).bind(v)
        xi = np.linspace(0.001, 0.999, 4001)
        d = mod.spec.duty(xi, mod.settings, v)
        xi = xi[(d > 0) & (d < 1)]  # a clipped duty inverts nothing
        a1, a2 = mod.spec.fractions(xi, mod.settings, v)
        err = np.abs(averaging.equilibrium_pressure(a1, a2, v) - v.k2 * xi).max()
        print(f"LPWM inverse of the laws ({delay}): max |P_eq(d(xi)) - k2*xi| = {err:.2e} bar")
    n = 60000
    rng = np.random.default_rng(3)
    xi = np.clip(np.repeat(rng.uniform(-0.1, 1.1, 60), n // 60), 0, 1)
    k = np.arange(n, dtype=np.float64)
    ctrl = PIController(kp=0.0, ki=0.0, feedforward=(tuple(k), tuple(xi)))
    worst = 0.0
    for setting in KINDS.values():
        for delay in ("hold", "transport"):
            v = replace(VALVE, delay=delay)
            p, _, u = closed_loop_arrays(k, 1e-3, setting, ctrl, v, 0.2)
            worst = max(worst, float(np.abs(p - spa.simulate(u, 1e-3, v, p0=0.2)).max()))
    print(f"open-loop pieces against spa.simulate: max {worst:.2e} bar")
    r = np.repeat([0.2, 0.5, 0.3, 0.6], 250000)
    c = PIController(kp=1.0, ki=3.0)
    for name, v in (("paper's laws", replace(VALVE, laws=None)), ("own laws", VALVE)):
        closed_loop_arrays(r[:1000], 1e-3, KINDS["iipfm"], c, v)  # compiled, tables built
        t = time.perf_counter()
        closed_loop_arrays(r, 1e-3, KINDS["iipfm"], c, v)
        rate = r.size / (time.perf_counter() - t) / 1e6
        print(f"closed loop, {name}: {rate:.1f} M samples/s")


def balloons() -> None:
    from spa.closedloop.experiments import step_periods
    from spa.closedloop.promise import design_for_dataset, promise_kept
    from spa.datasets import read_runs
    from spa.identification import identify_with_config, load_params
    from spa.identification.identified import read_identified
    from spa.synthetic.balloons import BALLOON_SEEDS, SHORT_SESSION, compliant_balloons
    from spa.synthetic.physical import close_loop_in_c, measure_staircase
    from spa.synthetic.runs import generate_dataset

    config = yaml.safe_load((ROOT / "config" / "config.yaml").read_text())
    closed = {**config["closed_loop"], "levels_fraction": [0.2, 0.4, 0.6]}
    modulators = SHORT_SESSION["modulators"]
    experiments = SHORT_SESSION["experiments"]
    for name, plant in compliant_balloons().items():
        cfg = {"plant": {"kind": "physical", **plant.to_mapping()}, "controller_dt": 1e-3,
               "sensor": {"fs": 1000.0}, "modulators": modulators}  # fmt: skip
        with tempfile.TemporaryDirectory(prefix="spa-balloon-") as tmp:
            folder = Path(tmp) / name
            generate_dataset(name, cfg, experiments, BALLOON_SEEDS[name], folder)
            runs, metas = read_runs(folder)
            kinds = {r: m["kind"] for r, m in metas.items()}
            identified = identify_with_config(runs, kinds, {}, metas=metas).to_dict()
            print(f"{name}: laws chosen {identified['laws']['chosen']}")
            for which in ("own laws", "paper's laws"):
                valve = read_identified(identified)
                if which == "own laws":
                    valve = replace(valve, params=load_params(identified))
                t = time.perf_counter()
                result, bench = design_for_dataset(
                    identified, runs, metas, modulators, closed, valve=valve
                )
                promise = bench.summary["promise"]
                header = Path(tmp) / "controller.h"
                header.write_text(bench.header)
                levels = [float(v) for v in promise["levels"]]
                hold = float(promise["hold"])
                run = close_loop_in_c(
                    header, plant, levels, hold, lead=hold, rng=np.random.default_rng(7)
                )
                mod = Modulator.from_mapping(result.controllers["setting"])
                period = step_periods(mod, valve.params, levels, 1e-3)
                _, got = measure_staircase(run, period, skip=hold, r_initial=levels[0])
                _, true = measure_staircase(
                    run, period, column="p_true", skip=hold, r_initial=levels[0]
                )
                got = {**got, "worst_ripple_pp": true["worst_ripple_pp"]}
                verdict = promise_kept(got, promise, closed["max_overshoot"])
                print(
                    f"  {which}: {mod.label} {result.controllers.get('controller')}, verified "
                    f"{bench.summary['verified']}, promised overshoot "
                    f"{float(promise.get('overshoot', np.nan)):.2f} %, ripple "
                    f"{1e3 * float(promise.get('ripple_pp', np.nan)):.1f} mbar; on the balloon "
                    f"in C: overshoot {got['worst_overshoot']:.2f} %, end error "
                    f"{got['worst_error']:.2f} %, ripple {1e3 * got['worst_ripple_pp']:.1f} "
                    f"mbar; kept {verdict['kept']} ({time.perf_counter() - t:.0f} s)"
                )


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--balloons", action="store_true", help="the balloons end to end (slow)")
    args = ap.parse_args(argv)
    if args.balloons:
        balloons()
    else:
        model_numbers()
    return 0


if __name__ == "__main__":
    sys.exit(main())
