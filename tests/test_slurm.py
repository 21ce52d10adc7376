"""The cluster path on a real SLURM: a one-node Slurm 22.05 started by `.ci/slurm.sh`.

These tests run in CI (``CI=true``) or when opted in (``SPA_TEST_SLURM=1``), and skip with the
reason everywhere else, or where `.ci/slurm.sh` will not start a cluster (not root, an
existing /etc/slurm/slurm.conf or busy Slurm ports). Every Snakemake of a test runs under
``timeout -s KILL`` on its own process group, so a hung run (the plugin's issue #38) fails the
test instead of CI; on a failure, slurmctld's and slurmd's logs and `squeue`'s output are
kept in ``$SPA_SLURM_DIR/failed/<test>/`` (default /tmp/spa-slurm) and their tails printed.

A cluster without accounting needs ``--slurm-status-command squeue`` (:data:`NO_ACCOUNTING`,
docs/howto/cluster.md); ``--slurm-init-seconds-before-status-checks 2`` only makes the tests
faster (the default first check waits 40 s). The last test restarts the cluster with
slurmdbd on MariaDB and runs the profile's defaults.

The tests' cluster holds a task while the file named by the job's ``SPA_SLURM_HOLD``
environment variable exists (its TaskProlog, written by `.ci/slurm.sh`), unless
``<hold>.<jobid>.go`` exists (``<hold>.held.<jobid>`` says it waits): a test sees the job
running in `squeue` before it cancels, kills or releases it, so nothing races.
"""

from __future__ import annotations

import json
import os
import re
import shutil
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from spa.pipeline.execution import execution_path, memory_overrun, read_execution

ROOT = Path(__file__).resolve().parents[1]
SCRIPT = ROOT / ".ci" / "slurm.sh"
SLURM_DIR = Path(os.environ.get("SPA_SLURM_DIR", "/tmp/spa-slurm"))
OPTED_IN = bool(os.environ.get("CI")) or os.environ.get("SPA_TEST_SLURM") == "1"

pytestmark = pytest.mark.skipif(
    not OPTED_IN,
    reason="SLURM tests start daemons as root: they run in CI (CI=true) or with SPA_TEST_SLURM=1",
)

#: What a cluster without accounting (no slurmdbd) needs on top of profiles/slurm: the
#: plugin's default status query, `sacct`, fails there ("Slurm accounting storage is
#: disabled") and Snakemake then waits forever.
NO_ACCOUNTING = ["--slurm-status-command", "squeue"]
#: Test speed only: the first status check after 2 s rather than 40 s.
FAST = ["--slurm-init-seconds-before-status-checks", "2"]
#: Wall-clock limit of one Snakemake run, enforced with `timeout -s KILL`.
RUN_LIMIT_S = 420
SUBMITTED = re.compile(r"Job (\S+) has been submitted with SLURM jobid (\d+) \(log: ([^)]+)\)")


# --- the cluster ------------------------------------------------------------------------------


def _cluster(*args: str, limit: int = 600) -> subprocess.CompletedProcess:
    return subprocess.run(
        ["timeout", "-s", "KILL", str(limit), "bash", str(SCRIPT), *args],
        capture_output=True,
        text=True,
        env={**os.environ, "SPA_SLURM_DIR": str(SLURM_DIR)},
        start_new_session=True,
    )


def _up(*flags: str) -> None:
    res = _cluster("up", *flags)
    if res.returncode == 3:
        pytest.skip(res.stderr.strip().splitlines()[-1])
    assert res.returncode == 0, f"{SCRIPT} up failed:\n{res.stderr[-3000:]}\n{_daemon_logs()}"


@pytest.fixture(scope="module")
def slurm() -> Iterator[Path]:
    """A one-node cluster for the module, stopped at the end whatever happened."""
    try:
        _up()
        yield SLURM_DIR
    finally:
        _cluster("down", limit=120)


def _squeue() -> str:
    res = subprocess.run(
        ["squeue", "--states=all", "-o", "%i|%j|%T|%m|%l|%C|%k|%N|%M|%r"],
        capture_output=True,
        text=True,
        timeout=30,
    )
    return res.stdout + res.stderr


