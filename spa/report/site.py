"""The report as a small static site: an index, one page per dataset, one analytic page.

``results/report/<dataset>.html`` is built in that dataset's own job
(:func:`build_dataset_page`), so adding or changing a dataset re-renders its page and the
index alone; ``results/report/analytic.html`` holds the analytic section
(:func:`build_analytic_page`); ``results/report/index.html`` (:func:`build_index`) has the run's
header, the failed datasets first, the summary with a link to each page, the overview across
datasets (Fig. O1 and ``overview.csv``, section ``"overview"`` of the registry of outputs) and
the list of pages. ``results/report.html`` is the same index with its links into
``report/``. Each page follows the rules of :mod:`spa.report`: offline, no script, its figures
embedded, captions, the same bytes for the same inputs. The index embeds one figure (Fig. O1)
and reads a few small files per dataset: its size and its job's memory hardly grow with the
number of datasets. The report job removes the pages of datasets no longer in the run
(:func:`remove_stale_pages`): a stale page is not served as current.
"""

from __future__ import annotations

import html
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from spa.pipeline.status import dataset_failures
from spa.report.build import _PAPER, _section, dataset_body, document, meta_list
from spa.report.cost import cost_html
from spa.report.failure import failure_box
from spa.report.summary import summary_html

__all__ = [
    "INDEX",
    "build_analytic_page",
    "build_dataset_page",
    "build_index",
    "page_name",
    "remove_stale_pages",
]

INDEX = "index.html"
"""The index page's file name in ``results/report/``."""
_ANALYTIC = "analytic.html"
RESERVED = ("index", "analytic")
"""Names a dataset cannot have: their pages would be the index's and the analytic page's."""


def page_name(dataset: str) -> str:
    """The file name of a dataset's page, ``<dataset>.html``.

    Raises
    ------
    ValueError
        If the dataset is called ``index`` or ``analytic`` (the site's own pages).
    """
    if dataset in RESERVED:
        raise ValueError(
            f"a dataset cannot be called {dataset!r}: report/{dataset}.html is the site's"
        )
    return f"{dataset}.html"


_PAGE_MARK = "<title>spa: dataset "
"""What the head of every dataset's page holds (:func:`build_dataset_page`'s title)."""


def remove_stale_pages(report_dir: str | Path, datasets: Sequence[str]) -> list[Path]:
    """Remove the pages of datasets that are no longer in the run (no longer in raw/).

    A stale page would be served as current beside the index that no longer lists it, so it
    goes. Only files directly in ``report_dir`` (``results/report/``) named ``<name>.html``
    whose head is a dataset's page of this report (its ``<title>spa: dataset ...``) are
    removed; the index, the analytic page, the run's datasets' pages and any other file stay.
    The dataset's results folder (``results/<name>/``) is left alone, and nothing outside
    ``report_dir`` is touched (raw/ never).

    Parameters
    ----------
    report_dir : str or Path
        The report's folder, ``results/report``.
    datasets : sequence of str
        The run's datasets: their pages are kept.

    Returns
    -------
    list of Path
        The removed pages, sorted.
    """
    folder = Path(report_dir)
    keep = {INDEX, _ANALYTIC, *(f"{name}.html" for name in datasets)}
    removed = []
    for path in sorted(folder.glob("*.html")) if folder.is_dir() else []:
        if path.name in keep or path.is_symlink() or not path.is_file():
            continue
        with path.open("rb") as handle:
            head = handle.read(16384).decode("utf-8", errors="replace")
        if _PAGE_MARK in head:
            path.unlink()
            removed.append(path)
    return removed


def _back(prefix: str = "") -> str:
    return (
        f'<p class="note"><a href="{prefix}{INDEX}">Index of the run</a> · '
        f'<a href="{prefix}{_ANALYTIC}">Analytic (averaged model)</a></p>\n'
    )


