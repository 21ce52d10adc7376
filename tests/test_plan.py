"""spa plan: the session's design from a prior and the bench's limits, the folder it writes,
and what it refuses."""

from __future__ import annotations

import io

import numpy as np
import pytest
import yaml

from spa.cli import main
from spa.model.modulators import Modulator
from spa.model.params import ValveParams
from spa.plan.design import design_session
from spa.plan.folder import write_plan
from spa.plan.limits import Limits, PlanError, baud_needed, link_check
from spa.plan.prior import prior_from_numbers, scaled
from spa.plan.session import Q15, longest_high, run_commands, run_xi

LIMITS = Limits(p_max=1.0, baud=115200)


def _cli(*argv: str) -> tuple[int, str]:
    buf = io.StringIO()
    import contextlib

    with contextlib.redirect_stdout(buf):
        code = main(list(argv))
    return code, buf.getvalue()


def test_link_refuses_a_line_per_ms_at_115200_and_says_what_fits():
    with pytest.raises(PlanError, match=r"needs 212500 baud.*log every 2 ms"):
        link_check(0.001, Limits(p_max=1.0, baud=115200))
    assert "106250 baud" in link_check(0.002, Limits(p_max=1.0, baud=115200))
    assert baud_needed(0.001) > 115200 >= baud_needed(0.002)


def test_the_link_budget_counts_the_line_ending_println_sends():
    """The longest line the player prints, with Serial.println's CR LF: 17 bytes, 10 bits
    each, at 80 % load."""
    from spa.plan.limits import LINE_BYTES
    from spa.plan.player import player_sketch

    longest = "ffff,fff,1,8000" + "\r\n"
    assert LINE_BYTES == len(longest.encode("ascii")) == 17
    assert baud_needed(0.002) == pytest.approx(17 * 10 / 0.002 / 0.8)
    assert "Serial.println(q, HEX)" in player_sketch("a", 115200)  # the line ends with CR LF
    assert f"availableForWrite() < {LINE_BYTES}" in player_sketch("a", 115200)
    with pytest.raises(PlanError, match="1000 samples/s but the logger takes 500"):
        link_check(0.001, Limits(p_max=1.0, baud=None, samples_per_s=500))


def test_session_has_every_block_in_order_with_the_seed_deciding_the_order():
    design = design_session(ValveParams(), LIMITS, levels=3, seed=7)
    ids = [r.id for r in design.runs]
    assert ids[:2] == ["zero", "precondition"]
    kinds = [r.kind for r in design.runs]
    assert kinds[2:11] == ["charge", "discharge", "pulse"] * 3
    assert kinds[-3:] == ["charge", "discharge", "pulse"] and ids[-1] == "pulse-end"
    labels = {m.label for m in (r.modulator for r in design.runs) if m is not None}
    assert len(labels) == 4  # the paper's four at the valve's scale
    for label in labels:
        for kind in ("staircase-up", "staircase-down", "sine", "chirp"):
            n = sum(r.id.startswith(f"{kind}_{label}_r") for r in design.runs)
            assert n == 3, (label, kind, n)
    middle = [r.id for r in design.runs if r.block == "modulated"]
    again = [
        r.id
        for r in design_session(ValveParams(), LIMITS, levels=3, seed=7).runs
        if r.block == "modulated"
    ]
    other = [
        r.id
        for r in design_session(ValveParams(), LIMITS, levels=3, seed=8).runs
        if r.block == "modulated"
    ]
    assert middle == again and middle != other and sorted(middle) == sorted(other)


def test_levels_are_held_five_time_constants_and_ten_periods():
    design = design_session(ValveParams(), LIMITS, levels=3)
    for label, s in design.settings.items():
        assert s["hold"] >= 5 * s["tau_m_max"] - 1e-9, label
        assert s["hold"] >= 10 / s["slowest_rate"] - 1e-9, label
    stair = next(
        r for r in design.runs if r.kind == "staircase" and r.id.startswith("staircase-up")
    )
    xi = run_xi(stair)
    assert xi is not None and xi[0] == 0.0 and xi[-1] == 1.0
    assert np.all(np.diff(xi) >= 0) and np.all(xi * Q15 == np.round(xi * Q15))


def test_chirp_stays_below_half_the_slowest_switching():
    design = design_session(ValveParams(), LIMITS, levels=3, replicates=3)
    for run in design.runs:
        if run.kind != "chirp":
            continue
        seg = run.segments[0]
        top = (seg.c + 2 * seg.d * seg.ticks) / (2 * np.pi * design.dt)
        slowest = design.settings[run.modulator.label]["slowest_rate"]
        assert top < 0.5 * slowest, (run.id, top, slowest)


def test_pulse_lows_bracket_the_delay_of_both_corners():
    prior = ValveParams()
    design = design_session(prior, LIMITS, pilot=True)
    pulse = next(r for r in design.runs if r.kind == "pulse")
    lows = [s.ticks * design.dt for s in pulse.segments[1:-1] if s.a == 0.0]
    assert min(lows) < scaled(prior, 1 / 3).t_off and max(lows) > scaled(prior, 3).t_off