def _daemon_logs(lines: int = 40) -> str:
    parts = []
    for name in ["slurmctld.log", "slurmd.log", "slurmdbd.log"]:
        path = SLURM_DIR / name
        if path.exists():
            tail = path.read_text(errors="replace").splitlines()[-lines:]
            parts.append(f"--- {path} (last {lines} lines)\n" + "\n".join(tail))
    return "\n".join(parts)


@pytest.fixture(autouse=True)
def keep_logs_on_failure(request) -> Iterator[None]:
    """On a failed test, keep the daemons' logs and `squeue` in $SPA_SLURM_DIR/failed/<test>."""
    failed_before = request.session.testsfailed
    yield
    if request.session.testsfailed == failed_before or not SLURM_DIR.exists():
        return
    keep = SLURM_DIR / "failed" / request.node.name
    keep.mkdir(parents=True, exist_ok=True)
    for name in ["slurmctld.log", "slurmd.log", "slurmdbd.log", "munged.log"]:
        if (SLURM_DIR / name).exists():
            shutil.copy(SLURM_DIR / name, keep / name)
    (keep / "squeue.txt").write_text(_squeue())
    print(f"SLURM logs kept in {keep}\n{_daemon_logs()}\n--- squeue\n{_squeue()}")


# --- Snakemake on the cluster -----------------------------------------------------------------


def _command(*args: str, limit: int = RUN_LIMIT_S) -> list[str]:
    # `timeout` signals its whole process group: Snakemake and every sbatch/squeue it started
    return ["timeout", "-s", "KILL", str(limit), sys.executable, "-m", "snakemake", *args]


def snakemake(*args: str, env: dict | None = None) -> subprocess.CompletedProcess:
    """Snakemake from the repository root, with the job listing (`--quiet host`)."""
    return subprocess.run(
        _command(*args, "--quiet", "host"),
        cwd=ROOT,
        capture_output=True,
        text=True,
        env={**os.environ, **(env or {})},
        start_new_session=True,
    )


def start_snakemake(log: Path, *args: str, env: dict | None = None) -> subprocess.Popen:
    """Snakemake in the background, its console in ``log``, in a process group of its own."""
    with log.open("w") as fh:
        return subprocess.Popen(
            _command(*args, "--quiet", "host"),
            cwd=ROOT,
            stdout=fh,
            stderr=subprocess.STDOUT,
            env={**os.environ, **(env or {})},
            start_new_session=True,
        )


def wait_for(what: str, check, limit: float = 120.0):
    """Poll ``check()`` every 0.2 s until it returns something true; fail after ``limit``."""
    end = time.monotonic() + limit
    while time.monotonic() < end:
        got = check()
        if got:
            return got
        time.sleep(0.2)
    pytest.fail(f"waited {limit:.0f} s for {what}\n{_squeue()}")


def held_jobs(hold: Path) -> list[str]:
    """SLURM job ids whose task waits in ``hold`` (the TaskProlog writes <hold>.held.<id>)."""
    ids = [p.name.rsplit(".", 1)[1] for p in hold.parent.glob(f"{hold.name}.held.*")]
    return sorted(ids, key=int)


def _squeue_jobs(fields: str, ids: list[str]) -> list[str]:
    res = subprocess.run(
        ["squeue", "--states=all", "-h", "-j", ",".join(ids), "-o", fields],
        capture_output=True,
        text=True,
        timeout=30,
    )
    return res.stdout.split()


def job_state(job_id: str) -> str:
    res = subprocess.run(
        ["squeue", "--states=all", "-h", "-j", job_id, "-o", "%T"],
        capture_output=True,
        text=True,
        timeout=30,
    )
    return res.stdout.strip()


def submissions(log: str) -> list[tuple[str, str, str]]:
    """Every sbatch submission of a Snakemake console: (job, SLURM job id, SLURM log)."""
    return SUBMITTED.findall(log)


