"""Simultaneous bands of the identified laws (spa.identification.laws_bands): their sup-t
calibration, their coverage of known laws, the pressures visited, the box they give and the
clause that flags a use outside those pressures."""

from __future__ import annotations

import numpy as np
import pytest
from _laws_data import bench_runs

from spa.identification.identified import corners, laws_intervals
from spa.identification.laws_bands import (
    band_envelope,
    law_bands,
    outside_visited_clause,
    sup_t_quantile,
    visited_pressures,
)
from spa.identification.laws_fit import fit_laws
from spa.model.laws import Laws
from spa.model.laws.rates import closed_rate, open_rate
from spa.model.params import ValveParams

OTHER = Laws(log_g=(0.8, 0.0, -0.5, -0.6), log_h=(-0.5, 0.0, 0.4, 0.6), m=0.8)
TRUTH = ValveParams(laws=OTHER)


def test_sup_t_covers_whole_curves_not_points():
    rng = np.random.default_rng(1)
    # correlated Gaussian curves: a smooth random walk over 30 points
    draws = np.cumsum(rng.normal(size=(4000, 30)), axis=1) * 0.1
    spread = draws.std(axis=0)
    c = sup_t_quantile(draws[:2000], spread, np.ones(30, bool))
    fresh = np.max(np.abs(draws[2000:]) / spread, axis=1)
    assert 0.93 < np.mean(fresh <= c) < 0.97  # simultaneous 95 %
    assert c > 1.96  # wider than pointwise
    # the mask restricts where the maximum runs: fewer points, smaller c
    assert sup_t_quantile(draws, spread, np.arange(30) < 5) < c


@pytest.fixture(scope="module")
def fitted():
    out = []
    for seed in (0, 1, 2):  # the first three seeds
        runs = bench_runs(TRUTH, np.random.default_rng(seed))
        fit = fit_laws(runs, ValveParams())
        out.append((runs, fit, law_bands(runs, fit)))
    return out


def test_bands_cover_the_true_laws_over_the_visited_pressures(fitted):
    covered = []
    for _, _, b in fitted:
        for mode, law in (("open", open_rate), ("closed", closed_rate)):
            lo, hi = b.visited[mode]
            use = (b.grid >= lo) & (b.grid <= hi) & np.isfinite(b.lo[mode])
            assert use.sum() > 30
            true = law(b.grid[use], TRUTH)
            covered.append(bool(np.all((b.lo[mode][use] <= true) & (true <= b.hi[mode][use]))))
            # the band holds the estimate and is narrow where the data are rich
            assert np.all(b.lo[mode][use] <= b.rate[mode][use])
            assert np.all(b.rate[mode][use] <= b.hi[mode][use])
        env = b.envelope()
        assert 0.0 < env["open"] < 0.2 and 0.0 < env["closed"] < 0.2
    assert sum(covered) >= 5, covered


def test_bands_are_deterministic_and_record_cleanly(fitted):
    runs, fit, b = fitted[0]
    again = law_bands(runs, fit)
    np.testing.assert_array_equal(again.lo["open"], b.lo["open"])
    other = law_bands(runs, fit, seed=1)
    assert not np.array_equal(other.lo["open"], b.lo["open"])
    rec = b.to_dict()
    assert len(rec["grid"]) == 41 and rec["level"] == 0.95 and rec["draws"] == 400
    assert set(rec["open"]) == {"rate", "lo", "hi", "critical"}
    assert b.visited_dict()["closed"][0] == pytest.approx(b.visited["closed"][0])
    # the envelope from the record equals the one of the value
    assert band_envelope(rec, b.visited_dict()) == pytest.approx(b.envelope())


def test_visited_pressures_per_mode(fitted):
    runs, fit, _ = fitted[0]
    v = visited_pressures(runs, fit.params)
    charge = next(r for r in runs if r.kind == "charge")
    only = visited_pressures([charge], fit.params)
    # a charge run visits its whole rise open, and closed only before its edge (at ~0)
    assert only["open"][1] > 0.9 * TRUTH.k2 and only["closed"][1] < 0.05
    assert v["closed"][1] >= only["closed"][1] and v["open"][0] <= only["open"][0]
    for lo, hi in v.values():
        assert 0.0 <= lo < hi


