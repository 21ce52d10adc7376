"""Linearity tuning (Section 5) against closed forms, invariants and the paper's Table 2."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from matplotlib.figure import Figure

from spa import ValveParams
from spa.identification.identified import corners, read_intervals
from spa.model.averaging import equilibrium
from spa.plots.analytic import plot_cost_sweeps, plot_equilibrium
from spa.tuning import (
    PAPER_SETTING,
    PAPER_TABLE2,
    check_sweeps,
    equilibrium_frame,
    feasible,
    iipfm_optimal_t_l,
    linearity_cost,
    modulator_settings,
    optimum,
    optimum_table,
    propagate,
    sweep,
    sweep_frame,
    sweep_grid,
    tune,
    tuning_table,
)
from spa.tuning.recommend import TuningOptions, setting_metrics

P = ValveParams()

# The paper's grids (Section 5.1), as in config/config.yaml.
SWEEPS = {
    "pwm": {"start": 1.0, "stop": 80.0, "step": 0.1},
    "ipfm": {"start": 0.0125, "stop": 1.0, "step": 0.001},
    "iipfm": {"start": 0.0125, "stop": 1.0, "step": 0.001},
    "dsm": {"start": 0.0125, "stop": 1.0, "step": 0.001},
}


@pytest.fixture(scope="module")
def table2() -> pd.DataFrame:
    return optimum_table(SWEEPS, P, n_xi=100).set_index("modulator")


# ---- settings and constraints ----------------------------------------------------------


def test_modulator_settings():
    assert modulator_settings("iipfm", 0.02, P) == {"t_l": 0.02, "gain": pytest.approx(1.15)}
    assert modulator_settings("ipfm", 0.02, P) == {"t_h": 0.02, "gain": 1.0}
    assert modulator_settings("pwm", 20.0, P) == {"f_w": 20.0}
    assert modulator_settings("dsm", 0.02, P) == {"period": 0.02}
    s = modulator_settings("iipfm", np.array([0.01, 0.02]), P)
    np.testing.assert_allclose(s["gain"], 1 + P.t_on / np.array([0.01, 0.02]))


def test_constraints_of_section_5():
    values = np.array([0.002, 0.003, 0.004, 0.010, 0.011])
    assert feasible("pwm", values, P).all()
    assert feasible("ipfm", values, P).tolist() == [False, False, True, True, True]
    assert feasible("iipfm", values, P).tolist() == [False, False, False, False, True]
    assert feasible("dsm", values, P).tolist() == [False, False, False, False, True]


def test_sweep_marks_infeasible_points_nan():
    values, cost = sweep("iipfm", P, 0.005, 0.015, 0.001, n_xi=20)
    assert np.all(np.isnan(cost[values <= P.t_off]))
    assert np.all(np.isfinite(cost[values > P.t_off]))


def test_sweep_grid_is_inclusive_and_clean():
    g = sweep_grid(0.0125, 1.0, 0.001)
    assert g.size == 988  # 12.5, 13.5, ..., 999.5 ms: 1.0 is not on this grid
    assert g[7] == 0.0195
    f = sweep_grid(1.0, 80.0, 0.1)
    assert f.size == 791
    assert f[-1] == 80.0
    assert f[190] == 20.0


# ---- the cost (Eq. 25) -----------------------------------------------------------------


def test_cost_is_sum_of_absolute_deviations_from_k2_xi():
    xi = np.linspace(0, 1, 100)
    p_eq = equilibrium("dsm", xi, P, period=0.02)
    expected = np.abs(p_eq - P.k2 * xi).sum()
    assert linearity_cost("dsm", 0.02, P, n_xi=100) == pytest.approx(expected, rel=1e-14)


@pytest.mark.parametrize("n_xi", [2, 11, 100])
def test_cost_of_a_valve_that_never_charges_is_k2_n_over_2(n_xi):
    """IPFM pulses shorter than t_on never charge: P_eq = 0, J = sum k2*xi_i = k2*N/2."""
    assert linearity_cost("ipfm", 0.002, P, n_xi=n_xi) == pytest.approx(P.k2 * n_xi / 2)


def test_cost_of_the_ideal_valve_is_the_same_for_all_modulators():
    fast = ValveParams(t_on=1e-12, t_off=1e-12)
    costs = [linearity_cost(k, v, fast) for k, v in [("pwm", 20.0), ("ipfm", 0.02), ("dsm", 0.02)]]
    assert costs == pytest.approx([costs[0]] * 3, rel=1e-8)
    assert costs[0] > 10  # Eq. 5 itself is far from linear: J ~ 14.6 at N = 100


@given(
    kind=st.sampled_from(["pwm", "ipfm", "iipfm", "dsm"]),
    values=st.lists(st.floats(0.011, 0.5), min_size=1, max_size=8),
)
@settings(max_examples=50, deadline=None)
def test_vectorised_cost_equals_pointwise_cost(kind, values):
    v = np.array(values) * (100.0 if kind == "pwm" else 1.0)  # PWM: 1.1-50 Hz
    together = linearity_cost(kind, v, P, n_xi=37)
    one_by_one = [linearity_cost(kind, float(x), P, n_xi=37) for x in v]
    np.testing.assert_allclose(together, one_by_one, rtol=1e-13)
    assert np.all(together >= 0)


# ---- Table 2 and Eq. 29 -----------------------------------------------------------------


def test_eq29_gives_19_ms():
    assert iipfm_optimal_t_l(P) == pytest.approx(0.019, abs=0.5e-3)


@given(
    c1=st.floats(0.2, 1.0),
    k2=st.floats(0.3, 2.0),
    tau2=st.floats(0.8, 3.0),
    t_on=st.floats(1e-4, 0.01),
    t_off=st.floats(1e-4, 0.02),
)
@settings(max_examples=100, deadline=None)
def test_eq29_matches_the_ideal_fraction_ratio(c1, k2, tau2, t_on, t_off):
    """(t_l - t_off)²/(t_l + t_on)² = c1² k2/(2 tau2²) at t_l* (Section 5.2)."""
    params = ValveParams(c1=c1, k2=k2, tau2=tau2, t_on=t_on, t_off=t_off)
    r2 = c1**2 * k2 / (2 * tau2**2)
    if r2 >= 1:
        with pytest.raises(ValueError, match="c1"):
            iipfm_optimal_t_l(params)
        return
    t = iipfm_optimal_t_l(params)
    assert t > t_off
    assert (t - t_off) ** 2 / (t + t_on) ** 2 == pytest.approx(r2, rel=1e-10)


def test_eq29_is_close_to_the_numerical_iipfm_optimum(table2):
    """The paper: 19 ms analytic vs 20 ms optimised. Here 19.3 ms vs 19.5 ms."""
    assert table2.loc["iipfm", "optimum"] == pytest.approx(iipfm_optimal_t_l(P) * 1e3, abs=1.0)


def test_table2_ranking_matches_the_paper(table2):
    """IIPFM < ΔΣM < PWM < IPFM in J_min, as in Table 2 (4.8 < 9.6 < 10.5 < 12.5)."""
    j = table2["J_min"]
    assert j["iipfm"] < j["dsm"] < j["pwm"] < j["ipfm"]
    paper = {k: v[0] for k, v in PAPER_TABLE2.items()}
    assert sorted(paper, key=paper.get) == sorted(j.index, key=j.get)
    # "almost 2.5 times smaller" than PWM (paper: 10.5/4.8 = 2.2; here 10.9/3.6 = 3.0)
    assert 2.0 < j["pwm"] / j["iipfm"] < 3.5


def test_table2_optimum_locations_near_the_paper(table2):
    """PWM 18.6 Hz (paper 20 Hz), IIPFM 19.5 ms (20 ms), ΔΣM 24.5 ms (20 ms)."""
    assert table2.loc["pwm", "optimum"] == pytest.approx(20.0, abs=2.0)  # Hz
    assert table2.loc["iipfm", "optimum"] == pytest.approx(20.0, abs=1.0)  # ms
    assert table2.loc["dsm", "optimum"] == pytest.approx(20.0, abs=5.0)  # ms
    # J_min within 5 % of the printed value for PWM and ΔΣM (10.9 vs 10.5, 9.2 vs 9.6)
    for kind in ("pwm", "dsm"):
        assert table2.loc[kind, "J_min"] == pytest.approx(PAPER_TABLE2[kind][0], rel=0.05)


def test_ipfm_optimum_is_shallow_and_not_at_the_papers_20_ms(table2):
    """Known disagreement: the IPFM cost is flat with its minimum near 45 ms, not 20 ms.

    J(20 ms) is within 10 % of J_min, so the paper's choice is near-optimal, but the grid
    minimum of Eq. 25 with the table's fractions is not at 20 ms.
    """
    t_h, j_min = table2.loc["ipfm", "optimum"], table2.loc["ipfm", "J_min"]
    assert 35.0 < t_h < 55.0
    assert j_min < linearity_cost("ipfm", 0.020, P) < 1.10 * j_min


def test_iipfm_optimum_beats_unit_gain():
    """The Eq. 17 gain (no dead-zone) is what makes IIPFM the most linear."""
    xi = np.linspace(0, 1, 100)
    unit = np.abs(equilibrium("iipfm", xi, P, t_l=0.0195, gain=1.0) - P.k2 * xi).sum()
    assert linearity_cost("iipfm", 0.0195, P) < 0.6 * unit


def test_optimum_is_the_argmin_of_the_sweep():
    values, cost = sweep("dsm", P, 0.0125, 0.1, 0.0005, n_xi=50)
    value, j_min = optimum("dsm", P, 0.0125, 0.1, 0.0005, n_xi=50)
    assert j_min == np.nanmin(cost)
    assert value == values[np.nanargmin(cost)]
    assert np.all(cost[np.isfinite(cost)] >= j_min)


def test_table2_reference_columns_and_analytic_optimum(table2):
    for kind, (paper_j, paper_value, unit) in PAPER_TABLE2.items():
        assert table2.loc[kind, "paper_J_min"] == paper_j
        assert table2.loc[kind, "paper_optimum"] == paper_value
        assert table2.loc[kind, "unit"] == unit
    assert table2.loc["iipfm", "analytic_optimum"] == pytest.approx(iipfm_optimal_t_l(P) * 1e3)
    assert math.isnan(table2.loc["pwm", "analytic_optimum"])
    assert table2.loc["iipfm", "gain"] == pytest.approx(1 + 3 / table2.loc["iipfm", "optimum"])


# ---- validation ------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("call", "match"),
    [
        (lambda: linearity_cost("pfm", 0.02), "unknown modulator kind"),
        (lambda: linearity_cost("pwm", -1.0), "f_w"),
        (lambda: linearity_cost("dsm", 0.02, n_xi=1), "n_xi"),
        (lambda: linearity_cost("dsm", 0.02, n_xi=10.0), "n_xi"),
        (lambda: sweep("ipfm", P, 0.02, 0.01, 0.001), "stop"),
        (lambda: sweep("ipfm", P, 0.01, 0.02, 0.0), "step"),
        (lambda: optimum("ipfm", P, 0.001, 0.003, 0.001), "no feasible"),
        (lambda: sweep_frame({"pwm": SWEEPS["pwm"]}, P), "missing"),
    ],
)
def test_bad_arguments_raise_value_error_naming_them(call, match):
    with pytest.raises(ValueError, match=match):
        call()


# ---- figures ---------------------------------------------------------------------------


def test_figures_draw_the_tidy_tables():
    small = {k: {**g, "step": g["step"] * 20} for k, g in SWEEPS.items()}
    sweeps = sweep_frame(small, P, n_xi=20)
    assert set(sweeps["modulator"]) == {"pwm", "ipfm", "iipfm", "dsm"}
    np.testing.assert_allclose(
        sweeps.loc[sweeps["modulator"] == "pwm", "x_ms"],
        1e3 / sweeps.loc[sweeps["modulator"] == "pwm", "value"],
    )
    fig = plot_cost_sweeps(sweeps)
    assert isinstance(fig, Figure)
    assert len(fig.legends[0].get_texts()) == 4  # below the axes: never over a curve
    curves = equilibrium_frame({"pwm": 20.0, "iipfm": 0.02}, P, n_xi=21)
    assert len(curves) == 42
    np.testing.assert_allclose(curves["p_target"], P.k2 * curves["xi"])
    fig = plot_equilibrium(curves)
    assert len(fig.axes) == 4  # two rows x two modulators
    with pytest.raises(ValueError, match="J"):
        plot_cost_sweeps(sweeps.drop(columns="J"))


# ---- issue 14: a valve's own Table 2 ----------------------------------------------------

EXAMPLE = ValveParams(c1=0.45, k2=1.05, tau2=0.70, t_on=0.004, t_off=0.009)


def eq25_by_hand(kind: str, value: float, v: ValveParams, n: int = 100) -> float:
    """Eq. 25 written out from docs/model.md sections 3-4, one xi at a time (independent code)."""
    total = 0.0
    for i in range(n):
        x = i / (n - 1)
        if kind == "pwm":
            a1, a2 = (1 - x) - v.t_off * value, x - v.t_on * value
        elif kind == "ipfm":
            a1, a2 = 1 - (1 + v.t_off / value) * x, (1 - v.t_on / value) * x
        elif kind == "iipfm":
            g = 1 + v.t_on / value
            a1 = (1 / g) * (1 - v.t_off / value) * (1 - x)
            a2 = 1 - (1 / g) * (1 + v.t_on / value) * (1 - x)
        else:
            f = 1 / value
            a1 = 1 - (1 + 2 * f * v.t_off) * x + 2 * f * v.t_off * x**2
            a2 = (1 - 2 * f * v.t_on) * x + 2 * f * v.t_on * x**2
        if a2 <= 1e-15:
            p_eq = 0.0
        elif a1 <= 0:
            p_eq = v.k2
        else:
            b = v.tau2**2 * a1**2 / (2 * v.c1**2 * a2**2)
            p_eq = v.k2 + b * (1 - math.sqrt(1 + 4 * v.k2 * v.c1**2 * a2**2 / (v.tau2**2 * a1**2)))
        total += abs(p_eq - v.k2 * x)
    return total


def optimum_by_hand(kind: str, v: ValveParams) -> tuple[float, float]:
    g = SWEEPS[kind]
    count = int((g["stop"] - g["start"]) / g["step"] + 1e-9) + 1
    best = (math.inf, math.nan)
    for k in range(count):
        value = round(g["start"] + k * g["step"], 12)
        if (kind == "ipfm" and value <= v.t_on) or (kind in ("iipfm", "dsm") and value <= v.t_off):
            continue
        j = eq25_by_hand(kind, value, v)
        if j < best[0]:
            best = (j, value)
    return best[1], best[0]


@pytest.fixture(scope="module")
def example_table2() -> pd.DataFrame:
    return tuning_table(SWEEPS, EXAMPLE, n_xi=100).set_index("modulator")


@pytest.mark.parametrize("kind", ["pwm", "ipfm", "iipfm", "dsm"])
def test_table2_of_a_non_nominal_valve_agrees_with_eq25_by_hand(kind, example_table2):
    """Issue 14, done when: the table agrees with an independent evaluation of Eq. 25."""
    value, j_min = optimum_by_hand(kind, EXAMPLE)
    row = example_table2.loc[kind]
    scale = 1.0 if kind == "pwm" else 1e3
    assert row["optimum"] == pytest.approx(value * scale, abs=1e-9)
    assert row["J_min"] == pytest.approx(j_min, rel=1e-9)
    paper = PAPER_SETTING[kind]
    assert row["J_paper_setting"] == pytest.approx(eq25_by_hand(kind, paper, EXAMPLE), rel=1e-9)


def test_recommendation_of_a_non_nominal_valve_is_the_minimum_of_eq25_by_hand():
    unconstrained = {
        "max_switching_rate": None,
        "max_chattering": None,
        "max_chattering_relative": None,
        "min_pulse_width": None,
    }
    by_hand = {k: optimum_by_hand(k, EXAMPLE) for k in ("pwm", "ipfm", "iipfm", "dsm")}
    kind = min(by_hand, key=lambda k: by_hand[k][1])
    for options in (unconstrained, {}):  # the defaults do not bind at this optimum
        rec = tune(EXAMPLE, sweeps=SWEEPS, options=options).recommendation
        best = rec["recommended"]
        assert best["modulator"] == kind == "iipfm"
        assert best["setting"]["t_l"] == pytest.approx(by_hand[kind][0], abs=1e-12)
        assert best["setting"]["gain"] == pytest.approx(1 + EXAMPLE.t_on / by_hand[kind][0])
        assert best["J"] == pytest.approx(by_hand[kind][1], rel=1e-9)
        runners = {r["modulator"]: r for r in rec["runners_up"]}
        assert set(runners) == {"pwm", "ipfm", "dsm"}
        if not options:
            continue
        for k, r in runners.items():  # unconstrained, each runner-up is its own optimum
            assert r["J"] == pytest.approx(by_hand[k][1], rel=1e-9)


def test_nominal_table2_done_when(table2):
    """Issue 14: IIPFM optimum ~19.5 ms with G ~1.154, Eq. 29 19.3 ms, J at the paper's 20 Hz.

    The paper prints J = 10.5 for PWM at its 20 Hz: we get 10.94 there (4 % above; the
    sweep minimum is 10.92 at 18.6 Hz). For IIPFM at 20 ms it prints 4.8, we get 3.69.
    """
    t2 = tuning_table(SWEEPS, P, n_xi=100).set_index("modulator")
    assert t2.loc["iipfm", "optimum"] == 19.5
    assert t2.loc["iipfm", "gain"] == pytest.approx(1.154, abs=5e-4)
    assert t2.loc["iipfm", "analytic_optimum"] == pytest.approx(19.3, abs=0.05)
    assert t2.loc["pwm", "J_paper_setting"] == pytest.approx(linearity_cost("pwm", 20.0, P))
    assert t2.loc["pwm", "J_paper_setting"] == pytest.approx(10.5, rel=0.05)
    assert t2.loc["iipfm", "J_paper_setting"] == pytest.approx(3.69, abs=0.01)
    # the analytic stage's Table 2 and this one agree where they overlap
    for kind in ("pwm", "ipfm", "iipfm", "dsm"):
        assert t2.loc[kind, "optimum"] == table2.loc[kind, "optimum"]
        assert t2.loc[kind, "J_min"] == table2.loc[kind, "J_min"]
    assert (t2["interval_method"] == "none").all()
    assert (t2["optimum_lo"] == t2["optimum"]).all() and (t2["J_min_hi"] == t2["J_min"]).all()


def test_j_exact_column_is_the_exact_cost_at_the_optimum(example_table2):
    usable = 0
    for kind, row in example_table2.iterrows():
        value = row["optimum"] * (1.0 if kind == "pwm" else 1e-3)
        assert row["J_exact"] == pytest.approx(
            float(linearity_cost(kind, value, EXAMPLE, exact=True)), rel=1e-12
        )
        if setting_metrics(kind, value, EXAMPLE)["chattering"] <= 0.05:  # J's optimum is usable
            usable += 1
            assert row["J_exact_min"] <= row["J_exact"]
    assert usable > 0, "J's optimum is usable for some kinds of the example"


def _seconds(kind: str, shown: float) -> float:
    return shown if kind == "pwm" else shown * 1e-3


def test_j_exact_optimum_meets_the_constraints_and_is_interior(example_table2):
    """Issue 25: unconstrained, J_exact's minimum is the grid's longest period (IPFM, ΔΣM
    999.5 ms), where the pressure swings by most of k2; restricted to the settings that meet
    the tuning constraints it is an interior one (ΔΣM 16.5 ms for this valve)."""
    limits = TuningOptions()
    for kind, row in example_table2.iterrows():
        value = _seconds(kind, row["optimum_exact"])
        m = setting_metrics(kind, value, EXAMPLE)
        assert m["chattering"] <= limits.chattering_limit(EXAMPLE)
        assert m["switching_rate"] <= limits.max_switching_rate
        assert m["min_pulse"] >= limits.min_pulse_width * (1 - 1e-9)
        assert not row["optimum_exact_at_grid_edge"] and not row["optimum_at_grid_edge"]
        assert row["J_exact_min"] == pytest.approx(
            float(linearity_cost(kind, value, EXAMPLE, exact=True))
        )
    assert example_table2.loc["dsm", "optimum_exact"] == pytest.approx(16.5)
    free = {
        "max_switching_rate": None,
        "max_chattering": None,
        "max_chattering_relative": None,
        "min_pulse_width": None,
    }
    loose = tuning_table(SWEEPS, EXAMPLE, 100, options=TuningOptions(**free))
    loose = loose.set_index("modulator")
    for kind in ("ipfm", "dsm"):  # J_exact -> 0 as the period grows
        row = loose.loc[kind]
        assert row["optimum_exact"] == pytest.approx(999.5) and row["optimum_exact_at_grid_edge"]
        assert row["J_exact_min"] < example_table2.loc[kind, "J_exact_min"]
        swing = setting_metrics(kind, 0.9995, EXAMPLE)["chattering"]
        assert swing > 0.7 * EXAMPLE.k2


def test_j_exact_optimum_is_nan_when_no_setting_meets_the_constraints():
    small = {k: {**g, "step": g["step"] * 10} for k, g in SWEEPS.items()}
    table = tuning_table(small, EXAMPLE, 50, options=TuningOptions(max_chattering=1e-6))
    assert table["optimum_exact"].isna().all() and table["J_exact_min"].isna().all()
    assert not table["optimum_exact_at_grid_edge"].any()


def test_an_optimum_on_the_last_setting_is_flagged():
    narrow = {**SWEEPS, "pwm": {"start": 1.0, "stop": 10.0, "step": 0.5}}  # optimum near 18 Hz
    table = tuning_table(narrow, EXAMPLE, 50).set_index("modulator")
    assert table.loc["pwm", "optimum"] == 10.0 and table.loc["pwm", "optimum_at_grid_edge"]
    assert not table.loc["iipfm", "optimum_at_grid_edge"]


def test_j_exact_equals_j_under_fast_switching():
    """Tiny delays and short periods: the orbit is its average and J_exact -> J."""
    fast = ValveParams(t_on=1e-6, t_off=1e-6)
    for kind, value in [("pwm", 2000.0), ("ipfm", 5e-4), ("iipfm", 5e-4), ("dsm", 5e-4)]:
        j, j_exact = (
            linearity_cost(kind, value, fast),
            linearity_cost(kind, value, fast, exact=True),
        )
        assert j_exact == pytest.approx(j, rel=2e-3), kind


def test_intervals_bracket_the_point_and_widen_with_the_box():
    narrow = {"c1": (0.448, 0.452), "t_on": (0.0039, 0.0041)}
    wide = {"c1": (0.40, 0.50), "t_on": (0.003, 0.005), "t_off": (0.008, 0.010)}
    small = {k: {**g, "step": g["step"] * 5} for k, g in SWEEPS.items()}
    a = tuning_table(small, EXAMPLE, 50, narrow).set_index("modulator")
    b = tuning_table(small, EXAMPLE, 50, wide).set_index("modulator")
    for col in ("optimum", "J_min", "J_exact"):
        assert (a[f"{col}_lo"] <= a[col]).all() and (a[col] <= a[f"{col}_hi"]).all()
        assert (b[f"{col}_lo"] <= a[f"{col}_lo"]).all() and (a[f"{col}_hi"] <= b[f"{col}_hi"]).all()
    assert (b["J_min_hi"] - b["J_min_lo"] > 0).all()
    assert (a["interval_method"] == "corners").all()


def test_corners_and_propagate():
    box = {"c1": (0.5, 0.6), "k2": (0.8, 0.9), "t_off": (0.01, 0.01)}
    valves = corners(P, box)
    assert len(valves) == 4  # t_off's interval has one end
    assert {(v.c1, v.k2) for v in valves} == {(0.5, 0.8), (0.5, 0.9), (0.6, 0.8), (0.6, 0.9)}
    lo, hi = propagate(lambda v: [v.c1 * v.k2, -v.c1], P, box)
    np.testing.assert_allclose(lo, [0.4, -0.6])
    np.testing.assert_allclose(hi, [0.54, -0.5])
    assert corners(P, None) == [] and corners(ValveParams(), {"t_on": (-1e-3, 0.004)})[0].t_on > 0
    with pytest.raises(ValueError, match="unknown parameter"):
        corners(P, {"c2": (1.0, 2.0)})
    with pytest.raises(ValueError, match="k2: 95 % interval"):
        read_intervals({"k2": {"value": 0.8, "lo": 0.9, "hi": 0.7}})


@pytest.mark.parametrize(
    ("params", "name"),
    [
        (ValveParams(t_on=1.5), "t_on = 1.5 s"),
        (ValveParams(t_off=1.2), "t_off = 1.2 s"),
        (ValveParams(t_on=0.6, t_off=0.5), "t_on \\+ t_off"),
    ],
)
def test_delays_longer_than_the_sweep_are_named(params, name):
    with pytest.raises(ValueError, match=name):
        check_sweeps(SWEEPS, params)
    with pytest.raises(ValueError, match=name):
        tune(params, sweeps=SWEEPS)


def test_gain_argument_of_the_cost():
    j = linearity_cost("iipfm", np.array([0.02, 0.03])[:, None], P, gain=np.array([1.0, 1.15]))
    assert j.shape == (2, 2)
    assert j[0, 1] == pytest.approx(float(linearity_cost("iipfm", 0.02, P, gain=1.15)))
    assert linearity_cost("iipfm", 0.02, P, gain=1 + P.t_on / 0.02) == linearity_cost(
        "iipfm", 0.02, P
    )
    with pytest.raises(ValueError, match="pwm: has no gain"):
        linearity_cost("pwm", 20.0, P, gain=1.1)


def test_intervals_touching_a_physical_bound_are_accepted_and_clipped() -> None:
    """Issue 29: an identification's own output is a valid tuning input. A valve that opens
    at once (t_on = 0, its interval [0, 0.68 ms]) is tuned, not refused; an interval reaching
    past a bound (k2's lower end -0.1) is clipped to the domain and the clipping is said."""
    from spa.identification.identified import read_identified
    from spa.model.thresholds import thresholds
    from spa.tuning.cost import DEFAULT_SWEEPS

    flat = {"c1": 0.5, "k2": 0.8, "tau2": 0.8, "t_on": 0.0, "t_off": 0.01}
    assert read_identified(flat).params.t_on == 0.0
    ident = {k: {"value": v, "lo": v * 0.9, "hi": v * 1.1} for k, v in flat.items()}
    ident["t_on"] = {"value": 1e-6, "lo": 0.0, "hi": 0.00068}
    ident["k2"] = {"value": 0.8, "lo": -0.1, "hi": 1.7}
    valve = read_identified(ident)
    assert valve.intervals["t_on"] == (0.0, 0.00068) and "t_on" not in valve.clipped
    assert valve.intervals["k2"] == (pytest.approx(1.7e-3), 1.7)
    assert "clipped to the domain edge" in valve.clipped["k2"]
    small = {k: {**g, "step": g["step"] * 20} for k, g in DEFAULT_SWEEPS.items()}
    result = tune(valve, sweeps=small, n_xi=20)
    assert result.recommendation["intervals_clipped"] == dict(valve.clipped)
    assert result.recommendation["recommended"] is not None
    ideal = ValveParams(t_on=0.0, t_off=0.0)  # the formulas' limits, no division by zero
    assert [float(v) for v in thresholds("dsm", ideal, period=0.02)] == [0.0, 1.0]