def raw_datasets(base: Path, names: list[str], broken: str | None = None) -> Path:
    """Copies of raw/example named ``names`` under ``base``/raw (``broken``: a non-numeric
    pressure on line 4 of its charge.csv), and a config file choosing them."""
    raw = base / "raw"
    for name in names:
        shutil.copytree(ROOT / "raw" / "example", raw / name)
        spec = raw / name / "dataset.yaml"
        spec.write_text(spec.read_text().replace("name: example", f"name: {name}"))
    if broken:
        charge = raw / broken / "charge.csv"
        lines = charge.read_text().splitlines(keepends=True)
        t, _, valve = lines[3].split(",")
        lines[3] = f"{t},abc,{valve}"
        charge.write_text("".join(lines))
    cfg = base / "datasets.yaml"
    cfg.write_text(f"datasets:\n  raw_dir: {raw}\n  include: []\n  exclude: []\n")
    return cfg


def ingest_targets(out: Path, names: list[str]) -> list[str]:
    """The ingest job's status file of each dataset: the cheapest per-dataset target."""
    return [str(out / name / "status" / "runs.json") for name in names]


def slurm_run(out: Path, cfg: Path, *targets: str, extra: tuple = ()) -> list[str]:
    """The arguments of a run of ``targets`` through profiles/slurm on a cluster without
    accounting."""
    return [
        *targets,
        "--profile",
        "profiles/slurm",
        "--configfile",
        "config/small.yaml",
        str(cfg),
        "--config",
        f"results={out}",
        *NO_ACCOUNTING,
        *FAST,
        *extra,
    ]


# --- the small configuration, as a lab runs it ------------------------------------------------


@pytest.fixture(scope="module")
def slurm_small_run(slurm, timeout_run, tmp_path_factory, isolated_config):
    """`reproduce-all` of the small configuration through profiles/slurm (the timeout test's
    run is started first, and waits in the background meanwhile)."""
    out = tmp_path_factory.mktemp("slurm_small") / "results"
    res = snakemake("reproduce-all", *slurm_run(out, isolated_config))
    text = res.stdout + res.stderr
    assert res.returncode == 0, text[-4000:]
    return out, text


def test_every_job_went_through_sbatch_with_its_groups_resources(slurm_small_run):
    from test_cluster import planned_jobs

    out, log = slurm_small_run
    planned = planned_jobs(log)
    subs = submissions(log)
    ids = [slurm_id for _, slurm_id, _ in subs]
    assert len(ids) == len(set(ids))
    jobs = {}  # SLURM job id -> what sbatch was given, from slurmctld (MinJobAge keeps them)
    for line in _squeue().splitlines()[1:]:
        f = line.split("|")
        jobs[f[0]] = {"state": f[2], "mem": f[3], "time": f[4], "cpus": f[5], "comment": f[6]}
    assert set(ids) <= set(jobs), (ids, sorted(jobs))
    assert all(jobs[i]["state"] == "COMPLETED" for i in ids), {i: jobs[i] for i in ids}
    # each dataset: one submission for its whole chain, with the group's combined resources
    datasets = ["sim", "example"]
    grouped = set()
    for name in datasets:
        record = read_execution(execution_path(out, name))["jobs"]
        assert set(record) in ({"simulate_dataset", "analyse"}, {"ingest_dataset", "analyse"})
        (slurm_id,) = {entry["slurm_job_id"] for entry in record.values()}
        assert slurm_id in ids
        grouped.add(slurm_id)
        mem = max(entry["mem_mb"] for entry in record.values())
        minutes = sum(entry["runtime_min"] for entry in record.values())
        cpus = max(entry["threads"] for entry in record.values())
        job = jobs[slurm_id]
        assert job["mem"] == f"{mem}M", (name, job)
        assert job["time"] == f"{minutes // 60}:{minutes % 60:02d}:00", (name, job)
        assert job["cpus"] == str(cpus), (name, job)
        assert job["comment"].startswith("rule_dataset_"), job
    # every other job alone, with its own resources as Snakemake planned them
    alone = {r: j for r, j in ((j["rule"], j) for j in planned.values())}
    for slurm_id in set(ids) - grouped:
        rule = jobs[slurm_id]["comment"].removeprefix("rule_")
        assert rule in alone, (rule, sorted(alone))
        want = alone[rule]
        assert jobs[slurm_id]["mem"] == f"{want['mem_mb']}M", (rule, jobs[slurm_id], want)
        assert jobs[slurm_id]["time"] == f"{int(want['runtime']):d}:00", (rule, want)
        assert jobs[slurm_id]["cpus"] == want["threads"], (rule, want)
    in_groups = {"simulate_dataset", "ingest_dataset", "analyse", "analyse_tables"}
    n_alone = sum(j["rule"] not in in_groups for j in planned.values())
    assert len(ids) == len(datasets) + n_alone


