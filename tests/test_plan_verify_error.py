"""A verification's bands hold the identified model's own error, measured on the
identification's recordings (spa.plan.verify_error) as a standard deviation with its
degrees of freedom, the sensor noise's share taken out and scaled to held out, and the
identification's draws keep the valve's own laws (spa.plan.bands)."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest

from spa import simulate
from spa.model.laws import DEFAULT_KNOTS, Laws
from spa.model.modulators import Modulator
from spa.model.params import ValveParams
from spa.plan.limits import Limits
from spa.plan.session import run_commands, run_xi
from spa.plan.verify import (
    compare,
    compare_sine,
    corners,
    design_verification,
    sine_predictions,
    staircase_predictions,
)
from spa.plan.verify_error import no_model_error, recorded_model_error, sine_omega

NOMINAL = ValveParams()
NOISE = 0.002
QUANTUM = 0.001


@pytest.fixture(scope="module")
def session():
    design = design_verification(
        NOMINAL, Modulator.from_mapping({"type": "pwm", "f_w": 20.0}), Limits(p_max=1.0), levels=4
    )
    stair = next(r for r in design.runs if r.kind == "staircase")
    sine = next(r for r in design.runs if r.kind == "sine")
    return design.dt, stair, sine


def _recorded(run, dt, shift):
    """The planned run played on the nominal valve, every sample ``shift`` bar higher."""
    u = run_commands(run, dt)
    t = np.arange(u.size) * dt
    p = simulate(u, dt, NOMINAL) + shift
    return pd.DataFrame({"t": t, "p": p, "valve": u.astype(np.int8), "u": run_xi(run)})


def _levels_kept(table):
    rows = table[table["prediction"].str.startswith("level")]
    return (rows["verdict"] == "kept").to_numpy()


def _error(kind, sd, dof=math.inf):
    return {kind: {"sd": sd, "dof": dof}}


def test_a_level_shifted_by_less_than_the_model_error_is_kept(session):
    dt, stair, _ = session
    error = _error("level", 0.01)  # a 95 % band of about 19.6 mbar
    pred = staircase_predictions(stair, dt, NOMINAL, {}, NOISE, QUANTUM, error)
    bare = staircase_predictions(stair, dt, NOMINAL, {}, NOISE, QUANTUM)
    within = _recorded(stair, dt, 0.015)
    assert _levels_kept(compare(pred, within)).all()
    # the same recording breaks the bands without the model error: the term is what keeps it
    assert not _levels_kept(compare(bare, within)).any()


def test_a_level_shifted_by_clearly_more_than_the_model_error_is_broken(session):
    dt, stair, _ = session
    error = _error("level", 0.01)
    pred = staircase_predictions(stair, dt, NOMINAL, {}, NOISE, QUANTUM, error)
    table = compare(pred, _recorded(stair, dt, 0.04))
    assert not _levels_kept(table).any()
    levels = table[table["prediction"].str.startswith("level")]
    assert levels["verdict"].str.startswith("broken by +").all()


def test_the_sines_bands_hold_their_model_error(session):
    dt, _, sine = session
    error = _error("sine_mean", 0.01)
    pred = sine_predictions(sine, dt, NOMINAL, {}, NOISE, QUANTUM, error)
    kept = compare_sine(pred, _recorded(sine, dt, 0.015))
    broken = compare_sine(pred, _recorded(sine, dt, 0.04))
    assert kept.set_index("prediction").loc["sine mean bar", "verdict"] == "kept"
    assert broken.set_index("prediction").loc["sine mean bar", "verdict"].startswith("broken by +")


def test_the_error_is_measured_on_the_recorded_runs(session):
    dt, stair, sine = session
    runs = {"st": _recorded(stair, dt, 0.012), "si": _recorded(sine, dt, -0.007)}
    metas = {"st": {"kind": "staircase"}, "si": {"kind": "sine"}}
    err = recorded_model_error(runs, metas, NOMINAL)
    assert err["level"]["sd"] == pytest.approx(0.012, abs=1e-4)
    assert err["level"]["largest"] == pytest.approx(0.012, abs=1e-4)
    assert err["sine_mean"]["sd"] == pytest.approx(0.007, abs=1e-4)
    assert err["sine_amplitude"]["sd"] < 1e-3  # a shift leaves the fundamental alone
    assert err["fit"]["sd"] < 0.05  # and the levels' straightness
    assert "1 staircase(s) and 1 sine(s)" in err["measured_on"]
    # one staircase's levels share one bias: its four levels count as one, dof floored at 1
    assert err["level"]["n"] == 4 and err["level"]["dof"] == pytest.approx(3.0)
    # the valve that made them has no error on them
    exact = recorded_model_error({"st": _recorded(stair, dt, 0.0)}, metas, NOMINAL)
    assert exact["level"]["sd"] < 1e-9
    # held out, the error is the factor times larger
    scaled = recorded_model_error(runs, metas, NOMINAL, factor=1.5)
    assert scaled["level"]["sd"] == pytest.approx(1.5 * err["level"]["sd"], rel=1e-9)


def test_the_noises_share_of_the_recorded_error_is_taken_out(session):
    dt, stair, _ = session
    rng = np.random.default_rng(3)
    noisy = _recorded(stair, dt, 0.0)
    noisy["p"] += rng.normal(0.0, 0.05, len(noisy))  # 50 mbar noise, no model error
    metas = {"st": {"kind": "staircase"}}
    naive = recorded_model_error({"st": noisy}, metas, NOMINAL)
    told = recorded_model_error({"st": noisy}, metas, NOMINAL, noise=0.05)
    # each level's mean carries 50/sqrt(1400) = 1.3 mbar of noise: the naive sd holds it,
    # the told one takes it out (to well under the noise's own share)
    assert naive["level"]["sd"] > 5e-4
    assert told["level"]["sd"] < 0.6 * naive["level"]["sd"]


def test_the_verified_settings_own_runs_measure_its_error(session):
    dt, stair, _ = session
    runs = {"a": _recorded(stair, dt, 0.012), "b": _recorded(stair, dt, 0.003)}
    metas = {
        "a": {"kind": "staircase", "modulator": {"type": "pwm", "f_w": 20.0}},
        "b": {"kind": "staircase", "modulator": {"type": "pwm", "f_w": 40.0}},
    }
    label_b = Modulator.from_mapping({"type": "pwm", "f_w": 40.0}).label
    own = recorded_model_error(runs, metas, NOMINAL, setting=label_b)
    assert own["level"]["sd"] == pytest.approx(0.003, abs=1e-4) and not own["extrapolated"]
    # a setting nobody recorded takes the worst recorded setting's error, and says so
    far = recorded_model_error(runs, metas, NOMINAL, setting="pwm-90Hz")
    assert far["extrapolated"] and far["level"]["sd"] == pytest.approx(0.012, abs=1e-4)
    assert "pwm-90Hz was not recorded" in far["measured_on"]


def test_a_run_without_the_command_is_named():
    run = pd.DataFrame({"t": [0.0, 0.1], "p": [0.0, 0.1]})
    with pytest.raises(
        ValueError, match=r"run 'x' \(staircase\) has no column\(s\) \['u', 'valve'\]"
    ):
        recorded_model_error({"x": run}, {"x": {"kind": "staircase"}}, NOMINAL)


def test_no_runs_means_no_error_and_says_so():
    err = no_model_error("no run tables in results/x/runs")
    assert err["level"]["sd"] == 0.0 and err["measured_on"].startswith("not measured")


def test_sine_omega_finds_the_frequency():
    t = np.arange(15000) * 0.002
    assert sine_omega(t, 0.5 + 0.3 * np.sin(2.7 * t)) == pytest.approx(2.7, rel=2e-3)


def test_the_box_corners_keep_the_valves_laws(session):
    dt, stair, _ = session
    laws = Laws(
        log_g=(0.3, 0.1, -0.1, -0.3), log_h=(0.2, 0.0, 0.0, -0.2), m=0.6, knots=DEFAULT_KNOTS
    )
    valve = ValveParams(laws=laws)
    box = {"tau2": (0.95 * valve.tau2, 1.05 * valve.tau2), "c1": (0.95 * valve.c1, 1.05 * valve.c1)}
    assert all(c.laws == valve.laws for c in corners(valve, box))
    pred = staircase_predictions(stair, dt, valve, box, NOISE, QUANTUM)
    p, lo, hi = (np.asarray(pred[k]) for k in ("p", "lo", "hi"))
    assert ((lo <= p) & (p <= hi)).all()  # the estimate lies inside its own band


def test_the_plan_measures_the_error_on_results_runs(session, tmp_path):
    from spa.datasets.runtable import write_run_table
    from spa.plan.verify_command import _model_error

    dt, stair, _ = session
    results = tmp_path / "results" / "bench"
    said = _model_error(results, NOMINAL)
    assert said["level"]["sd"] == 0.0 and "not measured: no run tables" in said["measured_on"]
    (results / "runs").mkdir(parents=True)
    assert "not measured: no run tables" in _model_error(results, NOMINAL)["measured_on"]
    meta = {
        "dataset": "bench",
        "run": "st",
        "kind": "staircase",
        "origin": "bench",
        "modulator": {"type": "pwm", "f_w": 20.0},
    }
    write_run_table(results / "runs" / "st.parquet", _recorded(stair, dt, 0.009), meta)
    err = _model_error(results, NOMINAL)
    assert err["level"]["sd"] == pytest.approx(0.009, abs=1e-4)
    assert str(results / "runs") in err["measured_on"]


#: A valve whose levels settle within the first quarter of a 3 s level.
FAST = ValveParams(tau2=0.2)


def _ripple_run(scale: float, shift: float = 0.0, f_w: float = 20.0):
    from spa.model.plant import simulate

    dt = 0.002
    u = np.repeat([0.2, 0.35, 0.5, 0.65], 1500)
    period = round(1.0 / (f_w * dt))
    valve = (np.arange(u.size) % period < period * u).astype(np.int8)
    model = simulate(valve, dt, FAST)
    # the mean over the last period (causal: no level's last quarter sees the next level)
    mean = np.convolve(model, np.ones(period) / period)[: model.size]
    p = mean + scale * (model - mean) + shift  # the ripple about the cycle mean scaled
    run = pd.DataFrame({"t": np.arange(u.size) * dt, "p": p, "valve": valve, "u": u})
    meta = {"kind": "staircase", "modulator": {"type": "pwm", "f_w": f_w}}
    return run, meta


def test_the_ripple_error_is_the_ratio_of_recorded_to_replayed_ripple():
    from spa.plan.loop_error import ripple_error

    run, meta = _ripple_run(0.7)
    err = ripple_error({"s": run}, {"s": meta}, FAST, "pwm-20Hz")
    assert err["n"] == 4
    assert err["factor"] == pytest.approx(0.7, rel=0.05)
    # a level error alone leaves the ripple's ratio at 1
    run, meta = _ripple_run(1.0, shift=0.02)
    assert ripple_error({"s": run}, {"s": meta}, FAST, "pwm-20Hz")["factor"] == pytest.approx(
        1.0, abs=0.01
    )


def test_the_ripple_error_is_measured_on_the_loops_own_setting_only():
    from spa.plan.loop_error import RIPPLE_MIN_LEVELS, ripple_error

    run, meta = _ripple_run(0.7, f_w=10.0)
    err = ripple_error({"s": run}, {"s": meta}, FAST, "pwm-20Hz")
    assert err["n"] == 0 and "factor" not in err
    short = run.iloc[: 1500 * (RIPPLE_MIN_LEVELS - 1)]
    err = ripple_error({"s": short}, {"s": meta}, FAST, "pwm-10Hz")
    assert err["n"] == RIPPLE_MIN_LEVELS - 1 and "factor" not in err


def test_the_ripple_band_moves_with_the_factor_and_widens_with_its_spread():
    from spa.plan.loop_bands import with_model_error

    band = {"value": 0.03, "sd": 0.001, "dof": 47.0, "scale": 1.0, "lo": 0.028, "hi": 0.032}
    exact = with_model_error(band, {"n": 12, "factor": 1.0, "log_sd": 0.0, "dof": 11.0})
    assert exact["value"] == band["value"]
    assert exact["hi"] - exact["lo"] == pytest.approx(band["hi"] - band["lo"], rel=0.01)
    spread = with_model_error(band, {"n": 12, "factor": 0.7, "log_sd": 0.1, "dof": 11.0})
    assert spread["value"] == pytest.approx(0.021)
    assert spread["hi"] - spread["lo"] > 1.5 * 0.7 * (band["hi"] - band["lo"])
    assert spread["model_error"]["applied"]


def _settling_run(slower: float, f_w: float = 20.0):
    """An open-loop PWM staircase up and down, 8 s a level, on a valve whose charge and
    discharge are ``slower`` times the nominal's."""
    import dataclasses

    from spa.model.plant import simulate

    dt = 0.002
    u = np.repeat([0.2, 0.4, 0.6, 0.8, 0.6, 0.4, 0.2], 4000)
    period = round(1.0 / (f_w * dt))
    valve = (np.arange(u.size) % period < period * u).astype(np.int8)
    plant = dataclasses.replace(NOMINAL, c1=NOMINAL.c1 * slower, tau2=NOMINAL.tau2 * slower)
    run = pd.DataFrame({"t": np.arange(u.size) * dt, "p": simulate(valve, dt, plant)})
    run["valve"], run["u"] = valve, u
    return run, {"kind": "staircase", "modulator": {"type": "pwm", "f_w": f_w}}


