"""The body of an open-loop stage's workflow script: read the runs, run, write, record.

``workflow/scripts/{staircase,sine,chirp}.py`` are each one call of :func:`run_open_loop`
with their stage's two functions (``run_<stage>``, ``write_<stage>``).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from spa.datasets import read_runs
from spa.io import get_logger, read_params
from spa.pipeline.status import NoRuns, run_stage
from spa.stages._common import OpenLoopInputs

__all__ = ["run_open_loop"]


def run_open_loop(
    smk: Any, stage: str, run: Callable[..., Any], write: Callable[..., None]
) -> bool:
    """Run an open-loop stage in a workflow job and record its status.

    Parameters
    ----------
    smk : snakemake.script.Snakemake
        The job: ``input.runs``, ``input.params``, ``params.cfg``, ``output``, ``log``.
    stage : str
        The stage's name (``staircase``, ``sine``, ``chirp``): its logger and its status.
    run : callable
        ``run_<stage>(inputs, log)`` with the stage's
        :class:`~spa.stages._common.OpenLoopInputs`: its tables.
    write : callable
        ``write_<stage>(result, output, dataset, log)``: its files.

    Returns
    -------
    bool
        :func:`spa.pipeline.status.run_stage`'s: True when the stage ran and succeeded. A
        dataset without runs of the stage's kind succeeds with
        :class:`~spa.pipeline.status.NoRuns` in its status (the report says "no runs").
    """
    log = get_logger(stage, smk.log[0])

    def work() -> list | None:
        runs, metas = read_runs(smk.input.runs)
        inputs = OpenLoopInputs(runs, metas, read_params(smk.input.params), smk.params.cfg)
        result = run(inputs, log)
        write(result, smk.output, smk.wildcards.dataset, log)
        notes = list(getattr(result, "warnings", None) or [])
        if getattr(result, "empty", False):  # no runs of its kind: said, not "ok"
            notes.append(NoRuns(stage))
        return notes or None

    return run_stage(smk, stage, work, log)
