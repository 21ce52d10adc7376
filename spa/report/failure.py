"""What the report says about a dataset whose stage failed: a failed stage hides nothing.

A dataset's page shows the outputs of every stage that worked. In place of a failed stage's
outputs (placeholders, :func:`spa.pipeline.status.write_placeholder`) it names the stage and
its one-line message; a stage skipped because an earlier one failed says so in one line
(:func:`stage_note`). The box naming the failure (:func:`failure_box`, on the page and in the
index's *Failed datasets*) says "fix the data" only when the data is at fault, that is when
validation fails: the stage recorded ``"fault": "data"`` (:func:`spa.pipeline.status.fault_of`,
by the error's class). Data that ``spa validate`` accepts but that lack what a stage needs
(``"fault": "lacking"``: an identification that the runs cannot support) get what they lack,
in the error's own words, and that validation passed; otherwise the box says that the stage
failed on data the earlier stages accepted, and where its log is.
"""

from __future__ import annotations

import html
from collections.abc import Mapping
from pathlib import PurePosixPath
from typing import Any

from spa.pipeline.outputs import STAGES

__all__ = [
    "failed_here",
    "failure_box",
    "first_failure",
    "no_runs_for",
    "no_runs_note",
    "one_line",
    "skipped_note",
    "stage_note",
]

_MAX_CHARS = 400


def one_line(text: Any) -> str:
    """The first non-empty line of an error message, at most 400 characters.

    Examples
    --------
    >>> one_line("raw/d: 2 error(s) in dataset:\\n  error: runs.csv: no column p")
    'raw/d: 2 error(s) in dataset:'
    >>> one_line("")
    'no message'
    """
    lines = [line.strip() for line in str(text).splitlines() if line.strip()]
    if not lines:
        return "no message"
    first = lines[0]
    return first if len(first) <= _MAX_CHARS else first[: _MAX_CHARS - 1] + "…"


def _label(stage: str) -> str:
    """``<code>tune</code> (Tuning)``: the stage and its category, escaped."""
    category = next((s.category for s in STAGES if s.name == stage), "")
    name = f"<code>{html.escape(stage)}</code>"
    return f"{name} ({html.escape(category)})" if category else name


def failed_here(status: Mapping[str, Any] | None) -> bool:
    """Whether a status record says the stage failed or was skipped (its outputs are
    placeholders); None (the stage did not run) is not.

    Examples
    --------
    >>> failed_here({"ok": False}), failed_here({"ok": True}), failed_here(None)
    (True, False, False)
    """
    return status is not None and not status.get("ok", False)


def first_failure(records: list[dict[str, Any]]) -> dict[str, Any]:
    """The stage that failed itself (not skipped for an earlier one), from
    :func:`spa.pipeline.status.dataset_failures`'s records of a dataset."""
    return next((r for r in records if not r.get("upstream")), records[0])


def stage_note(stage: str, status: Mapping[str, Any], anchor: str) -> str:
    """One line in place of the outputs of a stage that failed or was skipped.

    Examples
    --------
    >>> print(stage_note("tune", {"ok": False, "errors": ["TuningError: t_on <= 0"]}, "a"), end="")
    <p class="note stage-failed" id="a">Stage <code>tune</code> (Tuning) failed: <code>TuningError: t_on &lt;= 0</code>; its outputs are not shown.</p>
    >>> print(stage_note("sine", {"ok": False, "upstream": "identify"}, "b"), end="")
    <p class="note stage-skipped" id="b">Stage <code>sine</code> (Sine) not run: stage <code>identify</code> failed.</p>
    """  # noqa: E501
    upstream = status.get("upstream")
    if upstream:
        return (
            f'<p class="note stage-skipped" id="{anchor}">Stage {_label(stage)} not run: '
            f"stage <code>{html.escape(str(upstream))}</code> failed.</p>\n"
        )
    errors = status.get("errors") or [""]
    message = html.escape(one_line(errors[0]))
    return (
        f'<p class="note stage-failed" id="{anchor}">Stage {_label(stage)} failed: '
        f"<code>{message}</code>; its outputs are not shown.</p>\n"
    )


def no_runs_for(status: Mapping[str, Any] | None, path: str) -> dict[str, Any] | None:
    """The ``no_runs`` record of a stage's status (:class:`spa.pipeline.status.NoRuns`) that
    covers the output ``path`` (relative to ``results/<dataset>``), or None: that output is
    an empty table or a figure saying "no runs", not shown.

    Examples
    --------
    >>> status = {"ok": True, "no_runs": [{"kind": "staircase", "message": "no staircase "
    ...     "runs in this dataset", "paths": []}]}
    >>> no_runs_for(status, "staircase/table3.csv")["kind"]
    'staircase'
    >>> no_runs_for({"ok": True}, "staircase/table3.csv") is None
    True
    """
    for record in (status or {}).get("no_runs") or []:
        if not isinstance(record, Mapping):
            continue
        paths = [str(p) for p in record.get("paths") or []]
        if not paths or path in paths or str(PurePosixPath(path).parent) in paths:
            return dict(record)
    return None


