"""Where and how each dataset's jobs ran: a record of its own beside the results.

Every per-dataset job (``ingest_dataset``, ``simulate_dataset``, ``analyse``) writes one entry
into ``results/<dataset>/provenance/execution.json`` (:data:`EXECUTION_FILE`), keyed by rule:
the executor (``slurm`` when the job ran under a SLURM allocation, else ``local``), the SLURM
job id and node, the job's elapsed time, and its peak memory with the ``mem_mb`` it asked for.

The peak memory is the job's own: the largest resident set size of the job's process
(``getrusage``), which is what a scheduler without cgroups can know of it too. A job whose peak
exceeds its ``mem_mb`` is named, with both numbers (:func:`memory_overrun`): where the
scheduler enforces memory (cgroups) such a job would have ended OUT_OF_MEMORY instead.

The record is provenance, not a result: it differs between two runs of the same data (job
ids, times), so it is kept out of the byte-for-byte comparison of results and out of the
outputs Snakemake tracks; the report's index sums it into the run's cluster cost
(:func:`cluster_cost`).
"""

from __future__ import annotations

import json
import os
import resource
import socket
import sys
import time
from collections.abc import Iterator, Mapping, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import Any

__all__ = [
    "EXECUTION_FILE",
    "MEMORY_SOURCE",
    "cluster_cost",
    "execution_path",
    "job_environment",
    "memory_overrun",
    "read_execution",
    "recorded_job",
    "write_job_record",
]

#: Where a dataset's execution record is written, under ``results/<dataset>/``.
EXECUTION_FILE = "provenance/execution.json"

#: How the peak memory of a record was measured.
MEMORY_SOURCE = "the job's own peak RSS (getrusage), not the scheduler's cgroup"


def execution_path(results: str | Path, dataset: str) -> Path:
    """The execution record of ``dataset`` in the results folder ``results``."""
    return Path(results) / dataset / EXECUTION_FILE


def job_environment(env: Mapping[str, str]) -> dict[str, Any]:
    """Executor, SLURM job id and node of the job whose environment is ``env``.

    Parameters
    ----------
    env : mapping
        The job's environment (``os.environ``). SLURM sets ``SLURM_JOB_ID`` and
        ``SLURMD_NODENAME`` in every task of a job, including the inner ``srun`` step of the
        SLURM executor plugin.

    Returns
    -------
    dict
        ``executor`` (``"slurm"`` or ``"local"``), ``slurm_job_id`` (str or None) and
        ``node`` (the SLURM node, or this machine's host name).
    """
    job_id = env.get("SLURM_JOB_ID") or None
    node = env.get("SLURMD_NODENAME") or socket.gethostname().split(".")[0]
    return {
        "executor": "slurm" if job_id else "local",
        "slurm_job_id": job_id,
        "node": node,
    }


def _peak_rss_mb() -> float:
    """The largest resident set of this process and its waited-for children, in MB."""
    kib = max(
        resource.getrusage(resource.RUSAGE_SELF).ru_maxrss,
        resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss,
    )
    return round(kib / 1024, 1)  # Linux reports kibibytes


def memory_overrun(rule: str, dataset: str, entry: Mapping[str, Any]) -> str | None:
    """A sentence naming a job whose peak memory exceeded its ``mem_mb``, or None.

    Parameters
    ----------
    rule, dataset : str
        The job's rule and dataset, to name it.
    entry : mapping
        Its execution record (``peak_mem_mb``, ``mem_mb``, ``memory_source``).

    Returns
    -------
    str or None
    """
    peak, asked = entry.get("peak_mem_mb"), entry.get("mem_mb")
    if peak is None or asked is None or peak <= asked:
        return None
    return (
        f"{dataset}: job {rule} (SLURM job {entry.get('slurm_job_id') or '-'}) peaked at "
        f"{peak:.0f} MB, over its mem_mb of {asked:.0f} MB (measured as "
        f"{entry.get('memory_source', MEMORY_SOURCE)}); raise it with --set-resources "
        f"{rule}:mem_mb=..."
    )


