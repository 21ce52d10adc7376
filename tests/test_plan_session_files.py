"""A planned session's folder as spa writes it and a lab runs it: the files spa wrote are
spa's (validation passes over them), the session is dated when planned and when recorded
(the overview orders sessions by that, not by name), the checklist says what a gauge shows,
a budget bounds the bench time, and a plan that misses its own precision targets says so in
its exit status."""

from __future__ import annotations

import contextlib
import io
from pathlib import Path

import pytest
import yaml

from spa.cli import main
from spa.datasets import load_spec, validate_dataset
from spa.model.params import ValveParams
from spa.plan.design import design_session
from spa.plan.folder import calibration_for, checklist, write_plan
from spa.plan.limits import Limits
from spa.plan.prior import prior_from_numbers
from spa.report.overview import overview_table

LIMITS = Limits(p_max=2.0, baud=115200)


def _cli(*argv: str) -> tuple[int, str]:
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        code = main(list(argv))
    return code, buf.getvalue()


def _pilot(folder: Path, **kw) -> None:
    design = design_session(prior_from_numbers(1.5, 2.0), LIMITS, pilot=True, precondition=0)
    write_plan(folder, design, **kw)


def test_validation_passes_over_the_files_spa_wrote_but_not_a_labs_own(tmp_path):
    folder = tmp_path / "pilot"
    _pilot(folder)
    (folder / "verification.csv").write_text("x\n1\n")  # spa record's, for a verification
    warnings = [p for p in validate_dataset(folder) if p.level == "warning"]
    assert not any("no run names" in p.message for p in warnings), warnings
    (folder / "notes.txt").write_text("the lab's own\n")
    (folder / "player" / "wiring.jpg").write_bytes(b"\0")  # inside player/: spa's folder
    stray = [p.message for p in validate_dataset(folder) if "no run names" in p.message]
    assert len(stray) == 1 and "notes.txt" in stray[0] and "wiring" not in stray[0]


def test_a_folder_without_a_plan_still_names_every_unnamed_file(tmp_path):
    folder = tmp_path / "pilot"
    _pilot(folder)
    (folder / "plan.yaml").unlink()  # not a planned session: checklist.md is the lab's
    stray = [p.message for p in validate_dataset(folder) if "no run names" in p.message]
    assert stray and "checklist.md" in stray[0] and "player/player.h" in stray[0]


def test_the_checklist_gives_the_regulator_as_a_gauge_shows_it():
    prior = ValveParams(c1=0.5, k2=1.49979, tau2=0.4, t_on=0.004, t_off=0.01)
    design = design_session(prior, LIMITS, pilot=True, precondition=0)
    text = checklist(design, "s", calibration_for(LIMITS.p_max))
    assert "Regulator at 1.50 bar" in text and "1.49979" not in text


def test_a_plan_is_dated_and_a_recording_dates_its_dataset(tmp_path):
    from spa import simulate
    from spa.plan.host import build_harness, play_session
    from spa.plan.record import record_stream

    folder = tmp_path / "pilot"
    design = design_session(prior_from_numbers(1.5, 2.0), LIMITS, pilot=True, precondition=0)
    write_plan(folder, design, planned="2026-12-01T09:30+00:00")
    plan = yaml.safe_load((folder / "plan.yaml").read_text())
    assert plan["planned"] == "2026-12-01T09:30+00:00"
    assert "recorded:" not in (folder / "dataset.yaml").read_text()  # planned, not yet recorded
    exe = build_harness(folder, tmp_path / "player")
    valve = ValveParams(c1=0.5, k2=1.5, tau2=0.4, t_on=0.004, t_off=0.01)
    stream, _, _ = play_session(
        exe, design, lambda u: simulate(u, design.dt, valve), calibration_for(2.0)
    )
    before = (folder / "dataset.yaml").read_text()
    record_stream(folder, stream.splitlines(), recorded="2026-12-02T10:05+00:00")
    after = (folder / "dataset.yaml").read_text()
    assert load_spec(folder).recorded == "2026-12-02T10:05"
    added = [line for line in after.splitlines() if line not in before.splitlines()]
    assert added == ["recorded: '2026-12-02T10:05+00:00'"]  # every other line kept
    assert not [p for p in validate_dataset(folder) if p.level == "error"]


