"""Beyond one machine: the SLURM profile's plan, and real runs through a local stand-in cluster.

These run on any machine, as any user, with no daemon; tests/test_slurm.py runs the same path
on a real one-node Slurm (in CI, or with SPA_TEST_SLURM=1).

profiles/local-cluster drives the cluster-generic executor exactly as it would drive a real
scheduler, but its submit command (profiles/local-cluster/submit.sh) runs each job script on
this machine and logs what it was asked for. The tests check that every job of a run went
through it with the threads, mem_mb and runtime Snakemake planned for that job, so a new rule
is covered without editing this file.
"""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SNAKEMAKE = [sys.executable, "-m", "snakemake"]


def run(*args: str, env: dict | None = None) -> subprocess.CompletedProcess:
    # `--quiet host`: list every job with its resources, which the workflow's own profile
    # (profiles/default, applied after --profile) leaves out of the console
    return subprocess.run(
        [*SNAKEMAKE, *args, "--quiet", "host"],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=900,
        env={**os.environ, **(env or {})},
    )


def run_local_cluster(
    targets: list[Path], out: Path, cluster_dir: Path, config: Path, *extra: str
) -> subprocess.CompletedProcess:
    """``targets`` of the small config through profiles/local-cluster into ``out``."""
    return run(
        *map(str, targets),
        "--profile",
        "profiles/local-cluster",
        "--configfile",
        "config/small.yaml",
        str(config),
        "--config",
        f"results={out}",
        *extra,
        env={"LOCAL_CLUSTER_DIR": str(cluster_dir)},
    )


def planned_jobs(log: str) -> dict[str, dict[str, str]]:
    """Every job block of a Snakemake log: jobid -> rule, threads, mem_mb, runtime.

    Jobs of local rules (`localrule ...:`) are left out: they never reach the executor.
    """
    jobs = {}
    for block in re.split(r"\n(?=\s*\[[^\]]+\]\n)", log):  # group jobs' are indented
        head = re.search(r"^\s*rule (\S+):$", block, re.M)
        jobid = re.search(r"^\s+jobid: (\d+)$", block, re.M)
        if not (head and jobid):
            continue
        resources = re.search(r"^\s+resources: (.*)$", block, re.M)
        res = dict(kv.split("=", 1) for kv in resources.group(1).split(", ")) if resources else {}
        threads = re.search(r"^\s+threads: (\d+)$", block, re.M)  # printed only when > 1
        jobs[jobid.group(1)] = {
            "rule": head.group(1),
            "threads": threads.group(1) if threads else "1",
            "mem_mb": res.get("mem_mb"),
            "runtime": res.get("runtime"),
        }
    return jobs


def submissions(cluster_dir: Path) -> dict[str, dict[str, str]]:
    """submit.sh's log: external job id -> the fields it recorded."""
    out = {}
    for line in (cluster_dir / "submissions.log").read_text().splitlines():
        fields = dict(kv.split("=", 1) for kv in line.split(" "))
        out[fields["id"]] = fields
    return out


def assert_every_job_went_through_submit(log: str, cluster_dir: Path) -> dict[str, dict]:
    """Each planned job was submitted once, via submit.sh, with its own resources."""
    jobs = planned_jobs(log)
    assert jobs, log[-3000:]
    submitted = dict(re.findall(r"Submitted job (\d+) with external jobid '([^']+)'", log))
    recorded = submissions(cluster_dir)
    assert sorted(submitted) == sorted(jobs), (sorted(submitted), sorted(jobs))
    assert sorted(recorded) == sorted(submitted.values())
    for jobid, job in jobs.items():
        got = recorded[submitted[jobid]]
        assert got["jobid"] == jobid
        for key in ["rule", "threads", "mem_mb", "runtime"]:
            assert got[key] == job[key], (jobid, key, got, job)
    return {submitted[j]: job for j, job in jobs.items()}


