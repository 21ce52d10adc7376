"""The report page: its sections and items come from the registry of outputs
(spa.pipeline.outputs)."""

from __future__ import annotations

import html
from collections.abc import Collection, Mapping, Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any

import pandas as pd

from spa.io import PNG_DPI, dump_yaml, read_yaml
from spa.pipeline.outputs import STAGES, section_outputs
from spa.pipeline.stage_types import FIGURE, FIGURES, PARAMS, RECOMMENDATION, Output
from spa.pipeline.status import dataset_failures, dataset_statuses
from spa.report.failure import (
    failed_here,
    failure_box,
    no_runs_for,
    no_runs_note,
    skipped_note,
    stage_note,
)
from spa.report.html import (
    STYLE,
    embed_png,
    format_value,
    html_table,
    pair_paper_columns,
    png_size,
    unique_anchor,
)
from spa.report.laws import laws_use_note
from spa.report.params import fits_note, identification_notes, params_table
from spa.report.summary import summary_html
from spa.report.table3 import csv_download, table3_html

__all__ = [
    "build_report",
    "dataset_body",
    "document",
    "meta_list",
    "recommendation_html",
    "section_items",
]

_PAPER = (
    "Serrano-Balbontín et al., Open-Loop Characterisation of Soft Actuator Pressure Regulated "
    "by Pulse-Driven Solenoid Valve, Robotics 2025, 14(12), 177."
)


_TABLE3 = "staircase/table3.csv"  # shown grouped and narrowed (spa.report.table3)


def section_items(section: str, folder: str | Path) -> list[Output]:
    """The tables and figures a report section shows, in order.

    Parameters
    ----------
    section : str
        ``"analytic"`` or ``"dataset"`` (see :func:`spa.pipeline.outputs.section_outputs`).
    folder : str or Path
        The folder the section's paths are relative to: the results folder for
        ``"analytic"``, ``results/<dataset>`` for ``"dataset"``.

    Returns
    -------
    list of Output
        The shown outputs of the section; a folder of figures is replaced by one figure per
        PNG file in it (sorted by name), ``{name}`` in its title and caption filled in.
    """
    items: list[Output] = []
    for out in section_outputs(section):
        if not out.shown:
            continue
        if out.kind != FIGURES:
            items.append(out)
            continue
        title = out.title or ""
        for png in sorted((Path(folder) / out.path).glob("*.png")):
            items.append(
                replace(
                    out,
                    path=f"{out.path}/{png.name}",
                    kind=FIGURE,
                    title=title.format(name=png.stem),
                    caption=out.caption.format(name=png.stem),
                )
            )
    return items


def recommendation_html(rec: Any) -> str:
    """The recommendation as HTML: its sentence, then the recommended setting as the
    ``dataset.yaml`` block of a run that uses it (``recommended.setting`` of
    ``tuning/recommendation.yaml``), then what was left out on the valve (``skipped`` of
    ``closed_loop/controllers.yaml``) or clipped (``intervals_clipped``), each with its reason.

    Examples
    --------
    >>> rec = {"sentence": "Use PWM.", "recommended": {"setting": {"type": "pwm", "f_w": 20.0}}}
    >>> print(recommendation_html(rec))
    <p class="lead">Use PWM.</p><pre>modulator:
      type: pwm
      f_w: 20.0</pre>
    """
    rec = rec if isinstance(rec, Mapping) else {}
    sentence = rec.get("sentence") or rec.get("failed") or "no recommendation"
    body = f'<p class="lead">{html.escape(str(sentence))}</p>'
    best = rec.get("recommended")
    setting = best.get("setting") if isinstance(best, Mapping) else None
    if isinstance(setting, Mapping) and setting:
        block = dump_yaml({"modulator": dict(setting)}, sort_keys=False).rstrip()
        body += f"<pre>{html.escape(block)}</pre>"
    notes = [*dict(rec.get("skipped") or {}).values()]
    notes += [
        f"{k}'s 95 % interval: {v}" for k, v in dict(rec.get("intervals_clipped") or {}).items()
    ]
    if notes:
        items = "".join(f"<li>{html.escape(str(n))}</li>" for n in notes)
        body += (
            f'<p class="note">Left out or adjusted on this valve:</p><ul class="note">{items}</ul>'
        )
    return body