def test_the_settling_error_is_the_ratio_of_recorded_to_replayed_settling():
    from spa.plan.loop_error import settling_error

    run, meta = _settling_run(1.0)
    same = settling_error({"s": run}, {"s": meta}, NOMINAL, "pwm-20Hz", noise=0.003, seed=1)
    assert same["n"] == 6
    assert same["factor"] == pytest.approx(1.0, abs=0.05)
    run, meta = _settling_run(1.4)
    slow = settling_error({"s": run}, {"s": meta}, NOMINAL, "pwm-20Hz", noise=0.003, seed=1)
    assert slow["n"] == 6
    assert 1.25 < slow["factor"] < 1.5  # a plant 40 % slower settles about that much later
    # another setting's staircases do not count
    assert settling_error({"s": run}, {"s": meta}, NOMINAL, "pwm-10Hz")["n"] == 0


def test_a_step_within_the_noise_or_unsettled_is_not_compared():
    from spa.plan.loop_error import settling_error

    run, meta = _settling_run(1.0)
    # levels that barely move: every step under min_step of the range but the largest
    err = settling_error({"s": run}, {"s": meta}, NOMINAL, "pwm-20Hz", min_step=0.9)
    assert err["n"] == 0 and "factor" not in err
    # 1 s levels: no step settles before its last quarter
    short = run.iloc[::8].reset_index(drop=True)
    short["t"] = np.arange(len(short)) * 0.002
    assert settling_error({"s": short}, {"s": meta}, NOMINAL, "pwm-20Hz")["n"] == 0


def test_the_settling_band_takes_the_model_error_and_a_promise_band_does_not():
    from spa.plan.loop_bands import with_model_error

    band = {"value": 0.9, "sd": 0.04, "dof": 47.0, "scale": 1.0, "lo": 0.82, "hi": 0.98}
    error = {"n": 18, "factor": 1.05, "log_sd": 0.17, "dof": 17.0}
    out = with_model_error(band, error)
    assert out["value"] == pytest.approx(0.945)
    # the open loop's 17 % log spread is the band's larger term: over 3x the draws' width
    assert out["hi"] - out["lo"] > 3 * (band["hi"] - band["lo"])
    assert out["lo"] < 0.945 * math.exp(-0.17) and out["hi"] > 0.945 * math.exp(0.17)
    promised = {"value": 0.9, "lo": 0.0, "hi": 1.1, "unit": "s"}  # a promise's worst case
    kept = with_model_error(promised, error)
    assert (kept["lo"], kept["hi"]) == (0.0, 1.1) and not kept["model_error"]["applied"]