def test_the_box_of_a_laws_valve_scales_each_law_by_its_envelope(fitted):
    _, fit, b = fitted[0]
    record = {"bands": b.to_dict(), "visited": b.visited_dict(),
              "covariance": {"names": list(fit.names), "matrix": fit.cov.tolist()}}  # fmt: skip
    valve = fit.params
    iv = laws_intervals(record, valve)
    # the envelope leaves out the tenth of k2 next to each law's zero, so it is no wider
    env = band_envelope(b.to_dict(), b.visited_dict(), valve.k2)
    wide = b.envelope()
    assert all(env[m] <= wide[m] + 1e-15 for m in ("open", "closed"))
    assert iv["tau2"] == pytest.approx(
        (valve.tau2 / (1 + env["open"]), valve.tau2 * (1 + env["open"]))
    )
    assert iv["c1"] == pytest.approx(
        (valve.c1 / (1 + env["closed"]), valve.c1 * (1 + env["closed"]))
    )
    se = fit.se
    assert iv["k2"][1] == pytest.approx(valve.k2 * np.exp(1.96 * se["log_k2"]))
    assert iv["t_on"][1] == pytest.approx(valve.t_on + 1.96 * se["t_on"])
    box = corners(valve, iv)
    assert box and all(v.laws == valve.laws for v in box)
    # a corner's scaled tau2 scales the whole charge law: the band's envelope at its edge
    slow = max(box, key=lambda v: v.tau2)
    p = b.grid[(b.grid > 0.1) & (b.grid < 0.5)]
    ratio = open_rate(p, slow) / open_rate(p, valve.__class__(**{**valve.as_dict(), "k2": slow.k2}))
    np.testing.assert_allclose(ratio, 1.0 / (1.0 + env["open"]), rtol=1e-12)
    with pytest.raises(ValueError, match=r"laws\.covariance"):
        laws_intervals({"covariance": {"names": ["t_on", "t_off"], "matrix": [[1.0]]}}, valve)


def test_a_use_outside_the_visited_pressures_is_flagged():
    visited = {"open": [0.0, 0.5], "closed": [0.05, 0.6]}
    assert outside_visited_clause([0.1, 0.45], visited, "the set-points") == ""
    text = outside_visited_clause([0.02, 0.3, 0.55], visited, "the recommended setting's levels")
    assert text.startswith("The recommended setting's levels at 0.02 and 0.55 bar lie outside")
    assert "(0.05–0.5 bar)" in text
    assert outside_visited_clause([0.9], None, "x") == ""  # no laws identified: nothing said
    assert outside_visited_clause([0.9], {"open": [None, None], "closed": [0, 1]}, "x") == ""


def test_bad_arguments_are_named(fitted):
    runs, fit, _ = fitted[0]
    with pytest.raises(ValueError, match="needs the runs"):
        law_bands([], fit)
    with pytest.raises(ValueError, match="draws must be >= 20"):
        law_bands(runs, fit, draws=5)


def test_the_page_draws_the_laws_or_says_why_not(fitted, tmp_path):
    import pandas as pd

    from spa.plots.laws import laws_data, laws_figure
    from spa.stages.identify import _write_laws

    _, fit, b = fitted[0]
    v = fit.params
    params = {
        **{n: {"value": getattr(v, n)} for n in ("c1", "k2", "tau2", "t_on", "t_off")},
        "laws": {"chosen": "identified", "bands": b.to_dict(), "visited": b.visited_dict()},
    }
    data = laws_data(params)
    assert set(data["series"]) == {"identified", "lo", "hi", "paper", "visited"}
    paper = data[(data["mode"] == "closed") & (data["series"] == "paper")]
    np.testing.assert_allclose(paper["dpdt"], -np.sqrt(paper["p"]) / v.c1)
    fig = laws_figure(data)
    assert [ax.get_title() for ax in fig.axes[:2]] == [
        "valve open: f_open(P)",
        "valve closed: f_closed(P)",
    ]
    out = {"laws": tmp_path / "laws.png", "laws_csv": tmp_path / "laws.csv"}
    _write_laws(params, out, "d")
    assert out["laws"].stat().st_size > 0 and len(pd.read_csv(out["laws_csv"])) == len(data)
    kept = {**params, "laws": {"chosen": "paper", "reason": "identification.laws: paper"}}
    with pytest.raises(ValueError, match="has no bands"):
        laws_data(kept)
    _write_laws(kept, out, "d")  # a placeholder figure and an empty table
    assert pd.read_csv(out["laws_csv"]).empty


def test_the_page_flags_a_recommendation_outside_the_visited_pressures():
    from spa.model.averaging import equilibrium
    from spa.report.laws import laws_use_note, recommended_levels

    valve = ValveParams(laws=OTHER)
    ident = {
        **{n: getattr(valve, n) for n in ("c1", "k2", "tau2", "t_on", "t_off")},
        "laws": {
            "chosen": "identified",
            "coefficients": OTHER.as_dict(),
            "valve": {"k2": valve.k2, "t_on": valve.t_on, "t_off": valve.t_off},
            "visited": {"open": [0.0, 0.5 * valve.k2], "closed": [0.0, valve.k2]},
        },
    }
    rec = {"recommended": {"setting": {"type": "pwm", "f_w": 20.0},
                           "predicted": {"dead_zone": 0.05, "saturation": 0.95}}}  # fmt: skip
    levels = recommended_levels(rec, valve)
    np.testing.assert_allclose(levels[-1], equilibrium("pwm", 0.95, valve, f_w=20.0))
    top = [p for p in levels if p > 0.5 * valve.k2]
    assert top  # the setting reaches above what the charges visited
    note = laws_use_note(rec, ident)
    assert note.startswith("The recommended setting's levels at ")
    assert f"{top[-1]:.3g} bar" in note
    # the paper's laws chosen: nothing said; a loop's set-points inside: nothing said
    assert laws_use_note(rec, {**ident, "laws": {**ident["laws"], "chosen": "paper"}}) == ""
    assert laws_use_note({"levels": [0.1, 0.3]}, ident) == ""