def test_refusals_are_stated():
    with pytest.raises(PlanError, match="above the actuator's rated maximum"):
        design_session(ValveParams(k2=2.0), LIMITS, pilot=True)
    with pytest.raises(PlanError, match="at least 3"):
        design_session(ValveParams(), LIMITS, replicates=2, pilot=True)
    with pytest.raises(
        PlanError, match=r"longer than the coil.s 1 s: precondition \(14.9 s\), charge-start1"
    ):
        design_session(ValveParams(), Limits(p_max=1.0, on_time_max=1.0), pilot=True)
    fast = Modulator.from_mapping({"type": "pwm", "f_w": 50.0})
    slow = Modulator.from_mapping({"type": "pwm", "f_w": 10.0})
    d = design_session(
        ValveParams(), Limits(p_max=1.0, f_switch_max=30.0), levels=3, settings=[fast, slow]
    )
    assert "pwm-50Hz" in d.refused and "30 Hz" in d.refused["pwm-50Hz"]
    assert list(d.settings) == ["pwm-10Hz"]
    beyond = Modulator.from_mapping({"type": "pwm", "f_w": 400.0})  # a period under one tick
    d = design_session(ValveParams(), LIMITS, levels=3, settings=[beyond, slow])
    assert "does not run at the tick 2 ms" in d.refused["pwm-400Hz"]
    assert not any(r.modulator == fast for r in d.runs)


def test_longest_high_and_direct_commands():
    design = design_session(ValveParams(), LIMITS, pilot=True)
    charge = next(r for r in design.runs if r.kind == "charge")
    u = run_commands(charge, design.dt)
    assert longest_high(u) == charge.segments[1].ticks


def test_prior_from_numbers_keeps_the_supply_and_fill_time():
    p = prior_from_numbers(3.0, 4.0)
    assert p.k2 == 3.0 and p.tau2 == pytest.approx(0.8)
    with pytest.raises(PlanError, match="fill_time"):
        prior_from_numbers(1.0, -1.0)


def test_write_plan_refuses_an_existing_folder_and_writes_a_dataset_yaml(tmp_path):
    design = design_session(ValveParams(), LIMITS, levels=3)
    target = tmp_path / "bench"
    paths = write_plan(target, design)
    assert {p.name for p in paths} >= {"plan.yaml", "dataset.yaml", "checklist.md", "player.h"}
    before = {p: p.read_bytes() for p in target.rglob("*") if p.is_file()}
    with pytest.raises(PlanError, match="exists"):
        write_plan(target, design)
    assert before == {p: p.read_bytes() for p in target.rglob("*") if p.is_file()}
    ds = yaml.safe_load((target / "dataset.yaml").read_text())
    assert ds["valve_edges"] == "on_tick" and ds["sample_step"] == design.dt
    assert ds["name"] == "bench"
    analysed = [r for r in design.runs if r.analysed]
    assert [r["id"] for r in ds["runs"]] == [r.id for r in analysed]
    plan = yaml.safe_load((target / "plan.yaml").read_text())
    assert plan["seed"] == design.seed and plan["tick_order"][0] == "read pressure"
    assert plan["tick_order"].index("read pressure") < plan["tick_order"].index("write valve")
    check = (target / "checklist.md").read_text().splitlines()
    assert len(check) <= 24 and max(map(len, check)) <= 80
    assert any("Regulator" in line and "no higher than" in line for line in check)


def test_cli_plan_help_fits_one_screen(capsys, monkeypatch):
    monkeypatch.setenv("COLUMNS", "80")
    code = main(["plan", "--help"])
    text = capsys.readouterr().out.splitlines()
    assert code == 0 and len(text) <= 24, "\n".join(text)
    assert max(map(len, text)) <= 80 and "--verify RESULTS" in text[0]


def test_cli_plan_refuses_a_link_and_an_existing_folder(tmp_path):
    code, out = _cli(
        "plan", str(tmp_path / "a"), "--p-max", "1", "--tick", "0.001", "--pilot", "--no-predict"
    )
    assert code == 1 and "needs 212500 baud" in out and not (tmp_path / "a").exists()
    code, out = _cli("plan", str(tmp_path), "--p-max", "1", "--pilot", "--no-predict")
    assert code == 1 and "exists" in out
    code, out = _cli(
        "plan", str(tmp_path / "b"), "--p-max", "3", "--supply", "2,x", "--pilot", "--no-predict"
    )
    assert code == 1 and "expected BAR,S" in out


def test_cli_plan_pilot_from_numbers(tmp_path):
    code, out = _cli(
        "plan", str(tmp_path / "p"), "--p-max", "3", "--supply", "2,1.5", "--pilot", "--no-predict"
    )
    assert code == 0, out
    plan = yaml.safe_load((tmp_path / "p" / "plan.yaml").read_text())
    assert plan["stage"] == "pilot" and plan["prior"]["k2"] == 2.0
    assert "re-plan" in (tmp_path / "p" / "checklist.md").read_text().lower()