def test_slurm_profile_plans_the_whole_run_without_slurm(tmp_path, isolated_config):
    # A dry run uses Snakemake's dry-run executor: the SLURM plugin only checks its settings
    # and calls no sbatch/sinfo/sacct, so this works on a machine without SLURM. Real runs
    # on a real Slurm are in tests/test_slurm.py.
    res = run(
        "reproduce-all",
        "--profile",
        "profiles/slurm",
        "--dry-run",
        "--configfile",
        "config/small.yaml",
        str(isolated_config),
        "--config",
        f"results={tmp_path}",
    )
    text = res.stdout + res.stderr
    assert res.returncode == 0, text[-3000:]
    assert "Using profiles profiles/slurm" in text
    jobs = planned_jobs(text)
    rules = {job["rule"] for job in jobs.values()}
    assert {"analytic_table1", "simulate_dataset", "ingest_dataset", "analyse"} <= rules
    for job in jobs.values():  # every job carries explicit memory and runtime for sbatch
        assert job["mem_mb"] and job["runtime"], job
    assert "This was a dry-run" in text
    assert not any(tmp_path.iterdir())
    # one submission per dataset: each dataset's chain is one group job (sim, example)
    assert text.count("Group job dataset") == 2


@pytest.fixture(scope="module")
def cluster_run(tmp_path_factory, isolated_config):
    """A real run of the small config through profiles/local-cluster.

    Three targets, one per stage (analytic, simulated dataset, bench dataset), rather than
    reproduce-all: every job through the stand-in cluster starts its own Snakemake, which
    roughly doubles the run time, and tests/test_workflow.py already runs the whole DAG.
    """
    base = tmp_path_factory.mktemp("cluster")
    out, cluster_dir = base / "results", base / "cluster"
    targets = [
        out / "analytic" / "table1.csv",
        out / "sim" / "identification" / "params.yaml",
        out / "example" / "validation" / "fit.csv",
    ]
    res = run_local_cluster(
        targets,
        out,
        cluster_dir,
        isolated_config,
        # A non-default size for one rule, to show the values are the job's, not defaults.
        # --cores caps a job's threads (not the number of jobs) with a cluster executor.
        "--cores",
        "2",
        "--set-threads",
        "analytic_table1=2",
        "--set-resources",
        "analytic_table1:mem_mb=700",
    )
    return res, out, cluster_dir, targets


def test_cluster_run_succeeds_and_writes_outputs(cluster_run):
    res, _, _, targets = cluster_run
    assert res.returncode == 0, res.stderr[-3000:]
    for target in targets:
        assert target.stat().st_size > 0, target


def test_every_cluster_job_went_through_submit_with_its_resources(cluster_run):
    res, _, cluster_dir, _ = cluster_run
    assert res.returncode == 0, res.stderr[-3000:]
    jobs = assert_every_job_went_through_submit(res.stdout + res.stderr, cluster_dir)
    by_rule = {job["rule"]: job for job in jobs.values()}
    assert {
        "analytic_table1",
        "simulate_dataset",
        "ingest_dataset",
        "analyse",
    } <= set(by_rule)
    assert by_rule["analytic_table1"]["threads"] == "2"
    assert by_rule["analytic_table1"]["mem_mb"] == "700"
    assert by_rule["ingest_dataset"]["mem_mb"] == "2500"
    assert by_rule["ingest_dataset"]["runtime"] == "30"
    # submit.sh recorded each job's exit status: all ran to the end and succeeded
    for ext_id in jobs:
        assert (cluster_dir / f"{ext_id}.exit").read_text().strip() == "0"


