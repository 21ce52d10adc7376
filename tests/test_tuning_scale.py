"""Tuning defaults in the valve's own scale, and the least-violating recommendation."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest

from spa.model.params import ValveParams
from spa.tuning import tune
from spa.tuning.cost import DEFAULT_SWEEPS
from spa.tuning.recommend import DEFAULT_CHATTERING_RELATIVE, TuningOptions, violation

SMALL = {k: {**g, "step": g["step"] * 5} for k, g in DEFAULT_SWEEPS.items() if k != "lpwm"}
FOUR_BAR = ValveParams(c1=0.9, k2=4.0, tau2=0.5, t_on=0.008, t_off=0.02)
FIVE_AND_A_HALF = ValveParams(c1=0.6, k2=5.5, tau2=0.3, t_on=0.005, t_off=0.012)


def test_the_default_chattering_limit_is_the_papers_on_the_papers_valve():
    """Chosen so that the paper's valve keeps (about) the former absolute 0.05 bar."""
    limit = TuningOptions().chattering_limit(ValveParams())
    assert limit == pytest.approx(0.05, rel=0.01)
    assert TuningOptions().chattering_limit(FOUR_BAR) == pytest.approx(
        DEFAULT_CHATTERING_RELATIVE * 4.0
    )
    assert TuningOptions(max_chattering=0.03).chattering_limit(FOUR_BAR) == 0.03
    assert TuningOptions(max_chattering_relative=None).chattering_limit(FOUR_BAR) is None


def test_a_4_bar_valve_gets_a_recommendation_by_default():
    """Issue case 1: with chattering limited to 0.05 bar absolute, a 4 bar valve got
    ``recommended: null`` by default ("No setting of any modulator meets the constraints")
    although every modulator has usable settings."""
    rec = tune(FOUR_BAR, sweeps=SMALL, n_xi=50).recommendation
    best = rec["recommended"]
    assert best is not None and not best.get("violates")
    assert rec["n_feasible"] > 0 and rec["excluded_by"] == []
    assert best["predicted"]["chattering"] <= DEFAULT_CHATTERING_RELATIVE * FOUR_BAR.k2
    assert rec["constraints"]["max_chattering_bar"] == pytest.approx(0.24)
    assert rec["sentence"].startswith("Use ")


def test_a_5_5_bar_valve_gets_the_least_violating_setting_with_the_constraint_named():
    """Issue case 1: the 5.5 bar valve got ``recommended: null``; no setting meets every
    constraint here (the response-speed limit), so the least-violating usable one is
    recommended and the sentence names the constraint it breaks, with its numbers."""
    result = tune(FIVE_AND_A_HALF, sweeps=SMALL, n_xi=50)
    rec = result.recommendation
    assert rec["n_feasible"] == 0 and rec["n_candidates"] > 0
    best = rec["recommended"]
    assert best is not None and set(best["violates"]) == {"max_time_constant"}
    broken = best["violates"]["max_time_constant"]
    assert broken["limit"] == pytest.approx(3.0 * FIVE_AND_A_HALF.tau2)
    assert broken["excess"] == pytest.approx(broken["value"] / broken["limit"] - 1.0)
    assert best["violation"] == pytest.approx(broken["excess"])
    assert "the least-violating one breaks max_time_constant (" in result.sentence
    assert "nan" not in result.sentence and "inf" not in result.sentence
    # it is the smallest violation of any candidate
    assert best["violation"] <= float(result.candidates["violation"].min()) * (1 + 1e-9)


def test_violation_is_the_sum_of_relative_excesses():
    frame = pd.DataFrame(
        {
            "modulator": ["pwm", "pwm", "dsm"],
            "value": [20.0, 60.0, 0.5],
            "switching_rate": [40.0, 150.0, 4.0],
            "chattering": [0.06, 0.02, 0.5],
            "min_pulse": [0.01, 0.0005, 0.5],
            "tau_max": [1.0, 1.0, math.nan],
        }
    )
    opts = TuningOptions(max_chattering=0.05, ranges={"dsm": [0.01, 0.1]})
    got = violation(frame, opts, ValveParams())
    # 0.06 vs 0.05: 20 %; 150 vs 100 edges/s: 50 % and 0.5 ms vs 1 ms: 50 %; the third has
    # no finite time constant: without bound
    np.testing.assert_allclose(got[:2], [0.2, 1.0])
    assert got[2] == np.inf
    assert violation(frame.iloc[:1], TuningOptions(max_chattering=0.1), ValveParams())[0] == 0.0


def test_nothing_usable_is_the_only_null():
    """``recommended: null`` only when no swept setting works on the valve at all."""
    from spa.tuning.recommend import TuningSetup, recommend
    from spa.tuning.sentence import recommendation_sentence

    coarse = {k: {**g, "step": g["step"] * 50} for k, g in SMALL.items()}
    candidates = tune(FOUR_BAR, sweeps=coarse, n_xi=20).candidates
    rec = recommend(candidates.iloc[:0], TuningSetup(FOUR_BAR, 20))
    assert rec["recommended"] is None and rec["excluded_by"] == []
    assert recommendation_sentence(rec).startswith(
        "No setting of any swept modulator works on this valve"
    )
    tight = recommend(
        candidates, TuningSetup(FOUR_BAR, 20, TuningOptions(max_switching_rate=0.001))
    )
    assert tight["n_feasible"] == 0
    assert tight["recommended"] is not None and tight["recommended"]["violates"]
