"""The valve pulses a loop asks for, against those the bench recorded
(``spa.closedloop.pulses``): a promise whose loop pulses the valve shorter than the records
ever did is the model's extrapolation and is not verified; the stage designs the settings
the bench ran, so that a loop within the records can be shipped."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from spa.closedloop.bench import bench_outputs
from spa.closedloop.comparison import closed_loop
from spa.closedloop.controller import PIController
from spa.closedloop.pulses import (
    FLOOR_QUANTILE,
    MIN_POOLED,
    UNCOVERED_SHARE,
    RecordedPulses,
    loop_pulses,
    pulse_clause,
    recorded_settings,
    valve_durations,
)
from spa.model.modulators import Modulator, modulate
from spa.model.params import ValveParams

DT = 1e-3
ONE = {
    "levels": [0.2, 0.5],
    "step_hold": 1.0,
    "sine": {"offset": 0.35, "amplitude": 0.1, "frequency": 0.5, "duration": 3.0, "skip": 1.0},
}


def _pwm_run(duty: float, f_w: float = 20.0, seconds: float = 2.0) -> pd.DataFrame:
    t = np.arange(round(seconds / DT)) * DT
    u = modulate("pwm", np.full(t.size, duty), DT, f_w=f_w)
    return pd.DataFrame({"t": t, "p": 0.0, "valve": u, "xi": duty})


def test_a_pwm_commands_open_and_closed_times_are_its_duty_and_the_rest_of_its_period():
    run = _pwm_run(0.3)
    opened, closed = valve_durations(run["t"], run["valve"])
    assert opened.size >= 38 and closed.size >= 38
    np.testing.assert_allclose(opened, 0.015, atol=1e-12)
    np.testing.assert_allclose(closed, 0.035, atol=1e-12)


def test_the_complete_intervals_tile_the_span_between_the_first_and_last_edges():
    rng = np.random.default_rng(5)
    t = np.cumsum(rng.uniform(0.5e-3, 2e-3, 4000))
    v = (rng.random(4000) < 0.3).astype(int)
    opened, closed = valve_durations(t, v)
    edges = np.flatnonzero(np.diff(v) != 0) + 1
    assert opened.size + closed.size == edges.size - 1
    assert np.isclose(opened.sum() + closed.sum(), t[edges[-1]] - t[edges[0]], rtol=1e-12)
    assert np.all(opened > 0) and np.all(closed > 0)


def test_no_edge_or_one_edge_gives_no_interval():
    for v in ([0, 0, 0], [0, 1, 1], [1]):
        o, c = valve_durations(np.arange(len(v), dtype=float), v)
        assert o.size == 0 and c.size == 0


def test_the_records_floor_is_a_low_quantile_of_many_pulses_and_the_shortest_of_few():
    many = {
        "a": _pwm_run(0.3, seconds=4.0),
        "b": _pwm_run(0.6, seconds=4.0),
        "charge": pd.DataFrame({"t": [0.0]}),
    }
    rec = RecordedPulses.from_runs(many)
    assert rec.n_open >= MIN_POOLED
    pooled = np.concatenate(
        [valve_durations(r["t"], r["valve"])[0] for r in (many["a"], many["b"])]
    )
    assert rec.open_floor == pytest.approx(np.quantile(pooled, FLOOR_QUANTILE))
    few = RecordedPulses.from_runs([_pwm_run(0.3, seconds=0.2)])
    assert few.n_open < MIN_POOLED and few.open_floor == pytest.approx(0.015)
    none = RecordedPulses.from_runs({"charge": pd.DataFrame({"t": [0.0, 1.0], "valve": [1, 1]})})
    assert none.open_floor is None and none.closed_floor is None


def test_a_loop_is_outside_the_records_past_a_share_of_its_pulses_either_way():
    rec = RecordedPulses(open_floor=0.010, closed_floor=0.010)
    n = 100
    inside = np.full(n, 0.02)
    short = int(UNCOVERED_SHARE * n)  # exactly the share: still within
    edge = np.r_[np.full(short, 0.005), np.full(n - short, 0.02)]
    past = np.r_[np.full(short + 1, 0.005), np.full(n - short - 1, 0.02)]
    assert pulse_clause(inside, inside, rec) == ""
    assert pulse_clause(edge, inside, rec) == ""
    said = pulse_clause(past, inside, rec)
    assert said.startswith("its valve's open times on the model")
    both = pulse_clause(past, past, rec)
    assert both.startswith("its valve's open and closed times")
    assert "open ≥ 10 ms" in both and "record a staircase" in both
    assert pulse_clause(inside, inside, None) == ""
    # a bench with no pulse recorded covers no loop
    assert "no pulses" in pulse_clause(inside, inside, RecordedPulses(None, None))


def test_a_loops_pulses_on_the_model_are_its_modulators():
    ctrl = PIController(kp=2.0, ki=5.0)
    o, c = loop_pulses({"type": "iipfm", "t_l": 0.02}, ctrl, ValveParams(), [0.3, 0.5], 1.0, DT)
    # IIPFM's low pulses last t_l (two back to back when the integrator fires again)
    assert np.median(c) == pytest.approx(0.02) and np.all(c >= 0.02 - 1e-9)
    assert o.size > 10 and np.all(o > 0)


@pytest.fixture(scope="module")
def one():
    return closed_loop(ValveParams(), [{"type": "iipfm", "t_l": 0.02, "gain": 1.15}], None, ONE)


def test_a_promise_on_pulses_shorter_than_the_records_is_not_verified(one):
    plain = bench_outputs(one, ValveParams(), None, ONE, 0.004)
    assert plain.summary["promise"]["kept"], plain.sentence
    covered = bench_outputs(
        one, ValveParams(), None, ONE, 0.004, recorded=RecordedPulses(1e-3, 1e-3, 500, 500)
    )
    assert covered.summary["verified"] is plain.summary["verified"]
    assert covered.summary["recorded_pulses"]["open_floor"] == 1e-3
    long_only = RecordedPulses(0.05, 0.05, 500, 500)  # a bench that only ran 50 ms pulses
    outside = bench_outputs(one, ValveParams(), None, ONE, 0.004, recorded=long_only)
    assert outside.summary["verified"] is False
    assert outside.summary["promise"]["kept"]  # the model's promise is made, not verified
    assert "are shorter than the bench recorded" in outside.sentence
    assert "Controller unverified" in outside.sentence


def test_the_settings_the_bench_ran_are_named_once_in_run_order():
    slow = Modulator.from_mapping({"type": "pwm", "f_w": 5.0})
    dsm = Modulator.from_mapping({"type": "dsm", "period": 0.05})
    metas = {
        "charge": {"modulator": None},
        "stair_pwm": {"modulator": slow},
        "sine_pwm": {"modulator": {"type": "pwm", "f_w": 5.0}},
        "stair_dsm": {"modulator": dsm},
        "notes": "not a run",
    }
    assert [m.label for m in recorded_settings(metas)] == ["pwm-5Hz", "dsm-50ms"]