def no_runs_note(stage: str, record: Mapping[str, Any], anchor: str) -> str:
    """One line in place of the outputs of a stage (or part of one) with no runs of its kind.

    Examples
    --------
    >>> print(no_runs_note("sine", {"message": "no sine runs in this dataset"}, "a"), end="")
    <p class="note stage-no-runs" id="a">Stage <code>sine</code> (Sine): no sine runs in this dataset; nothing to show.</p>
    """  # noqa: E501
    message = html.escape(str(record.get("message") or "no runs"))
    return (
        f'<p class="note stage-no-runs" id="{anchor}">Stage {_label(stage)}: {message}; '
        "nothing to show.</p>\n"
    )


def skipped_note(stage: str, status: Mapping[str, Any] | None) -> str:
    """One line naming the parts a stage that worked left out on this dataset, with why
    (its status's ``skipped``, :class:`spa.pipeline.status.Skipped`); ``""`` when none.

    Examples
    --------
    >>> print(skipped_note("sine", {"ok": True, "skipped": {"linear reference": "no tau_m"}}), end="")
    <p class="note stage-partial">Stage <code>sine</code> (Sine): linear reference skipped: no tau_m. The runs are analysed as recorded.</p>
    >>> skipped_note("sine", {"ok": True})
    ''
    """  # noqa: E501
    parts = dict((status or {}).get("skipped") or {})
    if not parts or failed_here(status):
        return ""
    said = "; ".join(f"{part} skipped: {why}" for part, why in parts.items())
    return (
        f'<p class="note stage-partial">Stage {_label(stage)}: {html.escape(said)}. '
        "The runs are analysed as recorded.</p>\n"
    )


def _advice(name: str, first: Mapping[str, Any]) -> str:
    """Fix the data when validation fails; say what the data lack when they passed it but
    the stage needs more; else say the stage failed on accepted data.

    Examples
    --------
    >>> print(_advice("d", {"fault": "lacking", "errors": ["IdentificationError: no charge run"]}))
    <code>spa validate raw/d</code> accepts this dataset, so the data are not at fault: they lack what the stage needs: <code>IdentificationError: no charge run</code> Record what it names and run <code>snakemake reproduce-all</code> again.
    """  # noqa: E501
    e = html.escape
    if first.get("fault") == "lacking":
        lack = one_line((first.get("errors") or [""])[0])
        return (
            f"<code>spa validate raw/{e(name)}</code> accepts this dataset, so the data are not "
            f"at fault: they lack what the stage needs: <code>{e(lack)}</code> Record what it "
            "names and run <code>snakemake reproduce-all</code> again."
        )
    if first.get("fault") == "data":
        return (
            "The data is at fault: fix it (check a bench dataset with <code>spa validate "
            f"raw/{e(name)}</code>) and run <code>snakemake reproduce-all</code> again."
        )
    return (
        "The data is not known to be at fault: the stage failed on data the earlier stages "
        "accepted (its log has the details)."
    )


def failure_box(failures: Mapping[str, list[dict[str, Any]]], pages: bool = True) -> str:
    """A framed list of datasets with a failed stage: the stage, whose fault, its first
    errors and the stages skipped for it.

    Parameters
    ----------
    failures : mapping
        :func:`spa.pipeline.status.dataset_failures` (dataset -> failed status records).
    pages : bool
        True: the index's box, saying each page keeps what was made; False: one page's own.

    Returns
    -------
    str
        HTML; every text escaped.
    """
    e = html.escape
    items = []
    for name, records in failures.items():
        first = first_failure(records)
        errors = "".join(f"<li><code>{e(str(x))}</code></li>" for x in first["errors"][:5])
        skipped = [r["stage"] for r in records if r.get("upstream")]
        note = f" Not run because of it: {e(', '.join(skipped))}." if skipped else ""
        items.append(
            f"<li><strong>{e(name)}</strong>: stage <code>{e(str(first['stage']))}</code> "
            f"failed; its log is logs/{e(name)}/.{note} {_advice(name, first)}"
            f"<ul>{errors}</ul></li>"
        )
    lead = (
        "These datasets have a stage that failed; the other datasets are complete. Each "
        "dataset's page shows every result its other stages made."
        if pages
        else "A stage of this dataset failed. Every result the other stages made is below."
    )
    return (
        '<div class="key" style="border-color:#a33;background:#fdf3f3">\n'
        f"<p>{lead}</p>\n<ul>{''.join(items)}</ul>\n</div>\n"
    )
