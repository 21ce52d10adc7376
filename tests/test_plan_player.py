"""The plan's player: its header and host harness build under strict C99, it issues exactly
the commands spa's simulation of the plan issues, it reads before it commands, it vents
above the rated maximum, and spa record flags what the stream lost. A missing C compiler
fails these tests (the player is what a lab flashes)."""

from __future__ import annotations

import subprocess

import numpy as np
import pytest
import yaml

from spa import simulate
from spa.model.modulators import Modulator
from spa.model.params import ValveParams
from spa.plan.design import design_session
from spa.plan.folder import calibration_for, write_plan
from spa.plan.host import STRICT, build_harness, counts, planned_commands, play_session
from spa.plan.limits import Limits, PlanError
from spa.plan.record import parse_stream, record_stream
from spa.plan.session import Q15, run_xi

NOMINAL = ValveParams()


@pytest.fixture(scope="module")
def session(tmp_path_factory):
    """A full plan (every setting, lpwm recommended) on the nominal valve, played on it."""
    root = tmp_path_factory.mktemp("plan")
    rec = Modulator.from_mapping({"type": "lpwm", "f_w": 25.0}).bind(NOMINAL)
    design = design_session(NOMINAL, Limits(p_max=1.0), levels=3, recommended=rec, seed=3)
    folder = root / "nominal"
    write_plan(folder, design)
    exe = build_harness(folder, root / "player")
    cal = calibration_for(1.0)
    noise = np.random.default_rng(0).normal(0.0, 0.003, planned_commands(design).size)
    stream, cmds, passes = play_session(
        exe, design, lambda u: simulate(u, design.dt, NOMINAL), cal, noise
    )
    return design, folder, cal, noise, stream, cmds, passes


def test_header_and_harness_build_strict_and_sketch_wraps_the_header(session, tmp_path):
    _, folder, *_ = session
    unit = tmp_path / "only.c"
    unit.write_text('#include "player.h"\nint spa_plan_unused(void) { return 0; }\n')
    res = subprocess.run(
        ["cc", *STRICT, f"-I{folder / 'player'}", "-c", str(unit), "-o", str(tmp_path / "o.o")],
        capture_output=True,
        text=True,
        check=False,
    )
    assert res.returncode == 0, res.stderr
    sketch = (folder / "player" / "player.ino").read_text()
    assert '#include "player.h"' in sketch
    assert (
        sketch.index("analogRead")
        < sketch.index("spa_plan_tick")
        < sketch.index("digitalWrite(VALVE_PIN, valve")
    )
    header = (folder / "player" / "player.h").read_text()
    assert "typedef float spa_real;" in header and "_mod_step" in header


def test_player_issues_exactly_the_simulated_commands(session):
    design, _, _, _, stream, cmds, passes = session
    planned = planned_commands(design)
    assert passes == 1  # no vent: the player never departed from its plan
    assert cmds.size == planned.size and int(np.count_nonzero(cmds != planned)) == 0
    caps = parse_stream(stream.splitlines())
    for i, run in enumerate(design.runs):
        xi = run_xi(run)
        if xi is None:
            continue
        logged = np.array([row[3] for row in caps[i].rows]) / Q15
        assert np.array_equal(logged, xi[run.logged()]), run.id


def test_player_reads_then_commands(session):
    design, _, cal, noise, stream, cmds, _ = session
    p = simulate(cmds, design.dt, NOMINAL)
    adc = counts(p + noise, cal)
    rest = round(design.rest / design.dt)
    start = 0
    caps = parse_stream(stream.splitlines())
    for i, run in enumerate(design.runs[:4]):
        rows = np.array(caps[i].rows)
        ticks = np.flatnonzero(run.logged()) + start
        # the count printed at tick k is the pressure at t_k, before command k took effect
        assert np.array_equal(rows[:, 1], adc[ticks]), run.id
        assert np.array_equal(rows[:, 2], cmds[ticks]), run.id
        start += run.ticks + rest
    plan = yaml.safe_load((session[1] / "plan.yaml").read_text())
    order = plan["tick_order"]
    assert order.index("read pressure") < order.index("write valve")


def test_player_vents_above_the_rated_maximum_on_the_physical_plant(tmp_path):
    from spa.synthetic.physical import PhysicalPlant, run_plant_in_c

    plant = PhysicalPlant(supply=1.5)  # the regulator set above the actuator's rating
    limits = Limits(p_max=1.0)
    design = design_session(NOMINAL, limits, pilot=True, replicates=3, precondition=1)
    write_plan(tmp_path / "vent", design)
    exe = build_harness(tmp_path / "vent", tmp_path / "player")
    cal = calibration_for(1.0)
    stream, cmds, passes = play_session(
        exe, design, lambda u: run_plant_in_c(plant, u, design.dt)[1], cal
    )
    caps = parse_stream(stream.splitlines())
    vented = [design.runs[i].id for i, c in caps.items() if c.end == "vent"]
    assert "charge-start1" in vented and "zero" not in vented
    limit = counts(1.0, cal)
    above = []
    for i, cap in caps.items():
        rows = np.array(cap.rows)
        over = np.flatnonzero(rows[:, 1] > limit)
        if over.size:  # from the first count above the maximum, the valve exhausts
            above.append(design.runs[i].id)
            assert np.all(rows[over[0] :, 2] == 0), design.runs[i].id
    assert "charge-start1" in above, "the vented charge goes above the maximum"
    assert passes >= 2 and np.count_nonzero(cmds != planned_commands(design)) > 0
    report = record_stream(tmp_path / "vent", stream.splitlines())
    assert any("charge-start1" in line and "VENTED" in line for line in report)


