"""A delay pressed against the searched bound is said (issue 63): the valve's delay may be
longer, or the fit stands in for what the model misses."""

from __future__ import annotations

from spa.identification.refined import bound_warnings
from spa.identification.results import Estimate


def test_only_a_resolved_delay_at_the_bound_is_said():
    at = Estimate(0.0499, 0.041, 0.05, "s")
    inside = Estimate(0.030, 0.025, 0.035, "s")
    unresolved = Estimate(0.05, 0.0, 0.05, "s", resolved=False)  # already said as unresolved
    fallback = Estimate(0.05, None, None, "s", fallback="no pulse run")
    said = bound_warnings({"t_on": at, "t_off": inside}, 0.05, 0.001)
    assert len(said) == 1 and said[0].startswith("t_on = 49.9 ms reaches the search bound")
    assert "[41, 50] ms" in said[0] and "identification.max_delay" in said[0]
    assert bound_warnings({"t_on": unresolved, "t_off": fallback}, 0.05, 0.001) == []
    # within one logging step of the bound counts; a step and a half does not
    assert len(bound_warnings({"t_off": Estimate(0.048, 0.04, 0.05, "s")}, 0.05, 0.002)) == 1
    assert bound_warnings({"t_off": Estimate(0.047, 0.04, 0.05, "s")}, 0.05, 0.002) == []


def test_edges_after_a_delay_longer_than_the_fitted_window_still_respond():
    """Each edge's response is fitted over ``post`` (30 ms) past the hold: a valve whose
    delays are 40 ms has responding edges and a per-edge spread, not every edge censored
    (the round trip's balloon was told to record pulse trains that move the pressure)."""
    from spa.identification import identify, simulate_identification
    from spa.model.params import ValveParams

    truth = ValveParams(c1=0.45, k2=1.05, tau2=0.7, t_on=0.040, t_off=0.045)
    runs = simulate_identification(truth)
    result = identify([runs["charge"]], [runs["discharge"]], [runs["pulse"]], seed=1, n_boot=50)
    pulse = result.delays.summary()
    assert pulse["n_edges_on"] > 0 and pulse["n_edges_off"] > 0, pulse
    assert result.t_on.spread["n"] > 0 and result.t_off.spread["n"] > 0
    assert abs(result.t_on.spread["median"] - truth.t_on) < 0.003
