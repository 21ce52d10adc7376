"""The stage table (spa/pipeline/stage_table.py): declared once, the workflow derived from it; each
stage a function in spa that a notebook can call; the workflow's scripts thin."""

from __future__ import annotations

import importlib
import io
from pathlib import Path

import pandas as pd
import pytest
import yaml

from spa.datasets import read_runs
from spa.io import read_params
from spa.pipeline.outputs import STAGES, job_stages, stage_outputs, stage_settings
from spa.stages._common import OpenLoopInputs
from spa.stages.chirp import run_chirp, write_chirp
from spa.stages.sine import run_sine, write_sine
from spa.stages.staircase import run_staircase, write_staircase

ROOT = Path(__file__).resolve().parents[1]
SCRIPTS = sorted((ROOT / "workflow" / "scripts").glob("*.py"))


@pytest.mark.parametrize("script", SCRIPTS, ids=lambda p: p.name)
def test_every_workflow_script_is_at_most_40_lines(script: Path) -> None:
    n = len(script.read_text(encoding="utf-8").splitlines())
    assert n <= 40, f"{script.name}: {n} lines; move the logic into spa (spa/stages/)"


def test_the_jobs_run_their_stages_in_the_tables_order() -> None:
    order = [s.name for s in STAGES]
    for job in ("ingest", "analyse"):
        names = list(job_stages(job))
        assert names == sorted(names, key=order.index)
    assert list(job_stages("analyse")) == [
        "identify", "tune", "validate_model", "staircase", "sine", "chirp", "closed_loop", "page",
    ]  # fmt: skip
    # the workflow writes no stage list of its own
    rules = (ROOT / "workflow" / "rules" / "analyse.smk").read_text(encoding="utf-8")
    assert 'ANALYSE = job_stages("analyse")' in rules and '"staircase",' not in rules
    with pytest.raises(KeyError, match="no stage runs in the job"):
        job_stages("nothing")


def test_every_declared_function_script_and_config_section_exists() -> None:
    config = yaml.safe_load((ROOT / "config" / "config.yaml").read_text(encoding="utf-8"))
    assert all(any(getattr(s, a) for s in STAGES) for a in ("function", "job", "config")), (
        "some stages declare a function, a job and a config section"
    )
    for stage in STAGES:
        if stage.function:
            module, _, name = stage.function.rpartition(".")
            assert callable(getattr(importlib.import_module(module), name)), stage.function
        if stage.job:
            assert stage.function, f"{stage.name}: a job's stage names its spa function"
            script = ROOT / "workflow" / "scripts" / f"{stage.script or stage.name}.py"
            assert script.is_file(), script
        if stage.config:
            section = stage_settings(config, [stage.name])[stage.name]
            assert isinstance(section, dict) and section, f"{stage.name}: {stage.config}"


def test_a_stage_without_settings_gets_an_empty_mapping() -> None:
    assert stage_settings({}, ["staircase", "page"]) == {"staircase": {}, "page": {}}


def _merged(base: dict, over: dict) -> dict:
    out = dict(base)
    for key, value in over.items():
        both = isinstance(value, dict) and isinstance(base.get(key), dict)
        out[key] = _merged(base[key], value) if both else value
    return out


@pytest.mark.parametrize(
    ("stage", "run", "write", "table"),
    [
        ("staircase", run_staircase, write_staircase, "table3"),
        ("sine", run_sine, write_sine, "table"),
        ("chirp", run_chirp, write_chirp, "table"),
    ],
)
def test_a_stage_function_reproduces_the_pipelines_table(
    small_run, tmp_path, stage, run, write, table
) -> None:
    """Called from Python on the small run's `sim` run tables, each open-loop stage gives the
    table the workflow wrote, byte for byte, and writes every output it is given."""
    small = yaml.safe_load((ROOT / "config" / "small.yaml").read_text(encoding="utf-8"))
    full = yaml.safe_load((ROOT / "config" / "config.yaml").read_text(encoding="utf-8"))
    cfg = stage_settings(_merged(full, small), [stage])  # as --configfile merges them
    runs, metas = read_runs(small_run / "sim" / "runs")
    params = read_params(small_run / "sim" / "identification" / "params.yaml")
    result = run(OpenLoopInputs(runs, metas, params, {**cfg[stage]}))
    assert not result.empty
    outputs = {
        key: str(tmp_path / Path(path).name)
        for key, path in stage_outputs(stage, str(tmp_path), "sim", figures=False).items()
        if key != "status"
    }
    write(result, outputs, "sim")
    written = Path(outputs[table]).read_bytes()
    assert written == (small_run / "sim" / stage / Path(outputs[table]).name).read_bytes()
    listed = set(pd.read_csv(io.BytesIO(written))["run"].dropna())
    ours = {rid for rid, m in metas.items() if m["kind"] == stage}
    assert ours <= listed and len(listed - ours) <= 1  # and the linear reference's row
