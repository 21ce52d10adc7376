"""The closed_loop stage's bench outputs: robust.csv, the header, controllers.yaml's sentence."""

from __future__ import annotations

import math
import shutil
import subprocess

import numpy as np
import pandas as pd
import pytest
import yaml

from spa.closedloop.bench import (
    NOISE_FALLBACK,
    ROBUST_COLUMNS,
    apply_bench,
    bench_outputs,
    bench_sentence,
    sensor_noise,
)
from spa.closedloop.comparison import ClosedLoopResult, closed_loop
from spa.closedloop.controller import PIController
from spa.closedloop.export import controller_header
from spa.model.modulators import Modulator
from spa.model.params import ValveParams
from spa.stages.closed_loop import write_closed_loop

SELECTED = [{"type": "pwm", "f_w": 20.0}, {"type": "iipfm", "t_l": 0.02, "gain": 1.15}]
CFG = {
    "levels": [0.1, 0.4, 0.7],
    "step_hold": 1.0,
    "sine": {"offset": 0.4, "amplitude": 0.1, "frequency": 0.5, "duration": 4.0, "skip": 1.0},
}
BOX = {"k2": (0.82, 0.85), "tau2": (0.8, 0.85), "c1": (0.52, 0.55)}


@pytest.fixture(scope="module")
def staged():
    result = closed_loop(ValveParams(), SELECTED, None, CFG)
    return result, bench_outputs(result, ValveParams(), BOX, CFG, 0.004)


def test_robust_table_has_a_row_per_setting_and_the_box_on_the_chosen(staged):
    result, bench = staged
    t = bench.robust
    assert list(t.columns) == list(ROBUST_COLUMNS)
    assert set(t.modulator) == set(result.controllers["controllers"])
    assert (t.controller == result.controllers["controller"]).all()
    assert t.chosen.sum() == 1
    chosen = t[t.chosen].iloc[0]
    assert chosen.n_corners == 8 and chosen.tau_c == result.controllers["tau_c"]
    assert (t.noise == 0.004).all() and (t.drop_level == 0.4).all()
    assert t[~t.chosen][["n_corners", "worst_overshoot"]].isna().all().all()
    # the box holds the estimate, so its worst case is at least the nominal table's
    stair = result.table[
        (result.table.experiment == "staircase")
        & (result.table.modulator == chosen.modulator)
        & (result.table.controller == chosen.controller)
    ].set_index("metric")["max"]
    assert chosen.worst_overshoot >= stair["overshoot"]
    assert chosen.worst_rise_time >= stair["rise_time"]
    # within the limit over the box at the stage's tau_c: the robust tau_c is that one
    assert chosen.worst_overshoot <= 10.0
    assert chosen.tau_c_robust == chosen.tau_c


def test_header_is_the_chosen_controller(staged):
    result, bench = staged
    ctl = result.controllers
    mod = Modulator.from_mapping(ctl["setting"])
    ctrl = PIController.from_mapping(ctl["controllers"][mod.label][ctl["controller"]])
    expected = controller_header(mod, ctrl, ctl["dt"])
    assert bench.header[bench.header.index("#ifndef") :] == expected[expected.index("#ifndef") :]
    assert '#include "controller.h"' in bench.sketch


def test_written_files_and_sentence(staged, tmp_path):
    result, bench = staged
    result = ClosedLoopResult(
        result.table, result.steps, result.traces, dict(result.controllers), result.skipped
    )
    before = result.sentence
    apply_bench(result, bench)
    out = {
        k: str(tmp_path / v)
        for k, v in {
            "table": "table.csv",
            "controllers": "controllers.yaml",
            "fig10_csv": "fig10.csv",
            "fig11_csv": "fig11.csv",
            "recorded": "runs.csv",
            "robust": "robust.csv",
            "header": "controller.h",
            "sketch": "controller.ino",
        }.items()
    }
    write_closed_loop(result, pd.DataFrame(), out, bench)
    data = yaml.safe_load((tmp_path / "controllers.yaml").read_text())
    assert data["sentence"].startswith(before) and "95 % box (8 corners)" in data["sentence"]
    assert data["bench"]["n_corners"] == 8
    assert (tmp_path / "controller.h").read_text() == bench.header
    robust = pd.read_csv(tmp_path / "robust.csv")
    assert len(robust) == len(bench.robust)
    if shutil.which("cc"):
        res = subprocess.run(
            ["cc", "-std=c99", "-fsyntax-only", "-Wall", "-Werror", "-Wno-unused-function",
             "-x", "c", str(tmp_path / "controller.h")],
            capture_output=True, text=True, check=False,
        )  # fmt: skip
        assert res.returncode == 0, res.stderr


