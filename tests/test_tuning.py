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
from spa.model.averaging import equilibrium
from spa.plots.analytic import plot_cost_sweeps, plot_equilibrium
from spa.tuning import (
    PAPER_TABLE2,
    equilibrium_frame,
    feasible,
    iipfm_optimal_t_l,
    linearity_cost,
    modulator_settings,
    optimum,
    optimum_table,
    sweep,
    sweep_frame,
    sweep_grid,
)

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


def test_full_sweeps_are_fast():
    import time

    start = time.perf_counter()
    sweep_frame(SWEEPS, P, n_xi=100)
    assert time.perf_counter() - start < 1.0  # ~3750 grid points x 100 xi


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
    assert len(fig.axes[0].get_legend().get_texts()) == 4
    curves = equilibrium_frame({"pwm": 20.0, "iipfm": 0.02}, P, n_xi=21)
    assert len(curves) == 42
    np.testing.assert_allclose(curves["p_target"], P.k2 * curves["xi"])
    fig = plot_equilibrium(curves)
    assert len(fig.axes) == 4  # two rows x two modulators
    with pytest.raises(ValueError, match="J"):
        plot_cost_sweeps(sweeps.drop(columns="J"))
