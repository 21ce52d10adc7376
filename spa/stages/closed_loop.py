"""The closed_loop stage's files: the table, ``controllers.yaml``, Figs. 10-11 and the
recorded runs against their replay (docs/model.md section 8)."""

from __future__ import annotations

from typing import Any

import pandas as pd

from spa.closedloop.stage import ClosedLoopResult, write_controllers
from spa.io import write_csv
from spa.plots.closedloop import fig10, fig11
from spa.plots.save import draw

__all__ = ["write_closed_loop"]


def write_closed_loop(result: ClosedLoopResult, recorded: pd.DataFrame, out: Any) -> None:
    """Write :func:`spa.closedloop.stage.closed_loop`'s outputs and the recorded runs' table.

    Parameters
    ----------
    result : ClosedLoopResult
        The designs and exact simulations.
    recorded : pandas.DataFrame
        :func:`spa.closedloop.stage.recorded_runs`: each closed_loop run against its replay.
    out : mapping-like
        Output key to path (``snakemake.output``, or a dict): ``table``, ``controllers``,
        ``fig10_csv``, ``fig11_csv``, ``recorded`` and ``fig10``, ``fig11`` where drawn.
    """
    write_csv(result.table, out.get("table"))
    write_controllers(result, out.get("controllers"))
    write_csv(result.traces, out.get("fig10_csv"))
    draw(out.get("fig10"), fig10, result.traces)
    write_csv(result.steps, out.get("fig11_csv"))
    draw(out.get("fig11"), fig11, result.steps)
    write_csv(recorded, out.get("recorded"))
