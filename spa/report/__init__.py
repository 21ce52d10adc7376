"""One self-contained HTML page with every table and figure of a ``reproduce-all`` run.

The page opens offline in any browser: figures are PNGs embedded as base64 ``data:`` URIs,
tables are rendered from the CSV files, the style is one inline ``<style>`` block, and there
is no JavaScript and no reference to anything outside the file. The same results give the
same bytes: nothing depends on the clock, the host or where the results folder lives.

The report has a header (the run's metadata, e.g. seed and ``spa`` version), a table of
contents with in-page anchors, the analytic section (Tables 1-2, Figs. 4-5), then one section
per dataset: Table 3 first when present, the identified parameters, Fig. 2, the validation
table and figures, then the staircase, sine and chirp outputs of that dataset when present.
What each section shows, in which order and with which caption, is the registry of outputs
(:data:`spa.outputs.STAGES`).

Modules: :mod:`spa.report.html` (cells, tables, embedded figures, style),
:mod:`spa.report.params` (the identified-parameter table), :mod:`spa.report.build` (the page).
"""

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

__all__ = [
    "PAPER_PREFIX",
    "PARAM_NAMES",
    "build_report",
    "embed_png",
    "format_value",
    "html_table",
    "pair_paper_columns",
    "params_table",
    "png_size",
    "section_items",
]