def test_keep_going_on_the_cluster_finishes_good_datasets(tmp_path):
    """A broken bench dataset fails alone on the cluster: its stages record the failure
    (spa.pipeline.status) instead of failing their jobs, and the other datasets finish."""
    raw = tmp_path / "raw"
    shutil.copytree(ROOT / "raw" / "example", raw / "example")
    shutil.copytree(ROOT / "raw" / "example", raw / "broken")
    spec = raw / "broken" / "dataset.yaml"
    spec.write_text(spec.read_text().replace("name: example", "name: broken"))
    charge = raw / "broken" / "charge.csv"
    lines = charge.read_text().splitlines(keepends=True)
    t, _, valve = lines[3].split(",")
    lines[3] = f"{t},abc,{valve}"  # a non-numeric pressure on line 4
    charge.write_text("".join(lines))
    cfg = tmp_path / "datasets.yaml"
    cfg.write_text(f"datasets:\n  raw_dir: {raw}\n  include: []\n  exclude: []\n")
    out, cluster_dir = tmp_path / "results", tmp_path / "cluster"
    res = run(
        *(f"{out}/{d}/identification/params.yaml" for d in ["example", "broken"]),
        "--profile",
        "profiles/local-cluster",
        "--configfile",
        "config/small.yaml",
        str(cfg),
        "--config",
        f"results={out}",
        env={"LOCAL_CLUSTER_DIR": str(cluster_dir)},
    )
    assert res.returncode == 0, res.stderr[-3000:]
    log = (out / "logs" / "broken" / "ingest.log").read_text()
    assert "charge.csv" in log and "non-numeric value" in log and "line 4" in log, log
    assert (out / "example" / "identification" / "params.yaml").stat().st_size > 0
    assert "failed" in (out / "broken" / "identification" / "params.yaml").read_text()
    status = json.loads((out / "broken" / "status" / "runs.json").read_text())
    assert not status["ok"] and "non-numeric value" in status["errors"][0]
    assert json.loads((out / "example" / "status" / "identify.json").read_text())["ok"]
    # the failure was seen through status.sh, and every job still went through submit.sh
    jobs = assert_every_job_went_through_submit(res.stdout + res.stderr, cluster_dir)
    failed = [i for i in jobs if (cluster_dir / f"{i}.exit").read_text().strip() != "0"]
    assert failed == []


def test_local_cluster_receives_one_submission_per_dataset(tmp_path, isolated_config):
    """The SLURM profile's grouping, through the stand-in cluster: a bench dataset's whole
    chain (raw_manifest ... chirp) is one submission, which runs every job of the chain."""
    import yaml

    groups = yaml.safe_load((ROOT / "profiles" / "slurm" / "config.yaml").read_text())["groups"]
    out, cluster_dir = tmp_path / "results", tmp_path / "cluster"
    per_dataset = _dataset_targets(out, "example")
    res = run_local_cluster(per_dataset, out, cluster_dir, isolated_config, "--groups", *groups)
    text = res.stdout + res.stderr
    assert res.returncode == 0, text[-3000:]
    recorded = submissions(cluster_dir)
    assert len(recorded) == 1, recorded
    (job,) = recorded.values()
    assert job["rule"] == "GROUP", job  # how the cluster-generic executor names a group job
    # the one submission ran the dataset's every stage, each to success
    for target in per_dataset:
        assert json.loads(target.read_text())["ok"] is True, target
    ext_id = next(iter(recorded))
    assert (cluster_dir / f"{ext_id}.exit").read_text().strip() == "0"


def _dataset_targets(out: Path, dataset: str) -> list[Path]:
    """The status file of every per-dataset stage of ``dataset``: written last by each."""
    from spa.pipeline.outputs import STAGES, stage_outputs

    paths = []
    for stage in STAGES:
        if stage.per_dataset and stage.name != "raw_manifest":
            path = stage_outputs(stage.name, str(out))["status"]
            paths.append(Path(path.format(dataset=dataset)))
    return paths


def test_howto_cluster_commands_are_the_ones_run_on_slurm():
    """Every option of the how-to's `snakemake` commands is one that tests/test_slurm.py
    passes to Snakemake on the real scheduler, and the flag it gives for a cluster without
    accounting is the one those tests use."""
    howto = (ROOT / "docs" / "howto" / "cluster.md").read_text()
    tested = (ROOT / "tests" / "test_slurm.py").read_text()
    blocks = re.findall(r"```bash\n(.*?)```", howto, re.S)
    commands = [
        line.strip()
        for block in blocks
        for line in block.replace("\\\n", " ").splitlines()
        if line.strip().startswith("snakemake ")
    ]
    assert len(commands) >= 4, commands
    options = {tok for cmd in commands for tok in cmd.split() if tok.startswith("--")}
    assert {"--profile", "--slurm-status-command", "--set-resources"} <= options
    for option in sorted(options):
        assert f'"{option}"' in tested, f"{option} (docs/howto/cluster.md) is not run on SLURM"
    assert "snakemake reproduce-all --profile profiles/slurm --slurm-status-command squeue" in (
        " ".join(commands)
    )
    assert 'NO_ACCOUNTING = ["--slurm-status-command", "squeue"]' in tested
