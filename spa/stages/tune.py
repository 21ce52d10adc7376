"""The tune stage's files: Tables 1-2, Figs. 4-5 and ``recommendation.yaml`` (Section 5)."""

from __future__ import annotations

from typing import Any

from spa.io import dump_yaml, write_csv
from spa.plots.save import draw
from spa.plots.tuning import plot_tuning_equilibrium, plot_tuning_sweeps
from spa.tuning.valve import TuningResult

__all__ = ["write_tuning"]


def write_tuning(result: TuningResult, out: Any, dataset: str) -> None:
    """Write :func:`spa.tuning.tune`'s tables, figures' data (and figures where drawn) and
    recommendation.

    Parameters
    ----------
    result : TuningResult
        :func:`spa.tuning.tune`'s.
    out : mapping-like
        Output key to path (``snakemake.output``, or a dict): ``table1``, ``table2``,
        ``fig4_csv``, ``fig5_csv``, ``recommendation`` and ``fig4``, ``fig5`` where drawn.
    dataset : str
        The dataset's name, Fig. 4's title.
    """
    write_csv(result.table1, out.get("table1"))
    write_csv(result.table2, out.get("table2"))
    write_csv(result.sweeps, out.get("fig4_csv"))
    params = result.identified.params
    draw(out.get("fig4"), plot_tuning_sweeps, result.sweeps, title=dataset, params=params)
    write_csv(result.curves, out.get("fig5_csv"))
    draw(out.get("fig5"), plot_tuning_equilibrium, result.curves)
    with open(out.get("recommendation"), "w") as fh:
        dump_yaml(dict(result.recommendation), fh, sort_keys=False, allow_unicode=True)