def build_dataset_page(
    results_dir: str | Path,
    dataset: str,
    meta: Mapping[str, Any],
    drawn: bool = True,
    raw_dir: str | Path | None = None,
) -> str:
    """One dataset's page: every table and figure its stages made; a stage that failed is
    named with its one-line message, first in a box and in its outputs' place
    (:func:`spa.report.build.dataset_body`).

    Parameters
    ----------
    results_dir : str or Path
        The results folder (the dataset's outputs are in ``<results_dir>/<dataset>``).
    dataset : str
        The dataset.
    meta : mapping
        Shown in the header (e.g. seed and spa version).
    drawn : bool
        False: the run draws no figures for it (config ``figures``): its tables alone,
        whatever figures an earlier run left.
    raw_dir : str or Path, optional
        The raw folder: a verification session's ``<raw_dir>/<dataset>/verification.csv``
        (``spa record``) adds its predictions beside their measurements.

    Returns
    -------
    str
        A complete HTML document, self-contained (figures as ``data:`` URIs).

    Raises
    ------
    FileNotFoundError
        If a required output of a stage that did not fail is missing.
    """
    anchor = "dataset"
    body, toc, failed = dataset_body(
        Path(results_dir),
        dataset,
        anchor,
        {"contents", anchor},
        drawn,
        None if raw_dir is None else Path(raw_dir) / dataset,
    )
    heading = f"Dataset {dataset}" + (" (failed)" if failed else "")
    header = _back() + meta_list({**meta, "dataset": dataset})
    return document(f"spa: dataset {dataset}", header, [(anchor, heading, body, toc)])


def build_analytic_page(results_dir: str | Path, meta: Mapping[str, Any]) -> str:
    """The analytic page: Tables 1-2 and Figs. 4-5 of the averaged model (section
    ``"analytic"`` of the registry of outputs).

    Raises
    ------
    FileNotFoundError
        If a required analytic output is missing.
    """
    body, toc = _section(Path(results_dir), "analytic", "analytic", {"contents", "analytic"})
    header = _back() + meta_list(meta)
    return document("spa: analytic (averaged model)", header, [("analytic", "Analytic", body, toc)])


def build_index(
    results_dir: str | Path,
    datasets: Sequence[str],
    meta: Mapping[str, Any],
    prefix: str = "",
    title: str = "spa: reproduction report",
) -> str:
    """The index of the run: header, failed datasets, summary, overview, pages, and where it
    ran when that was a SLURM cluster (:func:`spa.report.cost.cost_html`).

    Parameters
    ----------
    results_dir : str or Path
        The results folder.
    datasets : sequence of str
        The datasets, in the run's order.
    meta : mapping
        Shown in the header.
    prefix : str
        Where the pages are, relative to the index: ``""`` for ``report/index.html``,
        ``"report/"`` for ``report.html``.
    title : str
        The page's title and heading.

    Returns
    -------
    str
        A complete HTML document; it embeds Fig. O1 alone, no dataset's figures.

    Raises
    ------
    ValueError
        If ``datasets`` is a string, names a dataset twice, or names ``index`` or
        ``analytic``.
    """
    if isinstance(datasets, str):
        raise ValueError("datasets must be a sequence of dataset names, not one string")
    if len(set(datasets)) != len(datasets):
        raise ValueError(f"datasets names a dataset twice: {list(datasets)}")
    results = Path(results_dir)
    links = {name: prefix + page_name(name) for name in datasets}
    failures = dataset_failures(results, datasets)
    sections: list[tuple[str, str, str, list[tuple[str, str]]]] = []
    e = html.escape
    if failures:
        sections.append(("failed", "Failed datasets", failure_box(failures), []))
    summary = summary_html(results, datasets, failures, links)
    sections.append(("summary", "Summary", summary, [("summary-table", "Summary per dataset")]))
    taken = {"contents", "failed", "summary", "summary-table", "overview", "pages"}
    body, toc = _section(results, "overview", "overview", taken)
    sections.append(("overview", "Overview across datasets", body, toc))
    pages = [(prefix + _ANALYTIC, "Analytic (averaged model): Tables 1-2, Figs. 4-5")]
    pages += [(links[n], f"Dataset {n}" + (" (failed)" if n in failures else "")) for n in datasets]
    items = "".join(f'<li><a href="{e(href)}">{e(text)}</a></li>\n' for href, text in pages)
    sections.append(("pages", "Pages", f'<ol class="pages">\n{items}</ol>\n', []))
    cost = cost_html(results, datasets)  # "" unless the datasets ran under SLURM
    if cost:
        sections.append(("where", "Where it ran", cost, []))
    header = f"<p>Tables and figures of one run reproducing {e(_PAPER)}</p>\n"
    header += meta_list({**meta, "datasets": f"{len(datasets)}"})
    return document(title, header, sections)
