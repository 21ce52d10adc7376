"""The report's opening summary: one row per dataset with what a user came for.

Per dataset: the identified valve parameters with their 95 % intervals
(``identification/params.yaml``), the validation FIT over its runs (``validation/fit.csv``)
and the recommended modulator (``tuning/recommendation.yaml``), each when its stage worked; a
dataset with a failed stage (:func:`spa.pipeline.status.dataset_failures`) also gets the
stage that failed and its first errors.
"""

from __future__ import annotations

import html
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import pandas as pd

from spa.io import read_yaml
from spa.pipeline.status import dataset_statuses
from spa.report.failure import failed_here, first_failure, one_line
from spa.report.html import format_value
from spa.report.params import PARAM_NAMES

__all__ = ["SUMMARY_CAPTION", "fit_summary", "param_cell", "summary_html"]

# Shown in ms: the delays are milliseconds.
_SCALE = {"t_on": (1e3, "ms"), "t_off": (1e3, "ms")}
_UNITS = {"c1": "s·bar^-0.5", "k2": "bar", "tau2": "s"}

SUMMARY_CAPTION = (
    "Per dataset: each identified valve parameter, its 95 % interval below it; the validation "
    "FIT (every run re-simulated with those parameters): median over the runs and the lowest, "
    "with its run; the modulator setting the tuning recommends for this valve and its "
    "linearity cost J. A dataset with a failed stage shows what its other stages made, the "
    "stage that failed and its first errors."
)
"""The summary table's caption."""


def param_cell(entry: Mapping[str, Any], name: str) -> str:
    """One parameter as HTML: value, and its 95 % interval on a second line.

    Examples
    --------
    >>> print(param_cell({"value": 0.0034568, "lo": 0.0027, "hi": 0.0042}, "t_on"))
    3.457<br><small>[2.7, 4.2]</small>
    """
    scale = _SCALE.get(name, (1.0, ""))[0]
    value, lo, hi = (format_value(float(entry[k]) * scale) for k in ("value", "lo", "hi"))
    fallback = " (nominal)" if entry.get("fallback") else ""
    return (
        f"{html.escape(value)}{fallback}<br><small>[{html.escape(lo)}, {html.escape(hi)}]</small>"
    )


def fit_summary(fit: pd.DataFrame) -> str:
    """The validation FIT of a dataset in a few words: median and lowest (with its run).

    Examples
    --------
    >>> fit_summary(pd.DataFrame({"run": ["a", "b", "c"], "fit_percent": [90.0, 80.0, 70.5]}))
    'median 80 %, lowest 70.5 % (c), 3 runs'
    """
    values = pd.to_numeric(fit.get("fit_percent"), errors="coerce")
    if values is None or values.dropna().empty:
        return "no runs"
    worst = int(values.idxmin())
    median = format_value(float(values.median()))
    return (
        f"median {median} %, lowest {format_value(float(values[worst]))} % "
        f"({fit['run'].iloc[worst]}), {int(values.notna().sum())} runs"
    )


def _recommendation(path: Path) -> str:
    if not path.is_file():
        return "not tuned"
    rec = read_yaml(path) or {}
    best = rec.get("recommended")
    if isinstance(best, Mapping) and best.get("description"):
        cost = f" (J = {format_value(best['J'])} bar)" if "J" in best else ""
        return f"{best['description']}{cost}"
    return str(rec.get("failed") or rec.get("sentence") or "no recommendation")


def _stage_failed(status: Mapping[str, Any] | None) -> str:
    """``" (stage tune failed)"``, ``" (stage identify failed)"`` for a skipped one, or ``""``."""
    if status is None or not failed_here(status):
        return ""
    return f" (stage {status.get('upstream') or status.get('stage')} failed)"


def _failed_note(name: str, records: list[dict[str, Any]]) -> str:
    """``FAILED at stage <code>x</code> (log: ...)`` and its first errors, one line each."""
    e = html.escape
    first = first_failure(records)
    errors = "".join(f"<li><code>{e(one_line(x))}</code></li>" for x in first["errors"][:3])
    return (
        f"FAILED at stage <code>{e(str(first['stage']))}</code> (log: logs/{e(name)}/)"
        f"<ul>{errors}</ul>"
    )


def _dataset_row(
    results: Path, name: str, link: str, records: list[dict[str, Any]] | None = None
) -> str:
    """A dataset's row: what each stage that worked made, and the stage that failed.

    The parameters are shown when identification worked, whatever failed after it; the
    validation FIT and the recommendation when their stages worked; a dataset with a failed
    stage has ``FAILED at stage ...`` in its last cell (in place of everything, when it was
    not identified).
    """
    e = html.escape
    folder = results / name
    states = dataset_statuses(results, name)
    head = f'<th scope="row"><a href="{e(link)}">{e(name)}</a></th>'
    if records and failed_here(states.get("identify")):
        width = len(PARAM_NAMES) + 2
        note = _failed_note(name, records)
        return f'<tr class="failed">{head}<td class="text" colspan="{width}">{note}</td></tr>\n'
    params = read_yaml(folder / "identification" / "params.yaml")
    cells = [head]
    cells += [f'<td class="num">{param_cell(params[n], n)}</td>' for n in PARAM_NAMES]
    fit_path = folder / "validation" / "fit.csv"
    if failed_here(states.get("validate_model")) or not fit_path.is_file():
        fit = "not validated" + _stage_failed(states.get("validate_model"))
    else:
        fit = fit_summary(pd.read_csv(fit_path))
    cells.append(f'<td class="text">{e(fit)}</td>')
    if failed_here(states.get("tune")):
        rec = e("not tuned" + _stage_failed(states.get("tune")))
    else:
        rec = e(_recommendation(folder / "tuning" / "recommendation.yaml"))
    if records:
        rec += f'<div class="failed">{_failed_note(name, records)}</div>'
    cells.append(f'<td class="text">{rec}</td>')
    kind = ' class="failed"' if records else ""
    return f"<tr{kind}>{''.join(cells)}</tr>\n"


def summary_html(
    results: str | Path,
    datasets: Sequence[str],
    failures: Mapping[str, list[dict[str, Any]]],
    links: Mapping[str, str],
) -> str:
    """The summary ``<figure>``: a table of one row per dataset, and its caption.

    Parameters
    ----------
    results : str or Path
        The results folder.
    datasets : sequence of str
        The datasets, in report order.
    failures : mapping
        :func:`spa.pipeline.status.dataset_failures` of the run.
    links : mapping of str to str
        Dataset -> where its section or page is (``#<id>`` or ``<dataset>.html``): its name
        links there.

    Returns
    -------
    str
        HTML; every text escaped.
    """
    e = html.escape
    head = "".join(
        f"<th>{n} ({_SCALE[n][1] if n in _SCALE else _UNITS[n]})</th>" for n in PARAM_NAMES
    )
    rows = [_dataset_row(Path(results), n, links[n], failures.get(n)) for n in datasets]
    return (
        '<figure id="summary-table">\n<h3>Summary per dataset</h3>\n<div class="scroll">'
        f'<table class="summary">\n<thead><tr><th>dataset</th>{head}<th>validation FIT</th>'
        f"<th>recommended modulator</th></tr></thead>\n<tbody>\n{''.join(rows)}</tbody>\n"
        f"</table></div>\n<figcaption>{e(SUMMARY_CAPTION)}</figcaption>\n</figure>\n"
    )
