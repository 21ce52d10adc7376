"""The numbers behind the README's "Model-inverse PWM (LPWM)" section.

Run from the repository root, after the full config (``snakemake reproduce-all``):

    .venv/bin/python docs/lpwm_check.py [results]

For the nominal valve and each dataset's identified valve (``results/<dataset>/identification/
params.yaml``): LPWM's averaged ``J`` and ``J_exact`` at its grid optimum, at 20 Hz and at the
``J_exact`` optimum, its largest chattering over ``xi`` beside IIPFM's at IIPFM's optimum, and
its sensitivity to identification error (:func:`spa.tuning.sensitivity.valve_sensitivity`:
the inverse at each corner of the 95 % box while the plant keeps the estimate). Nothing is
fitted or hard-coded; the grids and ``n_xi`` are the config's.
"""

from __future__ import annotations

import sys
from pathlib import Path

import pandas as pd
import yaml

from spa.identification.identified import read_identified
from spa.model.params import ValveParams
from spa.tuning.cost import linearity_cost
from spa.tuning.recommend import setting_metrics
from spa.tuning.sensitivity import valve_sensitivity
from spa.tuning.tables import tuning_table

INVERSE, REFERENCE = "lpwm", "iipfm"  # the kind checked and the paper's best


def main(results: Path) -> None:
    config = yaml.safe_load(Path("config/config.yaml").read_text())
    sweeps, n_xi = config["analytic"]["sweeps"], config["analytic"]["n_xi"]
    valves = {"nominal": (ValveParams(**config["nominal"]), {})}
    for params in sorted(results.glob("*/identification/params.yaml")):
        ident = read_identified(params)
        valves[params.parts[-3]] = (ident.params, ident.intervals)
    rows, corners = [], []
    for name, (p, intervals) in valves.items():
        grids = {k: sweeps[k] for k in ("pwm", "ipfm", "iipfm", "dsm", INVERSE)}
        table = tuning_table(grids, p, n_xi).set_index("modulator")
        inv, ref = table.loc[INVERSE], table.loc[REFERENCE]
        f_opt, f_exact = inv["optimum"], inv["optimum_exact"]

        def chat(kind: str, value: float, gain: float | None = None, p: ValveParams = p) -> float:
            return float(setting_metrics(kind, value, p, n_xi, gain)["chattering"])

        rows.append(
            {
                "valve": name,
                "lpwm_optimum_Hz": f_opt,
                "lpwm_J": inv["J_min"],
                "lpwm_J_exact": inv["J_exact"],
                "lpwm_chattering": chat(INVERSE, f_opt),
                "lpwm_J_exact_20Hz": float(linearity_cost(INVERSE, 20.0, p, n_xi, exact=True)),
                "lpwm_J_20Hz": float(linearity_cost(INVERSE, 20.0, p, n_xi)),
                "lpwm_chattering_20Hz": chat(INVERSE, 20.0),
                "lpwm_optimum_exact_Hz": f_exact,
                "lpwm_J_exact_min": inv["J_exact_min"],
                "lpwm_chattering_at_exact_optimum": chat(INVERSE, f_exact),
                "iipfm_optimum_ms": ref["optimum"],
                "iipfm_J": ref["J_min"],
                "iipfm_J_exact": ref["J_exact"],
                "iipfm_chattering": chat(REFERENCE, ref["optimum"] * 1e-3, ref["gain"]),
            }
        )
        if intervals:
            for f_w in dict.fromkeys((20.0, f_exact, f_opt)):  # 20 Hz, recommended, J optimum
                t = valve_sensitivity({"type": INVERSE, "f_w": f_w}, p, intervals, n_xi)
                corners.append(
                    {
                        "valve": name,
                        "f_w": f_w,
                        "J_exact_estimate": t["J_exact"].iloc[0],
                        "J_exact_corners_min": t["J_exact"].iloc[1:].min(),
                        "J_exact_corners_max": t["J_exact"].iloc[1:].max(),
                        "J_corners_max": t["J"].iloc[1:].max(),
                        "worst_corner": t["case"].iloc[1:][t["J_exact"].iloc[1:].idxmax()],
                    }
                )
    with pd.option_context("display.width", 200, "display.max_columns", 30):
        print(pd.DataFrame(rows).set_index("valve").T.to_string(float_format="%.4g"))
        print()
        print(pd.DataFrame(corners).to_string(index=False, float_format="%.4g"))


if __name__ == "__main__":
    main(Path(sys.argv[1] if len(sys.argv) > 1 else "results"))
