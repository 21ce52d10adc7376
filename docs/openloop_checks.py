"""The numbers behind the README's "Open-loop linearity" section that no results table holds.

Run from the repository root, after the full config (``snakemake reproduce-all``):

    .venv/bin/python docs/openloop_checks.py [results]

Each block is labelled like the README statement it supports. Everything is computed with
spa from the config (config/config.yaml), the nominal valve parameters and, for [A] and
[B], the simulated dataset's runs under ``results/sim``; nothing is fitted or hard-coded.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pandas as pd
import yaml

from spa.datasets import read_runs
from spa.model.averaging import time_constant, time_fractions
from spa.model.params import ValveParams
from spa.openloop import (
    PAPER_SETTINGS,
    PAPER_TIME_CONSTANTS,
    chirp_reference,
    principal_domain_mask,
    reference_run,
    reference_time_constant,
    run_tags,
    runs_of_kind,
    sine_analysis,
    staircase_analysis,
)
from spa.synthetic import (
    RunSpec,
    Sensor,
    chirp_input,
    modulated_runs,
    simulate_run,
    staircase_input,
)

ROOT = Path(__file__).resolve().parents[1]
NOMINAL = ValveParams()


def sine_bands(results: Path) -> None:
    """[A] Fig. 8 at 0.02 Hz: RMS deviation below and above xi = 0.5, the paper's settings."""
    runs, metas = read_runs(results / "sim" / "runs")
    ids = runs_of_kind(metas, "sine")
    tags = run_tags(metas, ids)
    paper = {m.label for m in PAPER_SETTINGS}
    print("[A] sine: RMS of P/max(P) - xi over xi < 0.5 and xi >= 0.5")
    for rid in ids:
        if tags.loc[rid, "setting"] not in paper:
            continue
        settle = float(metas[rid]["experiment"]["settle"])
        aligned, summary = sine_analysis(runs[rid], settle=settle)
        dev = aligned["p_norm"] - aligned["xi"]
        low = aligned["xi"] < 0.5
        print(
            f"    {tags.loc[rid, 'setting']:18s} all {summary['rms']:.3f}  "
            f"xi<0.5 {np.sqrt(np.mean(dev[low] ** 2)):.3f}  "
            f"xi>=0.5 {np.sqrt(np.mean(dev[~low] ** 2)):.3f}"
        )


def linear_sine(config: dict) -> None:
    """[B] The linear reference's sine deviation against the sine's frequency and tau_m."""
    mods = config["simulated"]["sim"]["modulators"]
    median = reference_time_constant(mods, NOMINAL)
    taus = {"median of the sim settings": median, "IIPFM 20 ms": 1.077, "IPFM 10 ms": 2.36}
    print("[B] sine: linear first-order plant (gain k2), RMS deviation")
    print("    " + " | ".join(f"{k} {v:.3f} s" for k, v in taus.items()))
    for f in (0.02, 0.05, 0.2, 0.5):
        cfg = {**config["experiments"]["sine"], "frequency": f}
        spec = modulated_runs([mods[0]], 0.01, {"sine": cfg})[0]
        t = np.arange(spec.xi.size) * 0.01
        run = pd.DataFrame({"t": t, "u": spec.xi})
        cells = []
        for tau in taus.values():
            reference = reference_run(run, NOMINAL, tau)
            cells.append(sine_analysis(reference, settle=float(cfg["settle"]))[1]["rms"])
        print(f"    {f:5.2f} Hz: " + " | ".join(f"{c:.4f}" for c in cells))


def linear_chirp(config: dict) -> None:
    """[C] The linear reference under the chirp: bounded against HOSA's normalisation."""
    cfg = config["experiments"]["chirp"]
    options = {k: v for k, v in config["linearity"]["chirp"].items() if k != "seeds"}
    t = np.arange(round(cfg["duration"] * 1000)) * 1e-3
    xi = chirp_input(t, cfg["f0"], cfg["f1"], cfg["duration"], cfg["offset"], cfg["amplitude"])
    run = pd.DataFrame({"t": t, "p": 0.0, "u": xi})
    mods = config["simulated"]["sim"]["modulators"]
    print("[C] chirp: linear first-order plant, nominal valve, sampled at 1 kHz, noise-free")
    for norm in ("bounded", "hosa"):
        f, bic, row = chirp_reference(run, NOMINAL, mods, **{**options, "normalisation": norm})
        domain = bic[principal_domain_mask(f)]
        summarised = bic[principal_domain_mask(f, row["fmin"])]
        print(
            f"    {norm:8s}: largest {domain.max():.3g} over the principal domain, "
            f"{summarised.max():.3g} without the rows next to DC; significant fraction "
            f"{row['significant_fraction']:.4f} (threshold {row['threshold']:.4f})"
        )


def settling(config: dict) -> None:
    """[D] Measured against averaged-model equilibria: 5 s levels against 60 s levels."""
    print("[D] staircase, noise-free, nominal valve: 5 s levels | 60 s levels")
    settings = [m.to_mapping() for m in PAPER_SETTINGS] + [
        {"type": "ipfm", "t_h": 0.005},
        {"type": "iipfm", "t_l": 0.010},
        {"type": "dsm", "period": 0.005},
    ]
    step = float(config["experiments"]["staircase"]["step"])
    for mod in settings:
        cells = []
        for hold in (5.0, 60.0):
            dt = 1e-3
            t = np.arange(round(11 * hold / dt)) * dt
            spec = RunSpec("s", "staircase", xi=staircase_input(t, step, hold), modulator=mod)
            quiet = Sensor(fs=1 / dt, noise=0.0, quantum=0.0)
            run = simulate_run(spec, NOMINAL, dt, quiet, np.random.default_rng(0))
            _, _, s = staircase_analysis(run, mod, NOMINAL)
            cells.append(
                f"eq_rmse_model {s['eq_rmse_model']:.4f} drift_max {s['drift_max']:.4f} "
                f"FIT {s['fit']:.2f} sat_agrees {s['saturation_agrees']}"
            )
        print(f"    {mod}:\n      {cells[0]}\n      {cells[1]}")


def iipfm_time_constant() -> None:
    """[E] The averaged model's largest IIPFM tau_m (Eq. 9) against the paper's bench mean."""
    xi = np.linspace(0.0, 1.0, 1001)
    print("[E] Eq. 9, IIPFM t_l = 20 ms, nominal valve, xi in [0, 1] by 0.001")
    for gain in (1.0, 1.15):
        tau = time_constant(*time_fractions("iipfm", xi, NOMINAL, t_l=0.02, gain=gain), NOMINAL)
        k = int(np.nanargmax(tau))
        print(f"    G = {gain}: largest tau_m {tau[k]:.3f} s at xi = {xi[k]:.2f}")
    mean, sd = PAPER_TIME_CONSTANTS["iipfm"]
    print(f"    paper, bench: {mean} ± {sd} s")


def main() -> None:
    results = Path(sys.argv[1]) if len(sys.argv) > 1 else ROOT / "results"
    with open(ROOT / "config" / "config.yaml", encoding="utf-8") as fh:
        config = yaml.safe_load(fh)
    sine_bands(results)
    linear_sine(config)
    linear_chirp(config)
    settling(config)
    iipfm_time_constant()


if __name__ == "__main__":
    main()
