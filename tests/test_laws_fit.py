"""Fitting the actuator's laws and the rule that chooses them (spa.identification.laws_fit),
on benches made with known laws and on the compliant balloons."""

from __future__ import annotations

import dataclasses

import numpy as np
import pandas as pd
import pytest
from _laws_data import DT, bench_runs, plant_runs

from spa import simulate
from spa.identification.laws_fit import choose_laws, fit_laws, law_model, law_names
from spa.identification.refine import prepare_runs, refine
from spa.model.laws import Laws
from spa.model.laws.rates import open_rate
from spa.model.params import ValveParams
from spa.synthetic.balloons import BALLOON_SEEDS, compliant_balloons
from spa.synthetic.physical import equivalent_params

# A charge rate falling with pressure and a discharge rising: not the paper's.
OTHER = Laws(log_g=(0.8, 0.0, -0.5, -0.6), log_h=(-0.5, 0.0, 0.4, 0.6), m=0.8)


def test_charges_from_three_pressures_fall_on_one_f_open():
    truth = ValveParams(laws=OTHER)
    rng = np.random.default_rng(11)
    n = round(4.0 / DT)
    runs, kinds = {}, {}
    for j, p0 in enumerate((0.0, 0.25 * truth.k2, 0.5 * truth.k2)):
        u = np.ones(n, np.int8)
        u[:20] = 0  # 20 ms closed, then the charge: a run with its command edge
        p = simulate(u, DT, truth, p0=p0) + rng.normal(0.0, 0.001, n)
        runs[f"charge{j}"] = pd.DataFrame({"t": np.arange(n) * DT, "p": p, "valve": u})
        kinds[f"charge{j}"] = "charge"
    prepared = prepare_runs(runs, kinds)
    start = ValveParams()
    # Under the paper's laws the three charges disagree with any single exponential...
    paper = min(
        100 * (1 - np.linalg.norm(law_model(r, start) - r.y) / np.linalg.norm(r.y - r.y.mean()))
        for r in prepared
    )
    fit = fit_laws(prepared, start, m=0.5, valve=False)
    # ...and with the fitted laws all three follow one f_open.
    assert min(fit.fit.values()) > 99.5 > paper
    p = np.linspace(0.02, 0.9, 45) * truth.k2
    ratio = open_rate(p, fit.params) / open_rate(p, truth)
    assert np.max(np.abs(ratio - 1.0)) < 0.02
    assert fit.fixed == ("m", "log_k2", "t_on", "t_off")
    assert fit.se["m"] == 0.0 and fit.se["log_g[0]"] > 0.0


def test_paper_data_keep_the_paper_laws():
    truth = ValveParams(c1=0.45, k2=0.9, tau2=0.7, t_on=0.003, t_off=0.006)
    runs = bench_runs(truth, np.random.default_rng(3))
    choice = choose_laws(runs, truth)
    assert choice.laws == "paper"
    assert choice.params == truth and choice.params.laws is None
    assert abs(choice.gain) < 1.0
    assert set(choice.fit_paper) == {r.rid for r in runs if r.modulator}
    # The fitted laws sit on the paper's: every log-rate within 4 standard errors of 0.
    n = 2 * len(choice.fit.laws.knots)
    se = np.array([choice.fit.se[k] for k in law_names()[:n]])
    assert np.all(np.abs(choice.fit.x[:n]) < np.maximum(4 * se, 0.02))


def test_other_laws_are_recovered_and_chosen():
    truth = ValveParams(laws=OTHER)
    runs = bench_runs(truth, np.random.default_rng(5))
    choice = choose_laws(runs, ValveParams())
    assert choice.laws == "identified"
    assert choice.gain > 2.0 and choice.gain > 2.0 * choice.se
    got = choice.params
    assert got.laws is not None
    assert abs(got.laws.m - OTHER.m) < 0.05
    p = np.linspace(0.05, 0.95, 19) * truth.k2
    np.testing.assert_allclose(open_rate(p, got), open_rate(p, truth), rtol=0.02)
    assert abs(got.k2 - truth.k2) < 0.005
    # The one-step held-out fits (as the refinement's) agree with the refits here.
    assert set(choice.fit.heldout) == {r.rid for r in runs}
    quick = choose_laws(runs, ValveParams(), fit=choice.fit, refit=False)
    assert abs(quick.gain - choice.gain) < 1.0
    # The covariance is a covariance: symmetric, positive semi-definite.
    np.testing.assert_allclose(choice.fit.cov, choice.fit.cov.T, atol=1e-15)
    assert np.min(np.linalg.eigvalsh(choice.fit.cov)) > -1e-12


@pytest.mark.parametrize("name", ["balloon-04"])
def test_a_compliant_balloon_chooses_the_identified_laws(name):
    plant = compliant_balloons()[name]
    runs = plant_runs(plant, np.random.default_rng(BALLOON_SEEDS[name]))
    rf = refine(runs, equivalent_params(plant))
    choice = choose_laws(runs, rf.params, paper_heldout=rf.fit_heldout, delay=rf.delay)
    assert choice.laws == "identified", choice.reason
    assert min(choice.fit_identified.values()) > 90.0
    assert min(choice.fit_paper.values()) < 85.0


def test_bad_arguments_are_named():
    with pytest.raises(ValueError, match="at least one run"):
        fit_laws([], ValveParams())
    runs = bench_runs(ValveParams(), np.random.default_rng(0), seconds=4.0)[:1]
    with pytest.raises(ValueError, match=r"m must be in \[0.5, 1\]"):
        fit_laws(runs, ValveParams(), m=0.3)
    with pytest.raises(ValueError, match="x0 must hold 12 values"):
        fit_laws(runs, ValveParams(), x0=np.zeros(3))
    one = choose_laws(runs, dataclasses.replace(ValveParams(), delay="hold"))
    assert one.laws == "paper" and "too few" in one.reason


def test_the_laws_replay_the_same_command_runs_as_the_paper_on_edges_off_the_ticks():
    """Edges logged off the log's ticks are moved earlier by half a step (the run's
    ``edge_shift``) for the paper's laws; the general laws' model replays the same runs, so
    the paper's laws written as a Laws value give the paper's replay."""
    from spa.identification.edges import EdgeTiming

    truth = ValveParams(c1=0.45, k2=0.9, tau2=0.7, t_on=0.003, t_off=0.006)
    n = 3000
    u = (np.arange(n) // 137 % 2).astype(np.int8)
    p = simulate(u, DT, truth)
    table = pd.DataFrame({"t": np.arange(n) * DT, "p": p, "valve": u})
    sampled = EdgeTiming("sampled", "declared", DT)
    (run,) = prepare_runs({"r": table}, {"r": "pulse"}, edges={"r": sampled})
    assert run.edge_shift[1:].min() > 0.0  # the edges are moved
    nested = dataclasses.replace(truth, laws=Laws(log_g=(0.0,) * 4, log_h=(0.0,) * 4, m=0.5))
    for delay in ("hold", "transport"):
        paper = run.model(truth, delay)
        general = law_model(run, nested, delay)
        assert np.max(np.abs(general - paper)) < 1e-5  # the fit's time maps: about 1e-6 bar
    # Without the shift the replays part by about the step's effect on every edge.
    unshifted = dataclasses.replace(run, edge_shift=np.zeros(run.starts.size))
    assert np.max(np.abs(law_model(unshifted, nested) - run.model(truth))) > 1e-4