def _render_item(path: Path, item: Output, anchor: str) -> str:
    """``<figure>`` with the table or image of ``path``, its heading and its caption."""
    title = item.title or ""
    caption = item.caption
    attrs = ""
    if item.kind == FIGURE:
        # print resolution (PNG_DPI) shown at 100 CSS px per inch: sharp on high-density screens
        width, height = (max(1, round(n * 100 / PNG_DPI)) for n in png_size(path.read_bytes()))
        alt = html.escape(title)
        body = f'<img src="{embed_png(path)}" alt="{alt}" width="{width}" height="{height}">'
        attrs = f' class="fig" style="max-width:{width + 2}px"'
    elif item.kind == RECOMMENDATION:
        rec = read_yaml(path)
        body = recommendation_html(rec)
        ident = path.parent.parent / "identification" / "params.yaml"
        note = ""
        if isinstance(rec, Mapping) and ident.is_file():
            note = laws_use_note(rec, read_yaml(ident))
        if note:
            body += f'<p class="note">{html.escape(note)}</p>'
    elif item.kind == PARAMS:
        params = read_yaml(path)
        body = f'<div class="scroll">{html_table(params_table(params))}</div>'
        body += "".join(
            f'<p class="note">{html.escape(n)}</p>' for n in identification_notes(params)
        )
        caption += fits_note(params)
    elif item.path == _TABLE3:
        table = pd.read_csv(path)
        link = csv_download(path, "table3.csv", f"the full table ({table.shape[1]} columns)")
        body = f'<div class="scroll">{table3_html(table)}</div>\n<p class="note">Download {link}'
        body += f" as CSV: every column, as in {html.escape(_TABLE3)}.</p>"
    else:
        body = f'<div class="scroll">{html_table(pair_paper_columns(pd.read_csv(path)))}</div>'
    return (
        f'<figure id="{anchor}"{attrs}>\n<h3>{html.escape(title)}</h3>\n{body}\n'
        f"<figcaption>{html.escape(caption)}</figcaption>\n</figure>\n"
    )


def _owners(section: str) -> dict[str, str]:
    """Output path -> the stage that writes it, for a section's outputs."""
    return {o.path: st.name for st in STAGES if st.section == section for o in st.outputs}


def _section(
    folder: Path,
    section: str,
    prefix: str,
    taken: set[str],
    drawn: bool = True,
    states: Mapping[str, Mapping[str, Any] | None] | None = None,
) -> tuple[str, list[tuple[str, str]]]:
    """The HTML of one section's items that exist and its table-of-contents entries; without
    its figures when not ``drawn``.

    ``states`` (stage -> its status record, :func:`spa.pipeline.status.dataset_statuses`):
    the outputs of a stage that failed or was skipped are placeholders, not shown; one line
    naming the stage and its message stands in their place (:func:`spa.report.failure.stage_note`).
    A stage that worked but left a part out names it before its first output
    (:func:`spa.report.failure.skipped_note`). The outputs of a stage (or part) with no runs
    of its kind (its status's ``no_runs``) are not shown: one line says "no runs" in their
    place (:func:`spa.report.failure.no_runs_note`).
    """
    parts: list[str] = []
    toc: list[tuple[str, str]] = []
    owners, states = _owners(section), states or {}
    order = {st.name: i for i, st in enumerate(STAGES)}

    def owner(item: Output) -> str:
        return owners.get(item.path) or owners.get(str(Path(item.path).parent), "")

    def place(item: Output) -> tuple[bool, int]:
        # the key item (Table 3) first when its stage worked; else in its stage's place
        status = states.get(owner(item))
        first = item.key_item and not failed_here(status) and no_runs_for(status, item.path) is None
        return not first, order.get(owner(item), -1)

    noted: set[str] = set()
    for item in sorted(section_items(section, folder), key=place):
        stage = owner(item)
        status = states.get(stage)
        if failed_here(status):
            if stage not in noted:
                noted.add(stage)
                anchor = unique_anchor(f"{prefix}-stage-{stage}", taken)
                parts.append(stage_note(stage, status or {}, anchor))
                what = "not run" if (status or {}).get("upstream") else "failed"
                toc.append((anchor, f"Stage {stage}: {what}"))
            continue
        empty = no_runs_for(status, item.path)
        if empty is not None:  # no runs of its kind: one line, not an empty table or figure
            key = f"{stage}:{empty.get('kind')}"
            if key not in noted:
                noted.add(key)
                anchor = unique_anchor(f"{prefix}-stage-{stage}-no-runs", taken)
                parts.append(no_runs_note(stage, empty, anchor))
                toc.append((anchor, f"Stage {stage}: no runs"))
            continue
        if not drawn and item.kind == FIGURE:
            continue
        path = folder / item.path
        if not path.is_file():
            if item.required:
                raise FileNotFoundError(f"{path}: required by the report but missing")
            continue
        if stage not in noted and skipped_note(stage, status):
            noted.add(stage)
            parts.append(skipped_note(stage, status))
        anchor = unique_anchor(f"{prefix}-{Path(item.path).stem}", taken)
        block = _render_item(path, item, anchor)
        if item.key_item:
            block = f'<div class="key">\n{block}</div>\n'
        parts.append(block)
        toc.append((anchor, item.title or ""))
    return "".join(parts), toc