def _result_files(folder: Path) -> dict[str, bytes]:
    """Every file of a results folder, by relative path, but what says where and when it was
    made: logs, the execution records (provenance), the report's index (report/index.html and
    report.html: it shows them), the
    store of stage results (keyed by the results folder) and the recommendation's `source:`
    line (it names the results folder)."""
    found = {}
    for path in sorted(folder.rglob("*")):
        rel = str(path.relative_to(folder))
        skip = rel.startswith(("logs/", ".store/")) or rel in {"report/index.html", "report.html"}
        if not path.is_file() or skip or rel.endswith("provenance/execution.json"):
            continue
        data = path.read_bytes()
        if path.name == "recommendation.yaml":
            data = data.split(b"\n", 1)[1]
        found[rel] = data
    return found


def test_slurm_results_equal_the_local_runs(slurm_small_run, small_run):
    out, _ = slurm_small_run
    on_slurm, local = _result_files(out), _result_files(small_run)
    assert len(local) > 100
    assert sorted(on_slurm) == sorted(local)
    differ = [rel for rel in local if on_slurm[rel] != local[rel]]
    assert differ == []


def test_execution_record_says_where_each_job_ran(slurm_small_run):
    out, log = slurm_small_run
    node = subprocess.run(["hostname", "-s"], capture_output=True, text=True).stdout.strip()
    ids = {slurm_id for _, slurm_id, _ in submissions(log)}
    for name in ["sim", "example"]:
        record = read_execution(execution_path(out, name))
        assert record["dataset"] == name
        for rule, entry in record["jobs"].items():
            assert entry["executor"] == "slurm", (rule, entry)
            assert entry["slurm_job_id"] in ids, (rule, entry)
            assert entry["node"] == node
            assert 0 < entry["elapsed_s"] < RUN_LIMIT_S
            assert 50 < entry["peak_mem_mb"] < entry["mem_mb"], (rule, entry)
    index = (out / "report" / "index.html").read_text()
    assert "Where it ran" in index and "slurm" in index


# --- failures ---------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def failures_run(slurm, tmp_path_factory):
    """Three bench datasets through profiles/slurm: `broken` has a non-numeric pressure; the
    first job seen running is cancelled with scancel; every ingest job asks for 64 MB."""
    base = tmp_path_factory.mktemp("slurm_failures")
    names = ["example", "broken", "spare"]
    cfg = raw_datasets(base, names, broken="broken")
    out, hold, log = base / "results", base / "hold", base / "console.txt"
    hold.touch()
    args = slurm_run(
        out,
        cfg,
        *ingest_targets(out, names),
        extra=(
            "--set-resources",
            "ingest_dataset:mem_mb=64",
            "--default-resources",  # the how-to's way to name a partition
            "slurm_partition=main",
        ),
    )
    proc = start_snakemake(log, *args, env={"SPA_SLURM_HOLD": str(hold)})
    try:
        first = wait_for("a held job", lambda: held_jobs(hold) and held_jobs(hold)[0])
        wait_for(f"job {first} running", lambda: job_state(first) == "RUNNING")
        subprocess.run(["scancel", first], check=True, timeout=30)
        wait_for(f"job {first} cancelled", lambda: job_state(first) == "CANCELLED")
        hold.unlink()
        proc.wait(timeout=RUN_LIMIT_S)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
    return out, proc.returncode, log.read_text(), first


