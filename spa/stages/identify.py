"""The identify stage's files: ``params.yaml`` and Fig. 2 (paper Section 3.2)."""

from __future__ import annotations

import logging
from collections.abc import Mapping
from typing import Any

import pandas as pd

from spa.identification import IdentificationResult
from spa.identification.results import with_basis
from spa.io import dump_yaml, write_csv
from spa.plots.identification import fig2a, fig2a_data, fig2b, fig2b_data, fig2c, fig2c_data
from spa.plots.laws import laws_data, laws_figure
from spa.plots.openloop import write_no_runs
from spa.plots.save import draw
from spa.plots.words import noted
from spa.validation import validate_run

__all__ = ["write_identification"]

_LOG = logging.getLogger("spa.stages.identify")


def write_identification(
    result: IdentificationResult,
    runs: Mapping[str, pd.DataFrame],
    kinds: Mapping[str, str],
    out: Any,
    dataset: str,
    log: logging.Logger | None = None,
) -> None:
    """Write ``params.yaml`` and the data (and, where drawn, the figures) of Fig. 2a-c.

    Parameters
    ----------
    result : IdentificationResult
        :func:`spa.identification.identify_with_config`'s.
    runs, kinds : mapping
        The dataset's run tables and each run's kind (Fig. 2c replays its first pulse run).
    out : mapping-like
        Output key to path (``snakemake.output``, or a dict): ``params``, ``fig2a_csv``,
        ``fig2b_csv``, ``fig2c_csv``, ``laws_csv`` and the figures ``fig2a``-``fig2c`` and
        ``laws`` where drawn (a key missing from ``out`` is not written).
    dataset : str
        The dataset's name, for the placeholder figures of a missing fit.
    log : logging.Logger, optional
        Where the identified parameters are logged.
    """
    with open(out.get("params"), "w") as fh:
        dump_yaml(with_basis(result.to_dict(), kinds), fh, sort_keys=False)
    (log or _LOG).info("identified %s", result.to_valve_params())
    if result.adequacy:
        (log or _LOG).info("%s", result.adequacy["sentence"])
    fallback = "; ".join(f"{k} from the fallback" for k in result.fallback)
    for data_fn, fig_fn, fit, key, kind in (
        (fig2a_data, fig2a, result.charge, "fig2a", "charge"),
        (fig2b_data, fig2b, result.discharge, "fig2b", "discharge"),
    ):
        png, csv = out.get(key), out.get(f"{key}_csv")
        if fit is None:
            write_no_runs(noted(f"{dataset}: no {kind} fit", fallback), [csv], [png])
            continue
        data = data_fn(fit)
        write_csv(data, csv)
        draw(png, fig_fn, data)
    _write_laws(result.to_dict(), out, dataset)
    pulse_ids = sorted(r for r, k in kinds.items() if k == "pulse")
    if not pulse_ids:
        message = noted(f"{dataset}: no pulse runs", fallback)
        write_no_runs(message, [out.get("fig2c_csv")], [out.get("fig2c")])
        return
    trace = validate_run(runs[pulse_ids[0]], result.to_valve_params()).trace
    data = fig2c_data(trace)
    write_csv(data, out.get("fig2c_csv"))
    draw(out.get("fig2c"), fig2c, data)


def _write_laws(params: Mapping[str, Any], out: Any, dataset: str) -> None:
    """The laws' figure and its data, or a one-line placeholder pointing to why the laws were
    not fitted (``laws: reason`` of ``params.yaml``)."""
    png, csv = out.get("laws"), out.get("laws_csv")
    if png is None and csv is None:
        return
    record = params.get("laws")
    if not isinstance(record, Mapping) or not isinstance(record.get("bands"), Mapping):
        write_no_runs(
            f"{dataset}: the actuator's own laws were not fitted (params.yaml, laws: reason)",
            [csv],
            [png],
        )
        return
    data = laws_data(params)
    write_csv(data, csv)
    draw(png, laws_figure, data)
