"""The tuning stage for one valve: constraints, recommendation, reading params.yaml, CLI."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest
import yaml
from matplotlib.figure import Figure

from spa import ValveParams
from spa.cli import main
from spa.identification.identified import read_identified
from spa.model.modulators import Modulator
from spa.plots.tuning import plot_tuning_equilibrium, plot_tuning_sweeps
from spa.tuning import (
    CONSTRAINTS,
    DEFAULT_SWEEPS,
    TuningError,
    TuningOptions,
    candidate_frame,
    recommendation_sentence,
    setting_metrics,
    tune,
    tune_with_config,
)

P = ValveParams()
# Grids 5x coarser than the paper's, enough for the logic and 5x faster.
# The paper's four kinds (the tests below check the paper's ranking); LPWM has its own test.
SMALL = {k: {**g, "step": g["step"] * 5} for k, g in DEFAULT_SWEEPS.items() if k != "lpwm"}


@pytest.fixture(scope="module")
def nominal():
    return tune(P, sweeps=SMALL, n_xi=50)


def identified_yaml(tmp_path, **changes):
    """A params.yaml like the identification writes, for the nominal valve."""
    content = {
        name: {"value": v, "lo": v * 0.98, "hi": v * 1.02, "unit": "s", "fallback": None}
        for name, v in P.as_dict().items()
    }
    content["fallback"] = {}
    content.update(changes)
    path = tmp_path / "params.yaml"
    path.write_text(yaml.safe_dump(content))
    return path


# ---- metrics and constraints ------------------------------------------------------------


def test_setting_metrics_of_pwm_and_dsm():
    m = setting_metrics("pwm", np.array([10.0, 20.0]), P, 100)
    np.testing.assert_allclose(m["switching_rate"], [20.0, 40.0])  # 2 edges a period
    assert np.all(m["min_pulse"] > P.t_on)  # the shortest pulse that moves the pressure
    d = setting_metrics("dsm", 0.02, P, 100)
    assert float(d["min_pulse"]) == 0.02
    assert float(d["switching_rate"]) == pytest.approx(1 / 0.02, rel=1e-3)  # 4 xi(1-xi)/T
    assert float(d["chattering"]) > 0


def test_candidates_cover_the_feasible_grid_and_the_gain_sweep():
    options = TuningOptions(gain_sweep={"start": 1.0, "stop": 1.3, "step": 0.05})
    c = candidate_frame(SMALL, P, 50, options)
    iipfm = c[c["modulator"] == "iipfm"]
    n_t = int((c["modulator"] == "dsm").sum())  # same grid, same constraint t > t_off
    assert len(iipfm) == n_t * (1 + 7)
    assert (c.loc[c["modulator"] == "ipfm", "value"] > P.t_on).all()
    assert set(CONSTRAINTS) <= set(c.columns)
    assert (c["feasible"] == c[list(CONSTRAINTS)].all(axis=1)).all()


def test_the_gain_sweep_can_only_lower_the_recommended_cost(nominal):
    swept = tune(
        P,
        sweeps=SMALL,
        n_xi=50,
        options={"gain_sweep": {"start": 1.0, "stop": 1.3, "step": 0.01}},
    )
    assert swept.recommendation["recommended"]["J"] <= nominal.recommendation["recommended"]["J"]


def test_score_j_exact_minimises_j_exact():
    result = tune(P, sweeps=SMALL, n_xi=50, options={"score": "J_exact"})
    feasible = result.candidates[result.candidates["feasible"]]
    best = result.recommendation["recommended"]
    assert best["J_exact"] == feasible["J_exact"].min()
    assert result.recommendation["score"] == "J_exact"


def test_ranges_restrict_the_choice():
    result = tune(P, sweeps=SMALL, n_xi=50, options={"ranges": {"iipfm": [0.025, 0.04]}})
    entries = [result.recommendation["recommended"], *result.recommendation["runners_up"]]
    iipfm = next(e for e in entries if e["modulator"] == "iipfm")
    assert 0.025 <= iipfm["setting"]["t_l"] <= 0.04
    # long separations chatter more than the default 50 mbar allows
    rec = tune(P, sweeps=SMALL, n_xi=50, options={"ranges": {"iipfm": [0.2, 0.5]}}).recommendation
    iipfm = next(e for e in rec["runners_up"] if e["modulator"] == "iipfm")
    assert iipfm["excluded_by"] == ["setting_range", "max_chattering"]


# ---- the recommendation -----------------------------------------------------------------


def test_nominal_recommendation(nominal):
    rec = nominal.recommendation
    best = rec["recommended"]
    assert best["modulator"] == "iipfm"
    mod = Modulator.from_mapping(best["setting"])  # copy-paste ready for a dataset.yaml
    assert mod.label == best["label"] and mod.gain == pytest.approx(1 + P.t_on / mod.value)
    pred = best["predicted"]
    assert pred["dead_zone"] == 0.0 and pred["saturation"] == 1.0
    assert 0 < pred["tau_m"]["min"] < pred["tau_m"]["max"] < 2 * P.tau2
    assert pred["switching_rate"] <= rec["constraints"]["max_switching_rate"]
    assert pred["chattering"] <= rec["constraints"]["max_chattering_bar"]
    # the simulated staircase ranks like the paper's Table 3: IIPFM fits best
    fits = {r["modulator"]: r["predicted"]["fit"] for r in rec["runners_up"]}
    assert pred["fit"] > max(fits.values()) and pred["fit"] > 85.0
    assert rec["excluded_by"] == [] and rec["n_feasible"] > 0
    assert nominal.sentence.startswith("Use IIPFM, t_l = ")
    assert "dataset.yaml modulator: {type: iipfm" in nominal.sentence


def test_a_constraint_that_excludes_everything_is_named():
    """Nothing meets the limit: the least-violating usable setting is recommended, and the
    sentence names the constraint it breaks."""
    result = tune(P, sweeps=SMALL, n_xi=50, options={"max_switching_rate": 1.0})
    rec = result.recommendation
    assert rec["n_feasible"] == 0 and rec["recommended"] is not None
    broken = rec["recommended"]["violates"]
    assert "max_switching_rate" in broken and broken["max_switching_rate"]["limit"] == 1.0
    assert rec["excluded_by"] == ["max_switching_rate"]
    assert all(r["excluded_by"] == ["max_switching_rate"] for r in rec["runners_up"])
    assert result.sentence.startswith("No setting meets every constraint; the least-violating")
    assert all(f"{name} (" in result.sentence for name in broken)


def test_constraints_that_exclude_everything_together_are_named():
    """Slow switching forces long periods, little chattering forbids them: neither alone."""
    options = {"max_switching_rate": 10.0, "max_chattering": 0.01}
    rec = tune(P, sweeps=SMALL, n_xi=50, options=options).recommendation
    assert rec["recommended"] is not None and rec["n_feasible"] == 0
    assert rec["excluded_by"] == ["max_switching_rate", "max_chattering"]
    assert "the least-violating one breaks" in recommendation_sentence(rec)
    excludes = rec["constraints"]["excludes"]
    assert 0 < excludes["max_switching_rate"] < rec["n_candidates"]


def test_tables_and_figures_of_the_stage(nominal):
    t1 = nominal.table1
    assert t1["case"].tolist() == ["paper"] * 4 + ["optimum"] * 4 + ["recommended"]
    assert t1.loc[t1["label"] == "pwm-20Hz", "dead_zone"].item() == pytest.approx(0.06)
    assert {"J", "J_exact"} <= set(nominal.sweeps.columns)
    assert np.isnan(nominal.sweeps["J_exact"]).sum() == np.isnan(nominal.sweeps["J"]).sum()
    assert "p_exact" in nominal.curves.columns
    fig = plot_tuning_sweeps(nominal.sweeps, title="nominal")
    assert isinstance(fig, Figure) and len(fig.legends[0].get_texts()) == 5
    assert len(plot_tuning_equilibrium(nominal.curves).axes) == 8


# ---- reading an identification ----------------------------------------------------------


def test_read_identified_takes_values_and_intervals(tmp_path):
    ident = read_identified(identified_yaml(tmp_path))
    assert ident.params == P
    assert ident.intervals["c1"] == pytest.approx((0.533 * 0.98, 0.533 * 1.02))
    result = tune(ident, sweeps=SMALL, n_xi=50)
    t2 = result.table2
    assert (t2["interval_method"] == "corners").all()
    assert (t2["J_min_lo"] < t2["J_min"]).all() and (t2["J_min"] < t2["J_min_hi"]).all()
    assert result.recommendation["intervals"]["k2"] == pytest.approx([0.837 * 0.98, 0.837 * 1.02])


def test_a_fallback_parameter_has_no_interval_and_is_recorded(tmp_path):
    t_off = {"value": 0.01, "lo": None, "hi": None, "fallback": "no pulse run"}
    path = identified_yaml(tmp_path, t_off=t_off, fallback={"t_off": "no pulse run"})
    ident = read_identified(path)
    assert "t_off" not in ident.intervals and ident.fallback == {"t_off": "no pulse run"}


@pytest.mark.parametrize(
    ("change", "match"),
    [
        ({"k2": {"value": None}}, "no value for 'k2'"),
        ({"tau2": {"value": -0.8}}, "ValveParams.tau2 must be"),
        ({"c1": {"value": 0.0}}, "ValveParams.c1 must be"),
        ({"error": "no charge run"}, "the identification failed: no charge run"),
    ],
)
def test_a_failed_identification_gets_no_tuning(tmp_path, change, match):
    with pytest.raises(TuningError, match=match):
        tune(identified_yaml(tmp_path, **change))


def test_a_missing_params_file_says_the_identification_did_not_run(tmp_path):
    with pytest.raises(TuningError, match="did not run or failed"):
        tune(tmp_path / "nowhere" / "params.yaml")


@pytest.mark.parametrize(
    ("options", "match"),
    [
        ({"score": "fit"}, "tuning.score"),
        ({"max_chattering": -1.0}, "tuning.max_chattering"),
        ({"max_switching_rate": True}, "tuning.max_switching_rate"),
        ({"ranges": {"pwm": [50.0, 5.0]}}, "tuning.ranges.pwm"),
        ({"ranges": {"pfm": [5.0, 50.0]}}, "unknown modulator"),
        ({"colour": "red"}, "unknown key"),
    ],
)
def test_bad_options_are_named(options, match):
    with pytest.raises(ValueError, match=match):
        TuningOptions.from_mapping(options)


def test_config_sections_reach_the_stage():
    config = {
        "analytic": {"sweeps": SMALL, "n_xi": 40},
        "tuning": {"max_chattering": 0.02},
        "linearity": {"staircase": {"settle": 0.3}},
    }
    result = tune_with_config(P, config, score="J_exact")
    assert result.recommendation["n_xi"] == 40
    assert result.recommendation["constraints"]["max_chattering"] == 0.02
    assert result.recommendation["score"] == "J_exact"


# ---- command line -----------------------------------------------------------------------


def test_cli_tunes_a_params_file(tmp_path, capsys):
    config = tmp_path / "config.yaml"
    config.write_text(yaml.safe_dump({"analytic": {"sweeps": SMALL, "n_xi": 50}}))
    assert main(["tune", str(identified_yaml(tmp_path)), "--config", str(config)]) == 0
    out = capsys.readouterr().out
    assert "Table 2 for" in out and "(intervals: corners)" in out
    assert "Use IIPFM" in out and "J 95 %" in out  # intervals shown in the brief table
    assert "recommended:" not in out  # the full recommendation only with --yaml / --json


def test_cli_tunes_given_parameters_as_json(tmp_path, capsys):
    config = tmp_path / "config.yaml"
    config.write_text(yaml.safe_dump({"analytic": {"sweeps": SMALL, "n_xi": 50}}))
    args = ["tune", "--c1", "0.45", "--k2", "1.05", "--tau2", "0.70", "--t-on", "0.004"]
    assert main([*args, "--t-off", "0.009", "--json", "--config", str(config)]) == 0
    data = json.loads(capsys.readouterr().out)
    assert [r["modulator"] for r in data["table2"]] == ["pwm", "ipfm", "iipfm", "dsm"]
    assert data["recommendation"]["recommended"]["setting"]["type"] == "iipfm"
    assert pd.isna(data["table2"][0]["gain"])  # NaN is written as null


VALVE = ["--c1", "0.5", "--k2", "1", "--tau2", "1", "--t-on", "0.003", "--t-off", "0.01"]


@pytest.mark.parametrize(
    ("args", "status", "message"),
    [
        (["--c1", "0.5"], 2, "missing --k2 --tau2 --t-on --t-off"),
        (["params.yaml", "--c1", "0.5"], 2, "not both"),
        (["--c1", "-0.5", *VALVE[2:]], 1, "ValveParams.c1 must be"),
        ([*VALVE[:-1], "2"], 1, "t_off = 2 s is not shorter"),
        (["missing/params.yaml"], 1, "did not run or failed"),
    ],
)
def test_cli_refuses_bad_input(args, status, message, capsys):
    assert main(["tune", *args]) == status
    assert message in capsys.readouterr().out
