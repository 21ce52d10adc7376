"""The closed_loop stage's files: the table, ``controllers.yaml``, Figs. 10-11 and the
recorded runs against their replay (docs/model.md section 8)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pandas as pd

from spa.closedloop.bench import BenchOutputs
from spa.closedloop.stage import ClosedLoopResult, write_controllers
from spa.io import write_csv
from spa.plots.closedloop import fig10, fig11, no_design
from spa.plots.save import draw

__all__ = ["write_closed_loop"]


def write_closed_loop(
    result: ClosedLoopResult,
    recorded: pd.DataFrame,
    out: Any,
    bench: BenchOutputs | None = None,
) -> None:
    """Write :func:`spa.closedloop.stage.closed_loop`'s outputs and the recorded runs' table.

    Parameters
    ----------
    result : ClosedLoopResult
        The designs and exact simulations.
    recorded : pandas.DataFrame
        :func:`spa.closedloop.stage.recorded_runs`: each closed_loop run against its replay.
    out : mapping-like
        Output key to path (``snakemake.output``, or a dict): ``table``, ``controllers``,
        ``fig10_csv``, ``fig11_csv``, ``recorded`` and ``fig10``, ``fig11`` where drawn;
        with ``bench``, also ``robust``, ``header`` and ``sketch``.
    bench : BenchOutputs, optional
        :func:`spa.closedloop.bench.bench_outputs` (already applied to ``result`` with
        :func:`spa.closedloop.bench.apply_bench`).
    """
    write_csv(result.table, out.get("table"))
    write_controllers(result, out.get("controllers"))
    write_csv(result.traces, out.get("fig10_csv"))
    write_csv(result.steps, out.get("fig11_csv"))
    if result.traces.empty:  # nothing designed for this valve: the figures say why
        draw(out.get("fig10"), no_design, result.sentence)
        draw(out.get("fig11"), no_design, result.sentence)
    else:
        draw(out.get("fig10"), fig10, result.traces)
        draw(out.get("fig11"), fig11, result.steps)
    write_csv(recorded, out.get("recorded"))
    if bench is not None:
        write_csv(bench.robust, out.get("robust"))
        Path(out.get("header")).write_text(bench.header, encoding="utf-8")
        Path(out.get("sketch")).write_text(bench.sketch, encoding="utf-8")
