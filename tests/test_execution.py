"""Each dataset's execution record (spa.pipeline.execution) and the report's "Where it ran"."""

from __future__ import annotations

import json
from types import SimpleNamespace

import pytest

from spa.pipeline.execution import (
    cluster_cost,
    execution_path,
    job_environment,
    memory_overrun,
    read_execution,
    recorded_job,
    write_job_record,
)
from spa.report.cost import cost_html


def _entry(**kw):
    base = {
        "executor": "slurm",
        "slurm_job_id": "17",
        "node": "n1",
        "elapsed_s": 30.0,
        "peak_mem_mb": 300.0,
        "mem_mb": 2000,
        "runtime_min": 30,
        "threads": 1,
    }
    return {**base, **kw}


def test_job_environment_reads_slurm_variables():
    env = {"SLURM_JOB_ID": "42", "SLURMD_NODENAME": "node07"}
    assert job_environment(env) == {"executor": "slurm", "slurm_job_id": "42", "node": "node07"}
    local = job_environment({})
    assert local["executor"] == "local" and local["slurm_job_id"] is None and local["node"]


def test_records_of_a_dataset_are_merged_by_rule(tmp_path):
    path = execution_path(tmp_path, "d1")
    assert path == tmp_path / "d1" / "provenance" / "execution.json"
    write_job_record(path, "d1", "ingest_dataset", _entry(slurm_job_id="5"))
    write_job_record(path, "d1", "analyse", _entry(slurm_job_id="5", elapsed_s=60.0))
    write_job_record(path, "d1", "analyse", _entry(slurm_job_id="9", elapsed_s=61.0))  # rerun
    record = read_execution(path)
    assert record["dataset"] == "d1"
    assert sorted(record["jobs"]) == ["analyse", "ingest_dataset"]
    assert record["jobs"]["analyse"]["slurm_job_id"] == "9"
    assert list(path.parent.glob(".*tmp")) == []


@pytest.mark.parametrize("text", ["", "not json", "[1, 2]", '{"jobs": 3}'])
def test_an_unreadable_record_reads_as_empty(tmp_path, text):
    path = tmp_path / "execution.json"
    path.write_text(text)
    assert read_execution(path)["jobs"] == {}
    assert read_execution(tmp_path / "missing.json")["jobs"] == {}


def test_memory_overrun_names_the_job_with_both_numbers():
    assert memory_overrun("analyse", "d1", _entry(peak_mem_mb=1999.0)) is None
    assert memory_overrun("analyse", "d1", _entry(peak_mem_mb=None)) is None
    text = memory_overrun("analyse", "d1", _entry(peak_mem_mb=2345.6, mem_mb=2000))
    assert text is not None
    assert text.startswith("d1: job analyse (SLURM job 17)")
    assert "2346 MB" in text and "2000 MB" in text and "RSS" in text
    assert "--set-resources analyse:mem_mb=" in text


def test_cluster_cost_sums_the_records():
    records = [
        {"dataset": "a", "jobs": {"ingest_dataset": _entry(), "analyse": _entry()}},
        {"dataset": "b", "jobs": {"analyse": _entry(slurm_job_id="18", peak_mem_mb=2500.0)}},
        {"jobs": {}},
    ]
    cost = cluster_cost(records)
    assert cost["jobs"] == 3
    assert cost["slurm_jobs"] == 2  # a's two jobs were one submission
    assert cost["job_hours"] == pytest.approx(90.0 / 3600)
    assert cost["peak_mem_mb"] == 2500.0
    assert cost["executors"] == ["slurm"] and cost["nodes"] == ["n1"]
    assert len(cost["overruns"]) == 1 and cost["overruns"][0].startswith("b: job analyse")
    assert cluster_cost([])["peak_mem_mb"] is None


def test_where_it_ran_shows_only_a_cluster_run(tmp_path):
    write_job_record(execution_path(tmp_path, "a"), "a", "analyse", _entry(executor="local"))
    assert cost_html(tmp_path, ["a", "missing"]) == ""  # a local run's report is unchanged
    write_job_record(execution_path(tmp_path, "b"), "b", "analyse", _entry(peak_mem_mb=2100.0))
    text = cost_html(tmp_path, ["a", "b"])
    assert "SLURM submissions" in text and "local, slurm" in text
    assert "b: job analyse (SLURM job 17) peaked at 2100 MB" in text


def test_recorded_job_writes_the_record_even_when_the_job_fails(tmp_path, monkeypatch, capsys):
    monkeypatch.delenv("SLURM_JOB_ID", raising=False)
    smk = SimpleNamespace(
        rule="analyse",
        wildcards=SimpleNamespace(dataset="d1"),
        resources=SimpleNamespace(mem_mb=1, runtime=5),
        threads=1,
        config={"results": str(tmp_path)},
    )
    with pytest.raises(RuntimeError), recorded_job(smk):
        raise RuntimeError("the stage failed")
    entry = json.loads(execution_path(tmp_path, "d1").read_text())["jobs"]["analyse"]
    assert entry["executor"] == "local" and entry["mem_mb"] == 1 and entry["runtime_min"] == 5
    assert entry["elapsed_s"] >= 0 and entry["peak_mem_mb"] > 1
    assert "memory overrun: d1: job analyse" in capsys.readouterr().err
