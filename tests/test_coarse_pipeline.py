"""A hobby controller's log through every command a lab runs: `spa init`, `spa validate`,
`spa identify` and `snakemake reproduce-all`, with default settings.

Five charges and five discharges, 50 readings at 20 ms each, in psi, no time column and no
valve column (spa.synthetic.coarse), written to a temporary raw/ folder. spa goes as far as
the samples allow (c1, k2, tau2), says what it cannot resolve (both delays) and what to
record, and no stage uses a point delay.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml

from spa.model.params import ValveParams
from spa.synthetic.coarse import write_coarse_bench

ROOT = Path(__file__).resolve().parents[1]
TRUTH = ValveParams(c1=0.084, k2=0.88, tau2=0.092, t_on=0.012, t_off=0.018)


def _spa(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "spa", *args], capture_output=True, text=True, timeout=300
    )


@pytest.fixture(scope="module")
def coarse_run(tmp_path_factory):
    base = tmp_path_factory.mktemp("coarse")
    raw = base / "raw"
    folder = raw / "arduino"
    write_coarse_bench(folder, TRUTH, np.random.default_rng(1))
    init = _spa("init", str(folder))
    draft = (folder / "dataset.yaml").read_text()
    todos = [ln for ln in draft.splitlines() if "TODO" in ln and not ln.lstrip().startswith("#")]
    (folder / "dataset.yaml").write_text(
        draft.replace("sample_step: TODO", "sample_step: 0.02  # was TODO")
    )
    validate = _spa("validate", str(folder))
    identify = _spa("identify", str(folder))
    cfg = base / "cfg.yaml"
    cfg.write_text(f"datasets: {{raw_dir: {raw}}}\nsimulated: {{sim: null}}\n")
    out = base / "results"
    run = subprocess.run(
        [sys.executable, "-m", "snakemake", "reproduce-all", "-c2", "--configfile",
         "config/small.yaml", str(cfg), "--config", f"results={out}"],
        cwd=ROOT, capture_output=True, text=True, timeout=900,
    )  # fmt: skip
    return {
        "init": init, "todos": todos, "validate": validate, "identify": identify,
        "run": run, "out": out / "arduino", "raw": folder,
    }  # fmt: skip


def test_init_leaves_only_the_step_and_every_command_exits_0(coarse_run) -> None:
    assert coarse_run["init"].returncode == 0, coarse_run["init"].stdout
    assert len(coarse_run["todos"]) == 1 and "sample_step" in coarse_run["todos"][0]
    for step in ("validate", "identify", "run"):
        res = coarse_run[step]
        assert res.returncode == 0, (step, res.stdout[-2000:], res.stderr[-3000:])


def test_both_delays_are_reported_unresolved_with_what_to_record(coarse_run) -> None:
    text = coarse_run["identify"].stdout
    assert "unresolved: designs use the interval" in text
    assert "log the valve command beside the pressure, on the pressure's clock" in text
    params = yaml.safe_load((coarse_run["out"] / "identification" / "params.yaml").read_text())
    for name in ("t_on", "t_off"):
        assert params[name]["resolved"] is False
        assert params[name]["lo"] <= params[name]["value"] <= params[name]["hi"] <= 0.05
    for name in ("c1", "k2", "tau2"):
        assert params[name]["lo"] <= getattr(TRUTH, name) <= params[name]["hi"], name


def test_the_recommendation_and_the_closed_loop_say_what_they_cannot_do(coarse_run) -> None:
    rec = yaml.safe_load((coarse_run["out"] / "tuning" / "recommendation.yaml").read_text())
    assert rec["verified"] is False
    assert rec["unresolved"] == {"t_on": [0.0, 0.05], "t_off": [0.0, 0.05]}
    assert rec["sentence"].startswith("t_on and t_off are not resolved by the data")
    # the validation replays nothing it cannot: no valve command, no onset
    log = (coarse_run["out"].parent / "logs" / "arduino" / "validate_model.log").read_text()
    assert "not replayed: no valve command in the log" in log


def test_nothing_was_written_under_raw(coarse_run) -> None:
    names = sorted(p.name for p in coarse_run["raw"].iterdir())
    assert names == sorted(
        ["dataset.yaml", *(f"{k}_{i}.txt" for k in ("inflate", "deflate") for i in range(1, 6))]
    )


def test_the_page_says_only_what_is_true(coarse_run) -> None:
    import html
    import re

    page = (coarse_run["out"].parent / "report" / "arduino.html").read_text()
    text = html.unescape(re.sub(r"<[^>]+>", " ", re.sub(r"<(style|script).*?</\1>", "", page,
                                                         flags=re.S)))  # fmt: skip
    assert "at fault" not in text
    for stage in ("staircase", "sine", "chirp"):
        assert re.search(rf"Stage {stage}: no runs", text), stage
    assert "()" not in text
    assert "t_on and t_off are not resolved by the data" in text
