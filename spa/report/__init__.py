"""The HTML report of a ``reproduce-all`` run: a small static site, every page self-contained.

Each page opens offline in any browser: figures are PNGs embedded as base64 ``data:`` URIs,
tables are rendered from the CSV files, the style is one inline ``<style>`` block, and there
is no JavaScript and no reference to anything outside the file but links to the other pages.
The same results give the same bytes: nothing depends on the clock, the host or where the
results folder lives.

The site (:mod:`spa.report.site`): ``results/report/<dataset>.html`` per dataset (built in
that dataset's job: Table 3 first when present, the identified parameters, Fig. 2, the
tuning, the validation table and figures, then the staircase, sine and chirp outputs),
``results/report/analytic.html`` (Tables 1-2, Figs. 4-5) and the index
(``results/report/index.html``, and ``results/report.html`` with its links into ``report/``):
the run's header, the failed datasets, a summary row per dataset and the overview across
datasets (:mod:`spa.report.overview`, Fig. O1). What each page shows, in which order and
with which caption, is the registry of outputs (:data:`spa.pipeline.outputs.STAGES`).
:func:`build_report` builds the whole run as one page (a small run, a notebook).

Modules: :mod:`spa.report.html` (cells, tables, embedded figures, style),
:mod:`spa.report.params` (the identified-parameter table), :mod:`spa.report.build` (sections,
the one-page report), :mod:`spa.report.site` (the pages of the site),
:mod:`spa.report.overview` (the overview across datasets).
"""

# The names imported here and left out of __all__ stay importable for the code that uses them.
# ruff: noqa: F401
from spa.report.build import build_report, section_items
from spa.report.html import (
    PAPER_PREFIX,
    embed_png,
    format_value,
    html_table,
    pair_paper_columns,
    png_size,
)
from spa.report.params import PARAM_NAMES, params_table
from spa.report.site import build_analytic_page, build_dataset_page, build_index

#: The one-page report a notebook can build; the site's pages and HTML helpers are the
#: pipeline's (the API reference's "Internals").
__all__ = ["build_report"]