def test_record_flags_dropped_lines_and_refuses_to_overwrite(tmp_path):
    design = design_session(NOMINAL, Limits(p_max=1.0), pilot=True, precondition=0)
    folder = tmp_path / "drop"
    write_plan(folder, design)
    exe = build_harness(folder, tmp_path / "player")
    stream, _, _ = play_session(
        exe, design, lambda u: simulate(u, design.dt, NOMINAL), calibration_for(1.0)
    )
    lines = stream.splitlines()
    start = lines.index("R 1")
    del lines[start + 100 : start + 103]  # three lines of charge-start1 lost
    lines.insert(start + 200, "O 2")  # the board reports a tick two steps late
    report = record_stream(folder, lines)
    line = next(x for x in report if "charge-start1" in x)
    assert (
        "1 jump(s)" in line
        and "1 overrun(s)" in line
        and f"{design.runs[1].logged().sum() - 3} of" in line
    )
    table = np.genfromtxt(folder / "runs" / "charge-start1.csv", delimiter=",", names=True)
    assert np.isclose(np.diff(table["t"]).max(), 4 * design.dt)
    assert all("ok" in x for x in report if "discharge-start1" in x)
    with pytest.raises(PlanError, match="never overwrites"):
        record_stream(folder, lines)


def test_full_plan_records_and_validates_with_no_edit(session, tmp_path):
    from spa.cli import main

    design, folder, _, _, stream, _, _ = session
    report = record_stream(folder, stream.splitlines())
    assert len(report) == len(design.runs) and all(line.endswith("ok") for line in report)
    assert main(["validate", str(folder)]) == 0
    kinds = {r.kind for r in design.runs if r.analysed}
    assert kinds == {"charge", "discharge", "pulse", "staircase", "sine", "chirp"}


def test_cli_record_reads_stdin_and_reports_a_missing_run(tmp_path, monkeypatch, capsys):
    import io as _io

    from spa.cli import main

    design = design_session(NOMINAL, Limits(p_max=1.0), pilot=True, precondition=0)
    folder = tmp_path / "cli"
    write_plan(folder, design)
    exe = build_harness(folder, tmp_path / "player")
    stream, _, _ = play_session(
        exe, design, lambda u: simulate(u, design.dt, NOMINAL), calibration_for(1.0)
    )
    cut = stream[: stream.index("R 9\n")]  # the link lost before the last run
    monkeypatch.setattr("sys.stdin", _io.StringIO(cut))
    code = main(["record", str(folder)])
    out = capsys.readouterr().out
    assert code == 1 and "missing: pulse-start3 (run 9)" in out
    assert (folder / "runs" / "discharge-start3.csv").is_file()
    assert not (folder / "runs" / "pulse-start3.csv").exists()


def test_the_full_player_fits_an_atmega328p(session):
    """The player compiled for the board (avr-gcc, which ``make test`` installs: a missing
    compiler FAILS this test)."""
    import shutil

    from spa.plan.avr import ATMEGA328P, avr_size, sketch_size

    assert shutil.which("avr-gcc"), "avr-gcc is not on the PATH (make test installs gcc-avr)"
    _, folder, *_ = session
    size = avr_size(folder)
    assert size is not None
    # room left for the Arduino core's serial, timer and ADC code (about 3 KB, 200 B of RAM)
    assert size["flash"] <= ATMEGA328P["flash"] - 4096, size
    assert size["ram"] <= ATMEGA328P["ram"] - 512, size
    sketch = sketch_size(folder)  # the .ino as C++ for the board, the core's code aside
    assert sketch is not None and sketch["flash"] <= ATMEGA328P["flash"] - 4096, sketch


def test_a_player_built_under_a_bare_name_runs_from_the_working_folder(
    session, tmp_path, monkeypatch
):
    """``build_harness(folder, "harness")`` then ``play_session("harness", ...)`` in the working
    folder: the executable is found there, not looked up on PATH (a reader's session on the
    plan page does just this)."""
    design, folder, cal, noise, stream, *_ = session
    monkeypatch.chdir(tmp_path)
    exe = build_harness(folder, "harness")
    assert exe.is_absolute() and exe.parent == tmp_path.resolve()
    plant = lambda u: simulate(u, design.dt, NOMINAL)  # noqa: E731
    again, _, _ = play_session("harness", design, plant, cal, noise)
    assert again == stream