def test_nothing_designed_gives_an_error_header():
    empty = ClosedLoopResult(pd.DataFrame(), pd.DataFrame(), pd.DataFrame(), {"sentence": "x"})
    bench = bench_outputs(empty, ValveParams(), BOX, CFG)
    assert bench.robust.empty and list(bench.robust.columns) == list(ROBUST_COLUMNS)
    assert bench.header.startswith("#error") and bench.summary == {}
    apply_bench(empty, bench)
    assert empty.controllers == {"sentence": "x"}


def test_sensor_noise_is_the_sensors_and_the_residual_is_only_an_upper_bound():
    """Issue 46: the sensor noise is params.yaml's noise.sensor; the pulse fit's residual
    (model error included) is never called the sensor's noise."""
    both = {"noise": {"sensor": 0.006, "method": "still levels", "upper_bound": False,
                      "model_residual": 0.117},
            "fits": {"pulse": {"rmse": 0.117}}}  # fmt: skip
    measured = sensor_noise(both)
    assert measured.value == 0.006 and measured.source == "measured" and not measured.bound
    assert measured.model_residual == 0.117
    bounded = sensor_noise({"noise": {"sensor": 0.009, "upper_bound": True}})
    assert bounded.value == 0.009 and bounded.bound
    old = sensor_noise({"fits": {"pulse": {"rmse": 0.117}}})  # a params.yaml without noise
    assert old.source == "model_residual" and old.bound and old.value == 0.117
    assert "unknown" in old.words() and "upper bound" in old.words()
    for bad in (None, {}, {"fits": {}}, {"fits": {"pulse": {"rmse": float("nan")}}}):
        assert sensor_noise(bad).value == NOISE_FALLBACK
        assert sensor_noise(bad).source == "assumed"
    assert math.isfinite(NOISE_FALLBACK) and np.isclose(NOISE_FALLBACK, 0.005)


def test_the_sentence_says_what_the_sensor_noise_is(one):
    measured = {"noise": {"sensor": 0.006, "method": "still levels", "upper_bound": False},
                "fits": {"pulse": {"rmse": 0.117}}}  # fmt: skip
    text = bench_outputs(one, ValveParams(), None, ONE, sensor_noise(measured)).sentence
    assert "sensor noise of 6.0 mbar (still levels) adds" in text
    assert "model residual of the pulse fit, 117.0 mbar" in text
    assert "sensor noise of 117.0 mbar" not in text
    bounded = {"noise": {"sensor": 0.009, "method": "second differences", "upper_bound": True}}
    text = bench_outputs(one, ValveParams(), None, ONE, sensor_noise(bounded)).sentence
    assert "sensor noise of at most 9.0 mbar (an upper bound, second differences)" in text
    old = {"fits": {"pulse": {"rmse": 0.117}}}
    bench = bench_outputs(one, ValveParams(), None, ONE, sensor_noise(old))
    assert "sensor noise of 117.0 mbar" not in bench.sentence
    assert "sensor noise unknown" in bench.sentence and "an upper bound of it" in bench.sentence
    assert bench.summary["sensor_noise"]["source"] == "model_residual"


def test_table_csv_holds_the_box_worst_case_and_the_disturbances(staged):
    """Issue 31: table.csv (the long table) carries the worst case over the 95 % box for the
    chosen loop and the supply drop and sensor noise for every designed setting."""
    result, bench = staged
    result = ClosedLoopResult(
        result.table.copy(), result.steps, result.traces, dict(result.controllers), result.skipped
    )
    before = len(result.table)
    apply_bench(result, bench)
    t = result.table
    assert len(t) > before
    chosen = bench.robust[bench.robust.chosen].iloc[0]
    box = t[t.experiment == "box_95"]
    assert set(box.modulator) == {chosen.modulator}
    worst = box[box.metric == "overshoot"]["max"].iloc[0]
    assert worst == pytest.approx(chosen.worst_overshoot)
    drop = t[(t.experiment == "supply_drop") & (t.metric == "dip")]
    assert set(drop.modulator) == set(bench.robust.modulator)
    assert set(t[t.experiment == "sensor_noise"].metric) == {"added_ripple_rms", "added_ripple_pp"}


