"""The closed loop in the valve's own scale: set-points as fractions of k2, the range every
compared setting holds, what the chosen loop cannot hold, and LPWM inverting the dataset's
valve (not the paper's nominal one)."""

from __future__ import annotations

import numpy as np
import pytest

from spa.closedloop.choice import held_clause
from spa.closedloop.comparison import closed_loop, level_hold, transit_time
from spa.closedloop.design import design_pi
from spa.closedloop.export import controller_header
from spa.closedloop.levels import common_levels, held_range, idle_duty, wanted_levels
from spa.model.modulators import Modulator
from spa.model.params import ValveParams

BIG = ValveParams(c1=0.2, k2=4.0, tau2=1.2, t_on=0.006, t_off=0.012)
QUICK = {
    "step_hold": 1.0,
    "sine": {"offset": 2.0, "amplitude": 0.5, "frequency": 0.5, "duration": 3.0, "skip": 1.0},
    "levels_fraction": [0.2, 0.5, 0.8],
}


@pytest.mark.parametrize("gain", [1.05, 1.15, 1.5])
def test_iipfm_idle_duty_is_the_closed_form(gain):
    # IIPFM at xi = 0 integrates (G - 1) up and 1 down per pulse: open (G - 1)/G of the time
    mod = {"type": "iipfm", "t_l": 0.02, "gain": gain}
    assert idle_duty(mod, ValveParams()) == pytest.approx((gain - 1.0) / gain, rel=1e-9)
    assert idle_duty({"type": "pwm", "f_w": 20.0}, ValveParams()) == 0.0


def test_default_levels_scale_with_k2():
    lv = wanted_levels(None, [0.1, 0.5, 0.8], 4.0)
    assert lv == [0.4, 2.0, 3.2]
    with pytest.raises(ValueError, match="levels_fraction"):
        wanted_levels(None, None, 4.0)


def test_common_levels_keep_what_every_grouped_setting_holds():
    wanted = [0.5, 1.0, 1.5, 2.0, 2.5, 3.0]
    levels, group = common_levels(wanted, {"a": (0.2, 3.6), "b": (1.2, 3.6), "c": None})
    assert group == ["a", "b"] and levels == [1.5, 2.0, 2.5, 3.0]
    # a setting holding far less leaves the group instead of shrinking everyone's range
    levels, group = common_levels(wanted, {"a": (0.2, 3.6), "b": (2.8, 3.6)})
    assert group == ["a"] and levels == wanted


def test_transit_and_hold_follow_the_closed_forms():
    p = ValveParams(c1=0.5, k2=1.0, tau2=1.0)
    assert transit_time([0.25, 0.5], p) == pytest.approx(np.log(0.75 / 0.5))
    assert transit_time([0.6, 0.9], p) == pytest.approx(np.log(0.4 / 0.1))
    # a slow valve gets long levels: at least five closed-loop time constants after the transit
    mod = Modulator.from_mapping({"type": "pwm", "f_w": 10.0})
    slow = ValveParams(c1=2.0, k2=4.0, tau2=6.0, t_on=0.01, t_off=0.02)
    hold = level_hold(mod, slow, [1.0, 2.0, 3.0], 0.2, {"hold": None})
    assert hold >= 6.0 * np.log(2.0 / 1.0) + 5 * 0.2  # the 2 -> 3 bar charge, adjacent levels
    assert level_hold(mod, slow, [1.0, 2.0], 0.2, {"hold": 3.0}) == 3.0


@pytest.fixture(scope="module")
def big():
    return closed_loop(BIG, [{"type": "pwm", "f_w": 20.0}], None, QUICK)


def test_the_staircase_covers_a_big_valve(big):
    # the old absolute default (0.05-0.75 bar) covered 19 % of a 4 bar valve
    levels = big.controllers["levels"]
    assert min(levels) >= 0.15 * BIG.k2 and max(levels) >= 0.7 * BIG.k2
    assert levels == big.controllers["controllers"]["pwm-20Hz"]["levels"]
    lo, hi = big.controllers["held_range"]["pwm-20Hz"]
    assert lo < min(levels) and max(levels) < hi


def test_the_sentence_names_what_iipfm_cannot_hold():
    setting = {"type": "iipfm", "t_l": 0.02, "gain": 1.15}
    valve = ValveParams(c1=1.0, k2=5.5, tau2=1.0, t_on=0.002, t_off=0.01)
    lo, hi = held_range(setting, valve, 0.95)
    assert lo > 0.05 * valve.k2  # it cannot go low: the valve still opens at xi = 0
    text = held_clause(setting, valve, (lo, hi), 0.95)
    assert f"cannot hold below {lo:.3g} bar" in text
    assert "opens the valve 13 % of the time" in text


def test_every_compared_setting_is_judged_on_the_same_levels():
    res = closed_loop(
        ValveParams(),
        [{"type": "pwm", "f_w": 20.0}, {"type": "iipfm", "t_l": 0.02, "gain": 1.15}],
        None,
        {**QUICK, "sine": {**QUICK["sine"], "offset": 0.4, "amplitude": 0.1}},
    )
    ctl = res.controllers
    common = ctl["levels"]
    for label in ctl["compared_on_common_levels"]:
        assert ctl["controllers"][label]["levels"] == common
        lo, hi = ctl["held_range"][label]
        assert lo < min(common) and max(common) < hi


def test_lpwm_in_the_stage_inverts_the_identified_valve(big):
    res = closed_loop(BIG, [{"type": "lpwm", "f_w": 20.0}], None, QUICK)
    entry = res.controllers["controllers"]["lpwm-20Hz"]
    for name in ("c1", "k2", "tau2", "t_on", "t_off"):
        assert entry["setting"][name] == getattr(BIG, name)


def test_header_comment_lists_lpwm_constants():
    mod = Modulator.from_mapping({"type": "lpwm", "f_w": 14.2}).bind(BIG)
    ctrl = design_pi(mod, BIG, levels=[1.0, 2.0, 3.0])["fixed"]
    text = controller_header(mod, ctrl, 1e-3)
    assert "Inverted valve (the identified one): c1 = 0.2, k2 = 4, tau2 = 1.2" in text


def test_a_high_supply_valve_judges_every_setting_on_the_same_pressures():
    # on main, PWM was judged on 0.05-0.75 bar and IIPFM G 1.15 on its own 1.6-4.8 bar
    valve = ValveParams(c1=1.0, k2=5.5, tau2=1.0, t_on=0.002, t_off=0.01)
    settings = [{"type": "pwm", "f_w": 20.0}, {"type": "iipfm", "t_l": 0.02, "gain": 1.15}]
    cfg = {**QUICK, "sine": {**QUICK["sine"], "offset": 2.5, "amplitude": 0.5}}
    res = closed_loop(valve, settings, None, cfg)
    ctl = res.controllers
    pwm, iipfm = (ctl["controllers"][k]["levels"] for k in ("pwm-20Hz", "iipfm-20ms-G1.15"))
    assert pwm == iipfm == ctl["levels"]
    assert min(pwm) > ctl["held_range"]["iipfm-20ms-G1.15"][0]  # IIPFM cannot go lower
    # judged on the same pressures, the setting that holds the low levels is the one used
    held = ctl["held_range"]
    assert held["pwm-20Hz"][0] < held["iipfm-20ms-G1.15"][0]
    assert ctl["setting"]["type"] == "pwm"
