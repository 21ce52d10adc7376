"""The tuning rule in the small-config run: every dataset's outputs, checked by hand."""

from __future__ import annotations

import math

import pandas as pd
import pytest
import yaml

from spa.identification import load_params
from spa.model.modulators import Modulator

TABLE2_COLUMNS = (
    "modulator parameter optimum unit gain J_min analytic_optimum J_paper_setting J_exact "
    "optimum_lo optimum_hi J_min_lo J_min_hi J_exact_lo J_exact_hi interval_method"
).split()
SMALL = {  # config/small.yaml
    "pwm": (1.0, 80.0, 1.0),
    "ipfm": (0.0125, 1.0, 0.0025),
    "iipfm": (0.0125, 1.0, 0.0025),
    "dsm": (0.0125, 1.0, 0.0025),
}


@pytest.mark.parametrize("dataset", ["sim", "example"])
def test_every_dataset_is_tuned(small_run, dataset):
    d = small_run / dataset / "tuning"
    for name in ["table1.csv", "table2.csv", "fig4.png", "fig4.csv", "fig5.png", "fig5.csv",
                 "recommendation.yaml"]:  # fmt: skip
        assert (d / name).stat().st_size > 0, name
    table2 = pd.read_csv(d / "table2.csv")
    assert table2.columns[: len(TABLE2_COLUMNS)].tolist() == TABLE2_COLUMNS
    assert (table2["interval_method"] == "corners").all()
    rec = yaml.safe_load((d / "recommendation.yaml").read_text())
    best = Modulator.from_mapping(rec["recommended"]["setting"])
    assert best.label == rec["recommended"]["label"]
    assert rec["sentence"].startswith(f"Use {best.description}")
    assert {"J_exact"} <= set(pd.read_csv(d / "fig4.csv").columns)


def test_example_valve_table2_agrees_with_eq25_by_hand(small_run):
    """Issue 14: the bench dataset's (raw/example) optima are the minima of Eq. 25 by hand."""
    from test_tuning import eq25_by_hand

    params = load_params(
        yaml.safe_load((small_run / "example/identification/params.yaml").read_text())
    )
    table2 = pd.read_csv(small_run / "example" / "tuning" / "table2.csv").set_index("modulator")
    for kind, (start, stop, step) in SMALL.items():
        count = int((stop - start) / step + 1e-9) + 1
        values = [round(start + k * step, 12) for k in range(count)]
        floor = params.t_on if kind == "ipfm" else params.t_off if kind != "pwm" else 0.0
        costs = {v: eq25_by_hand(kind, v, params, n=50) for v in values if v > floor}
        best = min(costs, key=costs.get)
        scale = 1.0 if kind == "pwm" else 1e3
        assert table2.loc[kind, "optimum"] == pytest.approx(best * scale, abs=1e-9), kind
        assert table2.loc[kind, "J_min"] == pytest.approx(costs[best], rel=1e-9), kind
        assert not math.isnan(table2.loc[kind, "J_exact"])
    rec = yaml.safe_load((small_run / "example" / "tuning" / "recommendation.yaml").read_text())
    assert rec["recommended"]["modulator"] == table2["J_min"].idxmin()
