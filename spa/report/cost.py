"""The report index's "Where it ran": a cluster run's cost, from the datasets' execution records.

Each dataset's jobs record where and how they ran (:mod:`spa.pipeline.execution`). When any
ran under SLURM, the index shows the run's jobs, SLURM submissions, nodes, job-hours, largest
peak memory and the jobs that used more memory than they asked for. A run on one machine shows
nothing, so that its report stays the same bytes for the same inputs (times differ between
runs; a cluster run's index is provenance, like the records it sums).
"""

from __future__ import annotations

import html
from collections.abc import Sequence
from pathlib import Path

from spa.pipeline.execution import cluster_cost, execution_path, read_execution

__all__ = ["cost_html"]


def cost_html(results_dir: str | Path, datasets: Sequence[str]) -> str:
    """HTML of the run's cluster cost, or ``""`` when no dataset's job ran under SLURM.

    Parameters
    ----------
    results_dir : str or Path
        The results folder.
    datasets : sequence of str
        The run's datasets.

    Returns
    -------
    str
    """
    records = [read_execution(execution_path(results_dir, name)) for name in datasets]
    cost = cluster_cost(records)
    if "slurm" not in cost["executors"]:
        return ""
    e = html.escape
    peak = "-" if cost["peak_mem_mb"] is None else f"{cost['peak_mem_mb']:.0f} MB"
    rows = [
        ("executors", ", ".join(cost["executors"])),
        ("dataset jobs", str(cost["jobs"])),
        ("SLURM submissions", str(cost["slurm_jobs"])),
        ("nodes", ", ".join(cost["nodes"])),
        ("job-hours (elapsed)", f"{cost['job_hours']:.3f}"),
        ("largest peak memory of a job", peak),
    ]
    body = (
        "<table>\n"
        + "".join(f"<tr><th>{e(k)}</th><td>{e(v)}</td></tr>\n" for k, v in rows)
        + "</table>\n"
    )
    if cost["overruns"]:
        items = "".join(f"<li>{e(s)}</li>\n" for s in cost["overruns"])
        body += f"<p>Jobs over their memory request:</p>\n<ul>\n{items}</ul>\n"
    body += (
        "<p>Per dataset and job: <code>&lt;dataset&gt;/provenance/execution.json</code> "
        "(executor, SLURM job id, node, elapsed time, peak memory).</p>\n"
    )
    return body
