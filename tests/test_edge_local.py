"""The delays read at each command edge on its own: the form test, the medians and their
standard errors, and the refinement that holds them."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest

from spa.identification.edge_local import EdgeDelays, edge_delays
from spa.identification.refine import prepare_runs, refine
from spa.model.params import ValveParams
from spa.model.plant import simulate

TRUTH = ValveParams(0.533, 0.837, 0.826, 0.008, 0.021)


def _train(
    delay: str, seed: int, on: float = 0.09, off: float = 0.11, n: int = 40, noise: float = 0.003
):
    """A pulse train of long segments on spa's exact model, 1 kHz, ``noise`` bar of noise."""
    dt = 1e-3
    one = np.r_[np.ones(round(on / dt)), np.zeros(round(off / dt))]
    u = np.r_[np.zeros(200), np.tile(one, n)]
    p = simulate(u, dt, TRUTH, 0.0, delay=delay)
    p = p + np.random.default_rng(seed).normal(0.0, noise, p.size)
    t = np.arange(u.size) * dt
    return {"train": pd.DataFrame({"t": t, "p": p, "valve": u, "u": 0.5})}


def _edges(tables) -> EdgeDelays:
    prepared = prepare_runs(tables, {"train": "pulse"}, command_dt={"train": 1e-3})
    return edge_delays(prepared, tables, TRUTH)


@pytest.mark.parametrize("delay", ["hold", "transport"])
def test_the_edges_tell_the_convention_and_recover_its_delays(delay) -> None:
    at = _edges(_train(delay, seed=3))
    assert at.form() == delay
    assert at.form_p() < 0.01
    prior = at.prior(delay)
    assert prior is not None
    for name in ("t_on", "t_off"):
        value, se = prior[name]
        assert abs(value - getattr(TRUTH, name)) < 1e-3, (name, value)  # a logging step
        assert 0 < se < 1e-3
    rec = at.record()
    assert rec["form"] == delay and rec["edges_on"] >= 25 and rec["edges_off"] >= 25


@pytest.mark.parametrize("delay", ["hold", "transport"])
@pytest.mark.parametrize("noise", [0.003, 0.012])
def test_the_standard_error_covers_the_seed_to_seed_spread(delay, noise) -> None:
    """Ten seeds: each common delay within 3 of its own standard errors of the truth, also
    where each edge on its own is noisy (12 mbar: the median of the edges' own best delays,
    or an old state extrapolated from before the edge alone, is biased by milliseconds)."""
    for seed in range(10):
        prior = _edges(_train(delay, seed=10 + seed, noise=noise)).prior(delay)
        assert prior is not None
        for name in ("t_on", "t_off"):
            value, se = prior[name]
            assert abs(value - getattr(TRUTH, name)) < 3 * se + 1e-4, (seed, name, value, se)


def test_too_few_edges_give_no_delays_and_no_form() -> None:
    at = _edges(_train("hold", seed=1, n=3))
    assert at.prior("hold") is None
    empty = EdgeDelays(at.table.iloc[:0], 1e-3)
    assert math.isnan(empty.form_p())
    assert empty.prior("hold") is None and empty.record()["edges_on"] == 0


def test_a_vent_from_an_empty_actuator_is_censored() -> None:
    """Edges at 0 bar cannot show a delay: they are left out, not read as 0."""
    tables = _train("hold", seed=2, on=0.002, off=0.2, n=12)
    at = _edges(tables)
    off = at.table[at.table["direction"] == "off"]
    assert off.empty or off["censored"].all()


def test_the_refinement_holds_the_edges_delays_with_their_variance() -> None:
    tables = _train("transport", seed=4)
    prepared = prepare_runs(tables, {"train": "pulse"}, command_dt={"train": 1e-3})
    prior = {"t_on": (0.0085, 2e-4), "t_off": (0.0205, 3e-4)}
    fit = refine(prepared, TRUTH, delay="transport", delay_prior=prior)
    assert fit.params.t_on == 0.0085 and fit.params.t_off == 0.0205
    assert fit.se["t_on"] == pytest.approx(2e-4) and fit.se["t_off"] == pytest.approx(3e-4)
    assert fit.se_difference == pytest.approx(math.hypot(2e-4, 3e-4))
    assert fit.informed["t_on"] == ("train",)
    free = refine(prepared, TRUTH, delay="transport")
    assert free.params.t_on != 0.0085  # without the prior the delays move


def _edges_of_runs(centres, per_run=(10,), own_se=2e-4, seed=0):
    """An :class:`EdgeDelays` of rising and falling edges, ``per_run`` a run (the last
    count for the runs past the list), each edge's
    squared residual a parabola in the delay about its own delay (its run's centre plus
    ``own_se`` of scatter) with that standard error."""
    rng = np.random.default_rng(seed)
    dt, grid = 1e-3, np.arange(0.0, 0.03 + 1e-12, 2.5e-4)
    rows, profiles = [], []
    for r, centre in enumerate(centres):
        for direction in ("on", "off"):
            for k in range(per_run[min(r, len(per_run) - 1)]):
                own = centre + rng.normal(0.0, own_se)
                samples = 40.0
                rows.append(
                    {"run": f"r{r}", "t": 0.1 * k, "direction": direction, "p_edge": 0.3,
                     "noise": 1.0, "samples": samples, "censored": False,
                     "delay_hold": own, "sse_hold": samples,
                     "delay_transport": own, "sse_transport": samples}
                )  # fmt: skip
                profiles.append(samples + ((grid - own) / own_se) ** 2)
    table = pd.DataFrame(rows)
    stack = np.asarray(profiles)
    return EdgeDelays(table, dt, grid, {"hold": stack, "transport": stack})


def test_runs_whose_delays_spread_beyond_their_errors_widen_and_centre_the_interval():
    """One delay stands for runs whose effective delays differ (a bounce or a lag that
    moves with the pulses): its interval holds their spread, and its centre is the runs'
    random-effects mean; runs that agree keep the pooled fit's interval."""
    same = _edges_of_runs([5e-3] * 6).prior("transport")
    value, se = same["t_on"]
    assert value == pytest.approx(5e-3, abs=2e-4)
    assert se < 2e-4  # the edges' pooled error, about 2e-4/sqrt(60) over the runs' spread
    centres = [8e-3, 4e-3, 4.5e-3, 5e-3, 5.5e-3, 6e-3]
    # the first run has 60 edges a direction, the others 8: the edges' pooled minimum leans
    # to the first run's setting
    spread = _edges_of_runs(centres, per_run=(60, 8)).prior("transport")
    value, se = spread["t_on"]
    assert value == pytest.approx(np.mean(centres), abs=1e-4)  # every run weighs alike
    # the 95 % interval holds a run of another setting: about t(5) sd sqrt(1 + 1/6) wide
    assert 1.96 * se > 2.0 * np.std(centres, ddof=1)
