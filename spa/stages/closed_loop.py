"""The closed_loop stage's files: the table, ``controllers.yaml``, Figs. 10-11 and the
recorded runs against their replay (docs/model.md section 8)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import pandas as pd

from spa.closedloop.bench import BenchOutputs
from spa.closedloop.comparison import ClosedLoopResult, write_controllers
from spa.closedloop.promise import design_for_dataset
from spa.closedloop.replay import recorded_runs
from spa.datasets import read_runs
from spa.identification.identified import read_identified
from spa.io import read_yaml, write_csv
from spa.plots.closedloop import fig10, fig11, no_design
from spa.plots.save import draw

__all__ = ["close_dataset_loop", "write_closed_loop"]


def close_dataset_loop(
    params_path: str | Path,
    recommendation_path: str | Path,
    run_paths: str | Path,
    selected: Sequence[Mapping[str, Any]],
    cfg: Mapping[str, Any],
) -> tuple[ClosedLoopResult, pd.DataFrame, BenchOutputs]:
    """The closed_loop stage's work for one dataset, from its files
    (:func:`spa.closedloop.promise.design_for_dataset` on them).

    Designs the PIs for the identified valve (:func:`spa.closedloop.comparison.closed_loop`),
    measures the model's error on the dataset's runs
    (:func:`spa.closedloop.model_error.dataset_error`), checks the chosen loop over the 95 %
    box merged with that error and exports it (:func:`spa.closedloop.bench.bench_outputs`),
    and replays the recorded closed-loop runs.

    Parameters
    ----------
    params_path : str or pathlib.Path
        The identification's ``params.yaml``.
    recommendation_path : str or pathlib.Path
        The tuning's ``recommendation.yaml`` (may be missing: no recommendation).
    run_paths : str or pathlib.Path
        The dataset's ``runs/`` folder of run tables (Parquet, :func:`spa.datasets.read_runs`).
    selected, cfg
        The settings compared and the ``closed_loop:`` section of the config.

    Returns
    -------
    result : ClosedLoopResult
        With the bench outputs applied.
    recorded : pandas.DataFrame
        Each recorded closed-loop run against its replay.
    bench : BenchOutputs
    """
    rec_path = Path(recommendation_path)
    # {} rather than None: without a recommendation the stage compares the selected settings
    # alone (design_for_dataset reads None as "take the adequacy from params.yaml")
    recommendation = read_yaml(rec_path) if rec_path.is_file() else {}
    identified = read_yaml(params_path)
    valve = read_identified(identified)  # the stage's valve, read once where it enters
    runs, metas = read_runs(run_paths)
    result, bench = design_for_dataset(
        identified, runs, metas, selected, cfg, recommendation=recommendation, valve=valve
    )
    return result, recorded_runs(runs, metas, valve.params), bench


def write_closed_loop(
    result: ClosedLoopResult,
    recorded: pd.DataFrame,
    out: Any,
    bench: BenchOutputs | None = None,
) -> None:
    """Write :func:`spa.closedloop.comparison.closed_loop`'s outputs and the recorded runs' table.

    Parameters
    ----------
    result : ClosedLoopResult
        The designs and exact simulations.
    recorded : pandas.DataFrame
        :func:`spa.closedloop.replay.recorded_runs`: each closed_loop run against its replay.
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
