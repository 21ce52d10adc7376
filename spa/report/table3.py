"""Table 3 as the report shows it: grouped columns with plain headers and units, the paper's
values beside ours, narrow enough for a 1280 px window; the full table is a CSV download.

``staircase/table3.csv`` has about 40 columns; the page shows the ones a reader compares with
the paper (:data:`TABLE3_VIEW`), each group under one heading, values scaled to short units
(mbar, 10⁻³ bar²) and rounded to 3 significant digits (the paper's as printed).

>>> df = pd.DataFrame({"setting": ["pwm-20Hz"], "paper_case": ["PWM"], "mse": [0.007952],
...                    "paper_mse": [0.0073], "fit": [73.57], "paper_fit": [75.23]})
>>> top = table3_html(df).splitlines()[2]
>>> print(top[:67])
<tr><th rowspan="2">setting</th><th rowspan="2" class="paper">paper
>>> table3_html(df).splitlines()[-3].split("</td>")  # doctest: +NORMALIZE_WHITESPACE
['<tr><td class="text">pwm-20Hz', '<td class="paper">PWM', '<td class="num">7.95',
 '<td class="paper">7.3', '<td class="num">73.6', '<td class="paper">75.23', '</tr>']
"""

from __future__ import annotations

import base64
import html
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pandas as pd

from spa.report.html import format_value

__all__ = ["TABLE3_VIEW", "csv_download", "table3_html"]


def _num(column: str, scale: float = 1.0, digits: int = 3) -> Callable[[pd.Series], str]:
    """A cell: ``column`` times ``scale``, ``digits`` significant digits."""

    def cell(row: pd.Series) -> str:
        value = row.get(column)
        if value is None or not isinstance(value, int | float | np.number) or np.isnan(value):
            return ""
        return format_value(float(f"{float(value) * scale:.{digits}g}"))

    return cell


def _bracket(lo: str, hi: str) -> Callable[[pd.Series], str]:
    """A cell ``lo–hi`` (a bracket of ξ between two staircase levels)."""

    def cell(row: pd.Series) -> str:
        a, b = _num(lo)(row), _num(hi)(row)
        return f"{a}–{b}" if a and b else a or b

    return cell


def _mean_sd(mean: str, sd: str) -> Callable[[pd.Series], str]:
    def cell(row: pd.Series) -> str:
        a, b = _num(mean)(row), _num(sd)(row)
        return f"{a} ± {b}" if a and b else a

    return cell


_TEXT = ("setting", "paper_case")  # columns of words, left-aligned


def _text(value: object) -> str:
    """A cell of words: empty for a missing value (None, NaN: a bench run has no paper's
    case), never ``"nan"``.

    >>> _text(float("nan")), _text(None), _text("PWM")
    ('', '', 'PWM')
    """
    if value is None or (isinstance(value, float | np.floating) and not np.isfinite(value)):
        return ""
    return str(value)


def _setting(row: pd.Series) -> str:
    return _text(row.get("setting")) or _text(row.get("run"))


# (group heading or "" for a single column, [(header, needed column, cell, is the paper's)])
TABLE3_VIEW: tuple[tuple[str, tuple[tuple[str, str, Callable[[pd.Series], str], bool], ...]], ...]
TABLE3_VIEW = (
    ("", (("setting", "setting", _setting, False),)),
    ("", (("paper's case", "paper_case", lambda r: _text(r.get("paper_case")), True),)),
    ("Line P = m ξ + n", (("m (bar)", "m", _num("m"), False), ("n (bar)", "n", _num("n"), False))),
    (
        "MSE (10⁻³ bar²)",
        (
            ("ours", "mse", _num("mse", 1e3), False),
            ("paper", "paper_mse", _num("paper_mse", 1e3, 4), True),
        ),
    ),
    (
        "Mean abs. deviation (mbar)",
        (
            ("ours", "mad", _num("mad", 1e3), False),
            ("paper MD", "paper_md", _num("paper_md", 1e3, 4), True),
        ),
    ),
    (
        "FIT (%)",
        (
            ("ours", "fit", _num("fit"), False),
            ("paper", "paper_fit", _num("paper_fit", 1.0, 4), True),
        ),
    ),
    ("", (("largest deviation (mbar)", "max_dev", _num("max_dev", 1e3), False),)),
    ("", (("levels vs model, RMS (mbar)", "eq_rmse_model", _num("eq_rmse_model", 1e3), False),)),
    (
        "",
        (("dead-zone (ξ)", "dead_zone_last", _bracket("dead_zone_last", "dead_zone_next"), False),),
    ),
    (
        "",
        (
            (
                "saturation (ξ)",
                "saturation_first",
                _bracket("saturation_prev", "saturation_first"),
                False,
            ),
        ),
    ),
    ("", (("step time constant (s)", "tau_mean", _mean_sd("tau_mean", "tau_sd"), False),)),
    ("", (("switching (edges/s)", "switching_rate_mean", _num("switching_rate_mean"), False),)),
    (
        "Chattering (mbar)",
        (
            ("noise-corrected", "ripple_corrected_mean", _num("ripple_corrected_mean", 1e3), False),
            ("Appendix B", "ripple_model_mean", _num("ripple_model_mean", 1e3), False),
        ),
    ),
)
"""What the report shows of Table 3: groups of (header, CSV column, cell, is the paper's)."""


def table3_html(df: pd.DataFrame) -> str:
    """Table 3 as an HTML ``<table>`` with a two-row header of groups and plain headers.

    Parameters
    ----------
    df : pandas.DataFrame
        ``staircase/table3.csv``. Columns of :data:`TABLE3_VIEW` it lacks are left out.

    Returns
    -------
    str
        ``<table class="t3">``: one row per setting; the paper's columns are marked
        ``class="paper"`` (shaded). Every text is HTML-escaped.
    """
    groups = []
    for group, cols in TABLE3_VIEW:
        present = tuple(c for c in cols if c[1] in df.columns)
        if present:
            groups.append((group, present))
    e = html.escape
    top, sub = [], []
    for group, cols in groups:
        if not group:
            header, _, _, paper = cols[0]
            cls = ' class="paper"' if paper else ""
            top.append(f'<th rowspan="2"{cls}>{e(header)}</th>')
            continue
        top.append(f'<th colspan="{len(cols)}">{e(group)}</th>')
        sub.extend(('<th class="paper">' if p else "<th>") + f"{e(h)}</th>" for h, _, _, p in cols)
    rows = []
    for _, row in df.iterrows():
        cells = []
        for _, cols in groups:
            for _, column, cell, paper in cols:
                cls = "paper" if paper else "text" if column in _TEXT else "num"
                cells.append(f'<td class="{cls}">{e(cell(row))}</td>')
        rows.append(f"<tr>{''.join(cells)}</tr>\n")
    if not rows:
        rows.append(f'<tr><td class="empty" colspan="{max(len(top), 1)}">no rows</td></tr>\n')
    return (
        '<table class="t3">\n<thead>\n'
        f"<tr>{''.join(top)}</tr>\n<tr>{''.join(sub)}</tr>\n</thead>\n"
        f"<tbody>\n{''.join(rows)}</tbody>\n</table>"
    )


def csv_download(path: str | Path, name: str, label: str) -> str:
    """A link that downloads the file ``path`` as ``name``: a ``data:`` URI (the page stays
    self-contained), labelled ``label``."""
    data = base64.b64encode(Path(path).read_bytes()).decode("ascii")
    return (
        f'<a download="{html.escape(name)}" href="data:text/csv;base64,{data}">'
        f"{html.escape(label)}</a>"
    )