ONE = {
    "levels": [0.2, 0.4, 0.6],
    "step_hold": 1.0,
    "sine": {"offset": 0.35, "amplitude": 0.1, "frequency": 0.5, "duration": 3.0, "skip": 1.0},
}
INADEQUATE = {
    "threshold": 80.0,
    "noise_ceiling_fit": 97.0,
    "heldout_fit": {"median": 70.0, "per_modulator": {"iipfm": 62.0}},
    "insample_fit": {"median": 90.0, "per_modulator": {"iipfm": 88.0}},
    "worst_run": {"run": "stair_pwm20", "fit": 62.0},
    "adequate": False,
    "measured_modulators": ["iipfm"],
    "sentence": "The model does not describe this valve well enough.",
}


@pytest.fixture(scope="module")
def one():
    return closed_loop(ValveParams(), SELECTED[1:], None, ONE)


def _text_is_clean(text: str) -> None:
    assert "nan" not in text.lower().split() and " nan" not in text and "inf " not in text


def test_adequacy_is_copied_and_an_inadequate_model_is_unverified(one):
    bench = bench_outputs(one, ValveParams(), None, ONE, 0.004, adequacy=INADEQUATE)
    assert bench.summary["adequacy"] == INADEQUATE
    assert bench.summary["verified"] is False
    assert "does not describe this valve well enough" in bench.sentence
    assert "stair_pwm20" in bench.sentence and "unverified" in bench.sentence
    _text_is_clean(bench.sentence)
    res = ClosedLoopResult(one.table.copy(), one.steps, one.traces, dict(one.controllers))
    apply_bench(res, bench)
    assert res.controllers["verified"] is False and res.controllers["adequacy"] == INADEQUATE


def test_unmeasured_modulator_and_unassessed_adequacy(one):
    other = {**INADEQUATE, "adequate": True, "measured_modulators": ["pwm", "dsm"]}
    bench = bench_outputs(one, ValveParams(), None, ONE, 0.004, adequacy=other)
    assert bench.summary["verified"] is False
    assert "not measured with this modulator on this bench" in bench.sentence
    plain = bench_outputs(one, ValveParams(), None, ONE, 0.004)
    assert plain.summary["adequacy"] is None
    assert "adequacy not assessed" in plain.sentence
    assert plain.summary["verified"] is plain.summary["promise"]["kept"]


def test_the_promise_covers_the_measured_model_error(one):
    narrow = bench_outputs(one, ValveParams(), None, ONE, 0.004)
    error = {"k2": (0.7, 0.95), "t_on": (0.001, 0.008)}
    wide = bench_outputs(one, ValveParams(), None, ONE, 0.004, model_error=error)
    assert wide.summary["box"]["k2"] == [0.7, 0.95]
    assert wide.summary["n_corners"] == 4 and narrow.summary["n_corners"] == 0
    assert wide.summary["worst_overshoot"] >= narrow.summary["worst_overshoot"]
    promise = wide.summary["promise"]
    assert promise["kept"], wide.sentence
    # the header ships the loop the promise is about, and the promise meets the limit
    assert promise["overshoot"] <= wide.summary["max_overshoot"]
    assert f"tau_c = {promise['tau_c']:g} s" in wide.header
    assert f"τ_c = {promise['tau_c']:.3g} s" in wide.sentence
    margins = wide.summary["margins"]
    assert margins["gain_margin"] > 1.0 and margins["delay_margin"] > 0.0
    _text_is_clean(wide.sentence)


def test_sentence_never_prints_nan():
    text = bench_sentence({"n_corners": 4, "tau_c": 0.2, "worst_rise_time": None,
                           "worst_overshoot": None, "recovery_time": None, "dip": None,
                           "noise": None, "added_ripple_rms": None, "drop_level": None,
                           "promise": {"kept": True, "tau_c": 0.3, "hold": 2.0,
                                       "overshoot": 4.0, "settling_time": None,
                                       "ripple_pp": 0.01}})  # fmt: skip
    _text_is_clean(text)
    assert "does not reach 90 %" in text and "ripple ≤ 10 mbar" in text
