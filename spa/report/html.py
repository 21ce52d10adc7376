"""HTML building blocks of the report: cell formatting, tables, embedded PNG figures, style.

>>> print(format_value(0.0050258454))
0.005026
>>> print(html_table(pd.DataFrame({"a<b": [1.234567, None]})))
<table>
<thead><tr><th>a&lt;b</th></tr></thead>
<tbody>
<tr><td class="num">1.235</td></tr>
<tr><td class="num"></td></tr>
</tbody>
</table>
"""

from __future__ import annotations

import base64
import html
import math
import numbers
import re
import struct
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

__all__ = [
    "PAPER_PREFIX",
    "STYLE",
    "embed_png",
    "format_value",
    "html_table",
    "pair_paper_columns",
    "png_size",
    "unique_anchor",
]

PAPER_PREFIX = "paper_"
"""Columns named ``paper_<name>`` hold the paper's printed value of column ``<name>``."""

_LONG_TEXT = 32  # cells longer than this (characters) may wrap; shorter ones stay on one line
_PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"

STYLE = """
body{font:15px/1.45 system-ui,sans-serif;color:#222;max-width:1280px;margin:0 auto;
padding:0 1.2em 3em}
h1{font-size:1.6em;margin:1em 0 .3em}h2{border-bottom:2px solid #345;padding-bottom:.2em;
margin-top:2.2em}h3{font-size:1.05em;margin:.4em 0}
dl.meta{display:grid;grid-template-columns:max-content auto;gap:.1em 1em;margin:.5em 0 1.5em}
dl.meta dt{font-weight:600}dl.meta dd{margin:0}
nav{background:#f4f6f8;border:1px solid #d8dde2;padding:.6em 1.2em}
nav ol{margin:.2em 0;padding-left:1.4em}nav>ol>li{margin:.3em 0}
nav ol ol{columns:3 18em;font-size:.92em}
figure{margin:1em 0 1.4em}figure.fig{display:inline-block;vertical-align:top;
margin-right:1.2em}
figcaption{font-size:.9em;color:#444;margin-top:.3em;max-width:60em}
img{max-width:100%;height:auto;border:1px solid #e3e3e3}
table{border-collapse:collapse;font-size:.88em}
th,td{border:1px solid #ccd;padding:.2em .5em;vertical-align:top}
th{background:#eef1f5;text-align:left}td{white-space:nowrap}
td.text{white-space:normal;min-width:18em}td.empty{color:#777;font-style:italic}
td.num{text-align:right;font-variant-numeric:tabular-nums}
tbody tr:nth-child(even){background:#fafbfc}
th.paper{background:#f6ead2}td.paper{background:#fdf6e8;font-style:italic}
.scroll{overflow-x:auto}
.key{border:2px solid #345;background:#f7fafc;padding:.2em 1em .6em;margin:1em 0}
p.note{font-size:.9em;color:#444}div.failed{color:#a33}
p.stage-failed{color:#a33;border-left:3px solid #a33;padding-left:.5em}
p.stage-skipped{border-left:3px solid #ccd;padding-left:.5em}
table.t3{font-size:.82em}table.t3 th{text-align:center}table.t3 td{padding:.2em .35em}
table.t3 td.text{min-width:0}
table.summary td small{color:#555}table.summary td{white-space:nowrap}
table.summary td.text{white-space:normal;min-width:10em}tr.failed td{background:#fdf3f3}
"""
"""The page's one inline style sheet."""


def format_value(value: Any) -> str:
    """Format one table cell: numbers to about 4 significant digits, missing values empty.

    Parameters
    ----------
    value : object
        A cell as read by :func:`pandas.read_csv` (or from ``params.yaml``).

    Returns
    -------
    str
        Integers in full, other reals rounded to 4 significant digits (positional between
        1e-4 and 1e6, scientific outside), ``""`` for ``None``/NaN, ``str(value)`` otherwise.
        The result is not HTML-escaped.

    Examples
    --------
    >>> [format_value(v) for v in (20000, 18.0, 5.405415736, 1.2344e-7, float("nan"), "pwm")]
    ['20000', '18', '5.405', '1.234e-07', '', 'pwm']
    """
    if value is None:
        return ""
    if isinstance(value, bool | np.bool_):
        return "yes" if value else "no"
    if isinstance(value, numbers.Integral):
        return str(int(value))
    if isinstance(value, numbers.Real):
        x = float(value)
        if math.isnan(x):
            return ""
        if math.isinf(x):
            return "∞" if x > 0 else "-∞"
        rounded = float(f"{x:.4g}")
        if rounded == 0.0:
            return "0"
        if 1e-4 <= abs(rounded) < 1e6:
            return np.format_float_positional(rounded, trim="-")
        return f"{x:.4g}"
    if value is pd.NA or value is pd.NaT:
        return ""
    return str(value)


def _is_number(value: Any) -> bool:
    return isinstance(value, numbers.Real) and not isinstance(value, bool | np.bool_)