def read_execution(path: str | Path) -> dict[str, Any]:
    """The execution record at ``path``: ``{"dataset", "jobs": {rule: entry}}``; empty jobs
    when there is none or it cannot be read (a record is never needed to build results)."""
    try:
        data = json.loads(Path(path).read_text())
    except (OSError, ValueError):
        return {"jobs": {}}
    if not isinstance(data, dict) or not isinstance(data.get("jobs"), dict):
        return {"jobs": {}}
    return data


def write_job_record(path: str | Path, dataset: str, rule: str, entry: Mapping[str, Any]) -> None:
    """Add or replace ``rule``'s entry in the execution record at ``path`` (atomic replace).

    The jobs of one dataset run one after the other (one group job on a cluster), so the
    read-modify-write does not race.
    """
    path = Path(path)
    data = read_execution(path)
    data["dataset"] = dataset
    data["jobs"] = {**data["jobs"], rule: dict(entry)}
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    tmp.write_text(json.dumps(data, indent=1, sort_keys=True) + "\n")
    os.replace(tmp, path)


@contextmanager
def recorded_job(smk: Any) -> Iterator[None]:
    """Run the body as one dataset job of ``smk``, then write its execution record.

    The record is written whether the body succeeds or raises (a failed job's elapsed time
    and memory are what a cluster's user needs most); a job whose peak memory exceeded its
    ``mem_mb`` is also named on standard error (:func:`memory_overrun`), which the scheduler's
    log and Snakemake's console show.

    Parameters
    ----------
    smk : snakemake.script.Snakemake
        The job: its ``rule``, ``wildcards.dataset``, ``resources`` and ``config["results"]``.
    """
    start = time.monotonic()
    started = time.strftime("%Y-%m-%dT%H:%M:%S%z")
    try:
        yield
    finally:
        dataset = str(smk.wildcards.dataset)
        resources = smk.resources
        entry = {
            **job_environment(os.environ),
            "started": started,
            "elapsed_s": round(time.monotonic() - start, 2),
            "peak_mem_mb": _peak_rss_mb(),
            "memory_source": MEMORY_SOURCE,
            "mem_mb": getattr(resources, "mem_mb", None),
            "runtime_min": getattr(resources, "runtime", None),
            "threads": getattr(smk, "threads", None),
        }
        path = execution_path(smk.config.get("results", "results"), dataset)
        try:
            write_job_record(path, dataset, str(smk.rule), entry)
        except OSError as exc:  # a record never fails a job
            print(f"spa: {path}: execution record not written: {exc}", file=sys.stderr)
        overrun = memory_overrun(str(smk.rule), dataset, entry)
        if overrun:
            print(f"spa: memory overrun: {overrun}", file=sys.stderr)


def cluster_cost(records: Sequence[Mapping[str, Any]]) -> dict[str, Any]:
    """What a run's datasets cost where they ran, from their execution records.

    Parameters
    ----------
    records : sequence of mapping
        Execution records (:func:`read_execution`), one per dataset.

    Returns
    -------
    dict
        ``jobs`` (count), ``job_hours`` (sum of elapsed times), ``peak_mem_mb`` (largest),
        ``executors`` (sorted names), ``slurm_jobs`` (distinct SLURM job ids: the
        submissions), ``nodes`` (sorted) and ``overruns`` (:func:`memory_overrun` sentences).
    """
    entries = [
        (str(rec.get("dataset", "?")), str(rule), entry)
        for rec in records
        for rule, entry in rec.get("jobs", {}).items()
        if isinstance(entry, Mapping)
    ]
    peaks = [float(e["peak_mem_mb"]) for _, _, e in entries if e.get("peak_mem_mb") is not None]
    overruns = [memory_overrun(rule, ds, e) for ds, rule, e in entries]
    return {
        "jobs": len(entries),
        "job_hours": sum(float(e.get("elapsed_s") or 0.0) for _, _, e in entries) / 3600.0,
        "peak_mem_mb": max(peaks, default=None),
        "executors": sorted({str(e.get("executor")) for _, _, e in entries}),
        "slurm_jobs": len({e["slurm_job_id"] for _, _, e in entries if e.get("slurm_job_id")}),
        "nodes": sorted({str(e.get("node")) for _, _, e in entries}),
        "overruns": [o for o in overruns if o],
    }