def test_cancelled_job_is_resubmitted_once_and_the_run_finishes(failures_run):
    out, returncode, log, cancelled = failures_run
    assert returncode == 0, log[-4000:]
    # the scheduler's own log of the job, which Snakemake shows with the failure
    assert f"*** JOB {cancelled} ON " in log and " CANCELLED AT " in log, log[-4000:]
    subs = submissions(log)
    jobs = [job for job, slurm_id, _ in subs]
    (job,) = [job for job, slurm_id, _ in subs if slurm_id == cancelled]
    assert f"Trying to restart job {job}." in log
    assert jobs.count(job) == 2, subs  # submitted, cancelled, resubmitted once
    assert len(subs) == 3 + 1
    for name in ["example", "spare"]:
        assert json.loads((out / name / "status" / "runs.json").read_text())["ok"] is True
    partitions = {line.split("|")[1] for line in _squeue_jobs("%i|%P", [s for _, s, _ in subs])}
    assert partitions == {"main"}


def test_broken_dataset_fails_alone_under_keep_going(failures_run):
    out, returncode, log, _ = failures_run
    assert returncode == 0, log[-4000:]
    status = json.loads((out / "broken" / "status" / "runs.json").read_text())
    assert not status["ok"] and "non-numeric value" in status["errors"][0]
    ingest_log = (out / "logs" / "broken" / "ingest.log").read_text()
    assert "charge.csv" in ingest_log and "line 4" in ingest_log
    for name in ["example", "spare"]:
        assert json.loads((out / name / "status" / "runs.json").read_text())["ok"] is True


def test_memory_overrun_is_named_with_both_numbers(failures_run):
    out, _, _, _ = failures_run
    for name in ["example", "broken", "spare"]:
        entry = read_execution(execution_path(out, name))["jobs"]["ingest_dataset"]
        assert entry["mem_mb"] == 64
        assert entry["peak_mem_mb"] > 64, entry  # Python and pandas alone are more
        sentence = memory_overrun("ingest_dataset", name, entry)
        assert sentence is not None
        assert name in sentence and "ingest_dataset" in sentence
        assert f"{entry['peak_mem_mb']:.0f} MB" in sentence and "64 MB" in sentence
        assert "RSS" in sentence  # how it was measured: no cgroups on this cluster


@pytest.fixture(scope="module")
def timeout_run(slurm, tmp_path_factory):
    """A job held past its one-minute runtime, started first and left to run in the background
    while the other tests use the cluster: SLURM ends it at 60-90 s (its time-limit check
    runs every 30 s), and the plugin, whose status checks back off by 10 s while nothing
    ends, sees it up to a minute later. Yields a function that waits for the run's end."""
    base = tmp_path_factory.mktemp("slurm_timeout")
    cfg = raw_datasets(base, ["slow"])
    out, hold, log = base / "results", base / "hold", base / "console.txt"
    hold.touch()
    args = slurm_run(
        out,
        cfg,
        *ingest_targets(out, ["slow"]),
        # --slurm-no-account: the plugin accepts it and ignores it (checked below)
        extra=(
            "--set-resources",
            "ingest_dataset:runtime=1",
            "--retries",
            "0",
            "--slurm-no-account",
        ),
    )
    proc = start_snakemake(log, *args, env={"SPA_SLURM_HOLD": str(hold)})

    def finished() -> tuple[Path, int, str]:
        try:
            proc.wait(timeout=RUN_LIMIT_S)
        finally:
            if proc.poll() is None:
                os.killpg(proc.pid, signal.SIGKILL)
        return out, proc.returncode, log.read_text()

    try:
        yield finished
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)


def test_job_over_its_runtime_is_reported_as_timeout_by_rule_and_dataset(timeout_run):
    out, returncode, text = timeout_run()
    assert returncode != 0, text[-3000:]
    (slurm_id,) = [s for _, s, _ in submissions(text)]
    assert job_state(slurm_id) == "TIMEOUT"
    # Snakemake names the rule and its outputs (the dataset's folder), and shows the job's
    # SLURM log, where the scheduler says why it ended
    error = text[text.index("Error in group dataset") :]
    assert "rule ingest_dataset:" in error, error[:3000]
    assert f"{out}/slow/status/runs.json" in error, error[:3000]
    assert f"*** JOB {slurm_id} ON " in error and "DUE TO TIME LIMIT" in error, error[:3000]
    # --slurm-no-account was passed, and the plugin still went guessing an account
    assert "No SLURM account given, trying to guess." in text