def dataset_body(
    results: Path,
    name: str,
    anchor: str,
    taken: set[str],
    drawn: bool = True,
    raw: Path | None = None,
) -> tuple[str, list[tuple[str, str]], bool]:
    """A dataset's section: every output its stages made, the failed and skipped stages
    named in their place, and a box naming the failure first when one failed; for a
    verification session (``raw``, the dataset's folder, holds ``verification.csv``), each
    prediction beside its measurement (:func:`spa.report.verification.verification_html`).

    Returns
    -------
    tuple
        The HTML, its table-of-contents entries, and whether a stage failed.
    """
    folder = results / name
    failures = dataset_failures(results, [name])
    states = dataset_statuses(results, name)
    body, toc = _section(folder, "dataset", anchor, taken, drawn, states)
    if raw is not None:
        from spa.report.verification import VERIFICATION_FILE, verification_html

        checked, checked_toc = verification_html(raw / VERIFICATION_FILE, taken, anchor)
        body, toc = body + checked, toc + checked_toc
    body += _mentions(folder, name, states) + ("" if drawn else _NOT_DRAWN)
    if name in failures:
        body = failure_box(failures, pages=False) + body
    return body, toc, name in failures


def _mentions(
    folder: Path, name: str, states: Mapping[str, Mapping[str, Any] | None] | None = None
) -> str:
    """A note naming the long tables of a dataset that the report does not reproduce (not
    those of a stage that failed: placeholders)."""
    owners, states = _owners("dataset"), states or {}
    present = [o.path for o in section_outputs("dataset") if o.mention]
    present = [p for p in present if not failed_here(states.get(owners.get(p, "")))]
    present = [p for p in present if (folder / p).is_file()]
    if not present:
        return ""
    listed = " and ".join(f"{name}/{p}" for p in present)
    return (
        f'<p class="note">Per-level and per-step values: {html.escape(listed)} in the '
        "results folder (not reproduced here).</p>\n"
    )


_NOT_DRAWN = (
    '<p class="note">No figures for this dataset in this run (config <code>figures</code>); '
    "the data of each are beside it as CSV, and <code>--config figures=all</code> or a list "
    "naming this dataset draws them.</p>\n"
)