def test_the_overview_orders_one_days_sessions_by_time_not_by_name():
    rows = []
    for name, when in (("verify", "2026-12-02T16:00"), ("pilot", "2026-12-02T09:00"),
                       ("full", "2026-12-02T11:30")):  # fmt: skip
        row = {"dataset": name, "recorded": when, "rig": "bench A", "status": "ok"}
        for p in ("c1", "k2", "tau2", "t_on", "t_off"):
            row |= {p: 1.0, f"{p}_lo": 0.9, f"{p}_hi": 1.1}
        rows.append(row)
    rows.append({**rows[0], "dataset": "old", "recorded": "2026-11-30"})
    table = overview_table(rows)
    assert table["dataset"].tolist() == ["old", "pilot", "full", "verify"]
    assert table["session"].tolist() == [1, 2, 3, 4]
    assert not table[[c for c in table if c.startswith("changed_")]].to_numpy().any()


def test_a_budget_bounds_the_bench_time_and_says_what_it_gave_up(tmp_path):
    code, out = _cli("plan", str(tmp_path / "full"), "--supply", "1.5,2", "--p-max", "2",
                     "--budget", "30min", "--no-predict")  # fmt: skip
    assert code == 0, out
    plan = yaml.safe_load((tmp_path / "full" / "plan.yaml").read_text())
    assert plan["duration_s"] <= 30 * 60
    assert plan["budget"]["seconds"] == 1800 and plan["budget"]["given_up"]
    assert "budget 30 min:" in out and "instead of 11" in out
    unbounded = design_session(prior_from_numbers(1.5, 2.0), LIMITS)
    assert unbounded.duration > 30 * 60  # the budget did cut something


def test_a_budget_too_small_for_any_plan_is_refused_with_the_smallest(tmp_path):
    code, out = _cli("plan", str(tmp_path / "b"), "--supply", "1.5,2", "--p-max", "2",
                     "--budget", "2min", "--no-predict")  # fmt: skip
    assert code == 1 and "the smallest plan" in out and not (tmp_path / "b").exists()
    code, out = _cli("plan", str(tmp_path / "c"), "--p-max", "2", "--budget", "soon")
    assert code == 1 and "expected a duration" in out


def test_a_plan_that_misses_its_targets_exits_3_unless_told_to_warn(tmp_path, monkeypatch):
    import spa.plan.precision as precision

    real = precision.predict_precision

    def missing(design, cal):
        table = real(design, cal)
        return table.assign(met=[False] + [True] * (len(table) - 1))

    monkeypatch.setattr(precision, "predict_precision", missing)
    monkeypatch.setattr(precision.size_for_targets, "__defaults__", (0,))  # no resize
    args = ("--supply", "1.5,2", "--p-max", "2", "--pilot")
    code, out = _cli("plan", str(tmp_path / "a"), *args)
    assert code == 3 and "MISSED" in out and "error: the plan misses 1" in out
    assert (tmp_path / "a" / "plan.yaml").is_file()  # written all the same
    code, out = _cli("plan", str(tmp_path / "b"), *args, "--missed-ok")
    assert code == 0 and "warning: the plan misses 1" in out


def test_the_plan_help_still_fits_one_screen_with_the_budget(capsys, monkeypatch):
    monkeypatch.setenv("COLUMNS", "80")
    assert main(["plan", "--help"]) == 0
    text = capsys.readouterr().out.splitlines()
    assert len(text) <= 24 and "--budget TIME" in "\n".join(text) and "--missed-ok" in text[-1]


def test_a_full_session_records_the_recommended_setting_and_its_neighbours():
    from spa.plan.design import NEIGHBOURS, default_settings, neighbour_settings
    from spa.tuning.cost import setting

    prior = prior_from_numbers(1.5, 2.0)
    rec = setting("lpwm", 30.0, prior)
    near = neighbour_settings(rec, prior, 0.002)
    assert [m.kind for m in near] == ["lpwm", "lpwm"]
    values = sorted(float(m.settings["f_w"]) for m in near)
    assert values == [pytest.approx(30.0 * f, rel=2e-3) for f in NEIGHBOURS]
    design = design_session(prior, LIMITS, recommended=rec)
    labels = list(design.settings)
    assert labels[:3] == [rec.label, *(m.label for m in near)]
    assert len(labels) == len(default_settings(prior, 0.002, rec))
    # at the tick's limit a neighbour is clipped, never faster than a tenth of 1/dt
    fast = neighbour_settings(setting("lpwm", 45.0, prior), prior, 0.002)
    assert max(float(m.settings["f_w"]) for m in fast) <= 50.0