def html_table(df: pd.DataFrame) -> str:
    """Render a table as an HTML ``<table>``, every header and cell HTML-escaped.

    Parameters
    ----------
    df : pandas.DataFrame
        The table; its index is not shown.

    Returns
    -------
    str
        ``<table>`` with a ``<thead>`` of the column names and one ``<tr>`` per row. Numbers
        are formatted by :func:`format_value` and right-aligned (``class="num"``), long texts
        may wrap (``class="text"``), ``paper_*`` columns are marked ``class="paper"``. A table
        without rows gets one cell saying so.

    Raises
    ------
    ValueError
        If ``df`` is not a DataFrame.
    """
    if not isinstance(df, pd.DataFrame):
        raise ValueError(f"df must be a pandas DataFrame, got {type(df).__name__}")
    paper = [str(c).startswith(PAPER_PREFIX) for c in df.columns]
    numeric = [
        pd.api.types.is_numeric_dtype(df[c]) and not pd.api.types.is_bool_dtype(df[c])
        for c in df.columns
    ]
    head = "".join(
        ('<th class="paper">' if is_paper else "<th>") + f"{html.escape(str(c))}</th>"
        for c, is_paper in zip(df.columns, paper, strict=True)
    )
    rows = []
    for values in df.itertuples(index=False, name=None):
        cells = []
        for is_num, is_paper, v in zip(numeric, paper, values, strict=True):
            text = format_value(v)
            flags = (
                ("num", is_num or _is_number(v)),
                ("text", len(text) > _LONG_TEXT),
                ("paper", is_paper),
            )
            cls = " ".join(name for name, on in flags if on)
            attr = f' class="{cls}"' if cls else ""
            cells.append(f"<td{attr}>{html.escape(text)}</td>")
        rows.append(f"<tr>{''.join(cells)}</tr>\n")
    if not rows:
        rows.append(
            f'<tr><td class="empty" colspan="{max(len(df.columns), 1)}">no rows</td></tr>\n'
        )
    return f"<table>\n<thead><tr>{head}</tr></thead>\n<tbody>\n{''.join(rows)}</tbody>\n</table>"


def pair_paper_columns(df: pd.DataFrame) -> pd.DataFrame:
    """Move every ``paper_<name>`` column right after the column ``<name>``, if there is one.

    The tables that compare with the paper (Tables 2 and 3) carry the printed values in
    ``paper_*`` columns; side by side they read as a comparison.

    Parameters
    ----------
    df : pandas.DataFrame
        The table.

    Returns
    -------
    pandas.DataFrame
        The same columns, reordered; other columns keep their order.

    Examples
    --------
    >>> df = pd.DataFrame(columns=["run", "mse", "fit", "paper_mse", "paper_fit", "paper_case"])
    >>> list(pair_paper_columns(df).columns)
    ['run', 'mse', 'paper_mse', 'fit', 'paper_fit', 'paper_case']
    """
    names = [str(c) for c in df.columns]
    paired = {
        c: c[len(PAPER_PREFIX) :]
        for c in names
        if c.startswith(PAPER_PREFIX) and c[len(PAPER_PREFIX) :] in names
    }
    order: list[str] = []
    for c in names:
        if c in paired:
            continue
        order.append(c)
        order.extend(p for p, base in paired.items() if base == c)
    return df[order]


def png_size(data: bytes) -> tuple[int, int]:
    """Width and height in pixels of a PNG image, from its IHDR chunk.

    Parameters
    ----------
    data : bytes
        The PNG file's bytes (the first 24 are enough).

    Returns
    -------
    (int, int)
        Width and height.

    Raises
    ------
    ValueError
        If ``data`` does not start with the PNG signature and an IHDR chunk.
    """
    if data[:8] != _PNG_SIGNATURE or data[12:16] != b"IHDR":
        raise ValueError("not a PNG image (no PNG signature and IHDR chunk)")
    width, height = struct.unpack(">II", data[16:24])
    return int(width), int(height)


def embed_png(path: str | Path) -> str:
    """A PNG file as a ``data:image/png;base64,...`` URI, for ``<img src=...>``.

    Parameters
    ----------
    path : str or Path
        The PNG file.

    Returns
    -------
    str
        The data URI.

    Raises
    ------
    ValueError
        If the file is not a PNG image.
    """
    data = Path(path).read_bytes()
    try:
        png_size(data)
    except ValueError as exc:
        raise ValueError(f"{path}: {exc}") from None
    return "data:image/png;base64," + base64.b64encode(data).decode("ascii")


def unique_anchor(text: str, taken: set[str]) -> str:
    """A unique HTML id made of letters, digits, '-' and '_' from ``text``, added to ``taken``.

    Examples
    --------
    >>> taken = set()
    >>> [unique_anchor(t, taken) for t in ("Fig. 2a", "fig-2a", "<>")]
    ['fig-2a', 'fig-2a-2', 'x']
    """
    base = re.sub(r"[^A-Za-z0-9_-]+", "-", text).strip("-").lower() or "x"
    anchor, n = base, 2
    while anchor in taken:
        anchor, n = f"{base}-{n}", n + 1
    taken.add(anchor)
    return anchor