def test_killed_snakemake_restarted_redoes_only_the_unfinished_datasets(slurm, tmp_path):
    names = ["first", "second"]
    cfg = raw_datasets(tmp_path, names)
    out, hold, log = tmp_path / "results", tmp_path / "hold", tmp_path / "console.txt"
    hold.touch()
    args = slurm_run(out, cfg, *ingest_targets(out, names))
    proc = start_snakemake(log, *args, env={"SPA_SLURM_HOLD": str(hold)})
    try:
        wait_for("two held jobs", lambda: len(held_jobs(hold)) >= 2)
        released, stuck = held_jobs(hold)[:2]
        Path(f"{hold}.{released}.go").touch()
        wait_for(f"job {released} finished", lambda: "Finished jobid" in log.read_text())
        os.killpg(proc.pid, signal.SIGKILL)  # Snakemake killed mid-run
        proc.wait(timeout=30)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
    subprocess.run(["scancel", stuck], check=True, timeout=30)  # its job is lost too
    hold.unlink()
    done = [n for n in names if (out / n / "status" / "runs.json").exists()]
    assert len(done) == 1, log.read_text()[-3000:]
    (finished,) = done
    (unfinished,) = set(names) - {finished}
    before = (out / finished / "status" / "runs.json").stat().st_mtime_ns
    assert snakemake(*ingest_targets(out, names), "--unlock", *args[2:]).returncode == 0
    res = snakemake(*args)  # the profile sets --rerun-incomplete
    text = res.stdout + res.stderr
    assert res.returncode == 0, text[-3000:]
    subs = submissions(text)
    assert len(subs) == 1, subs  # only the unfinished dataset's chain
    assert f"dataset={unfinished}" in text and f"dataset={finished}" not in text
    assert (out / finished / "status" / "runs.json").stat().st_mtime_ns == before
    for name in names:
        assert json.loads((out / name / "status" / "runs.json").read_text())["ok"] is True


# --- with accounting --------------------------------------------------------------------------


def test_profile_defaults_on_a_cluster_with_accounting(slurm, tmp_path):
    """slurmdbd on MariaDB: `sacct` answers, and profiles/slurm runs as it is, with no flag."""
    _up("--accounting")
    assert subprocess.run(["sacct", "-n", "-X"], capture_output=True).returncode == 0
    cfg = raw_datasets(tmp_path, ["acct"])
    out = tmp_path / "results"
    res = snakemake(
        *ingest_targets(out, ["acct"]),
        "--profile",
        "profiles/slurm",
        "--configfile",
        "config/small.yaml",
        str(cfg),
        "--config",
        f"results={out}",
    )
    text = res.stdout + res.stderr
    assert res.returncode == 0, text[-3000:]
    assert "Falling back" not in text
    (slurm_id,) = [s for _, s, _ in submissions(text)]
    sacct = subprocess.run(
        ["sacct", "-n", "-X", "-P", "-j", slurm_id, "-o", "State,Account"],
        capture_output=True,
        text=True,
        timeout=30,
    ).stdout
    # the plugin's account guess (`sacct -nu <user> ... | tail -1`, run without a shell) fails
    # even here, so sbatch gets no -A and SLURM charges the user's default account
    assert "Unable to guess SLURM account. Trying to proceed without." in text
    default = subprocess.run(
        [
            "sacctmgr",
            "-n",
            "-P",
            "show",
            "user",
            os.environ.get("USER", "root"),
            "format=DefaultAccount",
        ],
        capture_output=True,
        text=True,
        timeout=30,
    ).stdout.strip()
    assert sacct.strip() == f"COMPLETED|{default}", (sacct, default)
    entry = read_execution(execution_path(out, "acct"))["jobs"]["ingest_dataset"]
    assert entry["slurm_job_id"] == slurm_id