def build_report(
    results_dir: str | Path,
    datasets: Sequence[str],
    meta: Mapping[str, Any],
    title: str = "spa: reproduction report",
    figures: Collection[str] | None = None,
) -> str:
    """The whole HTML report of a results folder, as a string.

    Parameters
    ----------
    results_dir : str or Path
        The run's results folder, holding ``analytic/`` and one folder per dataset.
    datasets : sequence of str
        The datasets to report, in this order (the workflow's ``DATASETS``).
    meta : mapping
        Shown in the header, in this order (e.g. ``{"seed": 20251128, "spa version":
        "0.1.0"}``); keys and values are HTML-escaped.
    title : str
        The page's title and main heading.
    figures : collection of str, optional
        The datasets whose figures the run drew (config ``figures``, default all): the others'
        sections show their tables alone, whatever figures an earlier run left in their
        folders, and say where the figures' data are.

    Returns
    -------
    str
        A complete HTML5 document. It references nothing outside itself (figures are
        ``data:`` URIs), has no script, and depends only on the files read and the arguments:
        the same inputs give the same string.

    Raises
    ------
    FileNotFoundError
        If a required table or figure (see :data:`spa.pipeline.outputs.STAGES`: Tables 1-2,
        Figs. 4-5, and per dataset ``params.yaml``, Fig. 2a-c and ``validation/fit.csv``) is
        missing.
        Optional outputs (Table 3, Figs. 6-9, sine and chirp tables) are skipped when absent.
    ValueError
        If ``datasets`` is a string or names a dataset twice.
    """
    if isinstance(datasets, str):
        raise ValueError("datasets must be a sequence of dataset names, not one string")
    if len(set(datasets)) != len(datasets):
        raise ValueError(f"datasets names a dataset twice: {list(datasets)}")
    results = Path(results_dir)
    taken: set[str] = {"contents", "analytic", "summary", "summary-table"}
    sections: list[tuple[str, str, str, list[tuple[str, str]]]] = []
    anchors = {name: unique_anchor(f"dataset-{name}", taken) for name in datasets}

    failures = dataset_failures(results, datasets)
    summary = summary_html(results, datasets, failures, {n: f"#{a}" for n, a in anchors.items()})
    sections.append(("summary", "Summary", summary, [("summary-table", "Summary per dataset")]))
    if failures:
        sections.append(("failed", "Failed datasets", failure_box(failures), []))
        taken.add("failed")
    body, toc = _section(results, "analytic", "analytic", taken)
    sections.append(("analytic", "Analytic (averaged model)", body, toc))
    for name in datasets:
        anchor = anchors[name]
        drawn = figures is None or name in figures
        body, toc, failed = dataset_body(results, name, anchor, taken, drawn)
        sections.append((anchor, f"Dataset {name}" + (" (failed)" if failed else ""), body, toc))

    header = f"<p>Tables and figures of one run reproducing {html.escape(_PAPER)}</p>\n"
    header += meta_list({**meta, "datasets": ", ".join(datasets)})
    return document(title, header, sections)


def meta_list(meta: Mapping[str, Any]) -> str:
    """The run's metadata as a definition list; keys and values escaped."""
    e = html.escape
    items = "".join(f"<dt>{e(str(k))}</dt><dd>{e(format_value(v))}</dd>" for k, v in meta.items())
    return f'<dl class="meta">{items}</dl>\n'


def document(
    title: str, header: str, sections: Sequence[tuple[str, str, str, list[tuple[str, str]]]]
) -> str:
    """A complete page: ``header`` (HTML) under the title, a table of contents, the sections.

    Parameters
    ----------
    title : str
        The page's title and main heading (escaped).
    header : str
        HTML shown under the heading.
    sections : sequence of (anchor, heading, body, toc)
        Each section's id, heading (escaped), HTML body and its contents entries
        ``(anchor, text)``.

    Returns
    -------
    str
        An HTML5 document: inline style, no script, nothing outside itself.
    """
    e = html.escape
    nav = "".join(
        f'<li><a href="#{a}">{e(heading)}</a><ol>'
        + "".join(f'<li><a href="#{ia}">{e(it)}</a></li>' for ia, it in toc)
        + "</ol></li>\n"
        for a, heading, _, toc in sections
    )
    content = "".join(
        f'<section id="{a}">\n<h2>{e(heading)}</h2>\n{body}</section>\n'
        for a, heading, body, _ in sections
    )
    return (
        "<!DOCTYPE html>\n"
        '<html lang="en">\n<head>\n<meta charset="utf-8">\n'
        '<meta name="viewport" content="width=device-width, initial-scale=1">\n'
        '<link rel="icon" href="data:,">\n'
        f"<title>{e(title)}</title>\n<style>{STYLE}</style>\n</head>\n<body>\n"
        f"<header>\n<h1>{e(title)}</h1>\n{header}</header>\n"
        f'<nav id="contents">\n<strong>Contents</strong>\n<ol>\n{nav}</ol>\n</nav>\n'
        f"<main>\n{content}</main>\n</body>\n</html>\n"
    )
