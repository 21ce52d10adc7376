"""One self-contained HTML page with every table and figure of a ``reproduce-all`` run.

The page opens offline in any browser: figures are PNGs embedded as base64 ``data:`` URIs,
tables are rendered from the CSV files, the style is one inline ``<style>`` block, and there
is no JavaScript and no reference to anything outside the file. The same results give the
same bytes: nothing depends on the clock, the host or where the results folder lives.

The report has a header (the run's metadata, e.g. seed and ``spa`` version), a table of
contents with in-page anchors, the analytic section (Tables 1-2, Figs. 4-5), then one section
per dataset: Table 3 first when present, the identified parameters, Fig. 2, the validation
table and figures, then the staircase, sine and chirp outputs of that dataset when present.

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
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import yaml

__all__ = [
    "ANALYTIC_ITEMS",
    "DATASET_ITEMS",
    "PAPER_PREFIX",
    "PARAM_NAMES",
    "Item",
    "build_report",
    "embed_png",
    "format_value",
    "html_table",
    "pair_paper_columns",
    "params_table",
    "png_size",
]

PAPER_PREFIX = "paper_"
"""Columns named ``paper_<name>`` hold the paper's printed value of column ``<name>``."""

PARAM_NAMES = ("c1", "k2", "tau2", "t_on", "t_off")
"""The identified valve parameters, in the order of the paper (Section 3.2)."""

_LONG_TEXT = 32  # cells longer than this (characters) may wrap; shorter ones stay on one line
_PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


@dataclass(frozen=True)
class Item:
    """One table or figure of the report.

    Parameters
    ----------
    path : str
        File relative to the section's folder (``results/analytic`` or ``results/<dataset>``);
        ``.csv`` is shown as a table (``paper_*`` columns beside their own), ``.png`` as a
        figure, ``.yaml`` as the parameter table.
    title : str
        Short heading, also the entry in the table of contents.
    caption : str
        What the table or figure shows, printed under it.
    required : bool
        A missing required file is an error; a missing optional one is skipped.
    """

    path: str
    title: str
    caption: str
    required: bool = True


ANALYTIC_ITEMS = (
    Item(
        "table1.csv",
        "Table 1: dead-zone and saturation",
        "Dead-zone and saturation thresholds of the input fraction for each selected "
        "modulator setting, from the averaged model at the nominal parameters.",
    ),
    Item(
        "table2.csv",
        "Table 2: optimal modulator parameters",
        "Minimum linearity cost J_min and optimal parameter per modulator, the paper's printed "
        "values beside them, and the analytic IIPFM optimum t_l* (Eq. 29).",
    ),
    Item(
        "fig4.png",
        "Fig. 4: linearity cost",
        "Linearity cost J against the modulator parameter, all four modulators on one axis.",
    ),
    Item(
        "fig5.png",
        "Fig. 5: equilibrium pressure and time constant",
        "Equilibrium pressure and time constant against the input fraction ξ at each "
        "modulator's optimum, with the linear target.",
    ),
)
"""The analytic stage's tables and figures, in ``results/analytic``."""

_TABLE3 = Item(
    "staircase/table3.csv",
    "Table 3: static linearity of the staircase",
    "One row per modulator setting: line P = m ξ + n through the equilibrium pressure of each "
    "staircase level, MSE, MD (largest residual), MAD (mean absolute residual) and FIT %, with "
    "the paper's values (paper_*, shaded) beside its five cases; then the measured against the "
    "averaged-model equilibrium, dead-zone and saturation brackets, step time constants and "
    "switching rate.",
    required=False,
)

DATASET_ITEMS = (
    Item(
        "identification/params.yaml",
        "Identified valve parameters",
        "c1, k2, tau2, t_on and t_off identified from this dataset, each with its 95 % "
        "interval, unit, method and any fallback to the nominal value.",
    ),
    Item(
        "identification/fig2a.png",
        "Fig. 2a: charging",
        "dP/dt against P while charging, with the line fit that gives k2 and tau2.",
    ),
    Item(
        "identification/fig2b.png",
        "Fig. 2b: discharging",
        "dP/dt against P while discharging, with the power-law fit that gives c1.",
    ),
    Item(
        "identification/fig2c.png",
        "Fig. 2c: pulse run",
        "The pulse run: command, measured and model pressure, with a zoom on one edge.",
    ),
    Item(
        "validation/fit.csv",
        "Model validation: FIT per run",
        "Every run re-simulated with the identified parameters: FIT %, RMSE and largest "
        "error (bar).",
    ),
    Item(
        "staircase/fig6.png",
        "Fig. 6: staircase responses",
        "Pressure against time for the staircase input fraction, one panel per modulator "
        "(every setting).",
        required=False,
    ),
    Item(
        "staircase/fig7a.png",
        "Fig. 7a: equilibrium pressure",
        "Equilibrium pressure against ξ for the best setting of each modulator plus IIPFM "
        "with gain, with the ideal line k2·ξ.",
        required=False,
    ),
    Item(
        "staircase/fig7b.png",
        "Fig. 7b: time constants",
        "Time constant of each staircase step (time to 63.2 % of the step's change).",
        required=False,
    ),
    Item(
        "sine/linearity.csv",
        "Sine linearity",
        "Per setting: lag found by cross-correlation, RMS and largest deviation of P/max(P) "
        "from the line (0, 0)–(1, 1).",
        required=False,
    ),
    Item(
        "sine/fig8.png",
        "Fig. 8: sine linearity",
        "Lag-compensated P/max(P) against the input fraction of the sine runs, one panel per "
        "modulator, with the line (0, 0)–(1, 1).",
        required=False,
    ),
    Item(
        "chirp/bicoherence.csv",
        "Chirp bicoherence",
        "Per setting: mean (and largest) bicoherence of the pressure response to the chirp "
        "over the principal domain.",
        required=False,
    ),
    Item(
        "chirp/fig9.png",
        "Fig. 9: bicoherence",
        "Bicoherence maps over (f1, f2) of the pressure response to the chirp, for the "
        "lowest-mean setting of each modulator.",
        required=False,
    ),
)
"""A dataset's tables and figures after Table 3, in ``results/<dataset>``; the validation
figures (``validation/figures/*.png``) are inserted after ``validation/fit.csv``."""

_PAPER = (
    "Serrano-Balbontín et al., Open-Loop Characterisation of Soft Actuator Pressure Regulated "
    "by Pulse-Driven Solenoid Valve, Robotics 2025, 14(12), 177."
)

_LONG_TABLES = ("staircase/levels.csv", "staircase/time_constants.csv")

_CSS = """
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
p.note{font-size:.9em;color:#444}
"""


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


def params_table(params: Mapping[str, Any]) -> pd.DataFrame:
    """The identified parameters of a ``params.yaml`` as a table, one row per parameter.

    Parameters
    ----------
    params : mapping
        The content of ``identification/params.yaml``: for each of :data:`PARAM_NAMES` a
        mapping with ``value``, ``lo``, ``hi`` (the 95 % interval), ``unit``, ``method`` and
        ``fallback`` (``None``, or why the nominal value was used).

    Returns
    -------
    pandas.DataFrame
        Columns ``parameter``, ``value``, ``95 % lo``, ``95 % hi``, ``unit``, ``method``,
        ``fallback`` (``"no"`` or the reason), in the order of :data:`PARAM_NAMES`.

    Raises
    ------
    ValueError
        If a parameter or one of its fields is missing.

    Examples
    --------
    >>> entry = {"value": 0.5, "lo": 0.4, "hi": 0.6, "unit": "s", "method": "fit",
    ...          "fallback": None}
    >>> print(params_table({n: entry for n in PARAM_NAMES}).head(2).to_string(index=False))
    parameter  value  95 % lo  95 % hi unit method fallback
           c1    0.5      0.4      0.6    s    fit       no
           k2    0.5      0.4      0.6    s    fit       no
    """
    if not isinstance(params, Mapping):
        raise ValueError(f"params must be a mapping, got {type(params).__name__}")
    rows = []
    for name in PARAM_NAMES:
        entry = params.get(name)
        if not isinstance(entry, Mapping):
            raise ValueError(f"params lacks the parameter {name!r}")
        missing = [k for k in ("value", "lo", "hi", "unit", "method") if k not in entry]
        if missing:
            raise ValueError(f"params[{name!r}] lacks {missing}")
        fallback = entry.get("fallback")
        rows.append(
            {
                "parameter": name,
                "value": float(entry["value"]),
                "95 % lo": float(entry["lo"]),
                "95 % hi": float(entry["hi"]),
                "unit": str(entry["unit"]),
                "method": str(entry["method"]),
                "fallback": "no" if fallback in (None, False, "") else str(fallback),
            }
        )
    return pd.DataFrame(rows)


def _anchor(text: str, taken: set[str]) -> str:
    """A unique HTML id made of letters, digits, '-' and '_' from ``text``."""
    base = re.sub(r"[^A-Za-z0-9_-]+", "-", text).strip("-").lower() or "x"
    anchor, n = base, 2
    while anchor in taken:
        anchor, n = f"{base}-{n}", n + 1
    taken.add(anchor)
    return anchor


def _fits_note(params: Mapping[str, Any]) -> str:
    """`` R² of the fits: charge 0.9625, discharge 0.9853.`` or ``""``."""
    fits = params.get("fits") or {}
    parts = [
        f"{name} {format_value(fit['r2'])}"
        for name, fit in fits.items()
        if isinstance(fit, Mapping) and "r2" in fit
    ]
    return f" R² of the fits: {', '.join(parts)}." if parts else ""


def _render_item(path: Path, item: Item, anchor: str) -> str:
    """``<figure>`` with the table or image of ``path``, its heading and its caption."""
    caption = item.caption
    attrs = ""
    if path.suffix == ".png":
        width, height = png_size(path.read_bytes())
        alt = html.escape(item.title)
        body = f'<img src="{embed_png(path)}" alt="{alt}" width="{width}" height="{height}">'
        attrs = f' class="fig" style="max-width:{width + 2}px"'
    elif path.suffix == ".yaml":
        params = yaml.safe_load(path.read_text(encoding="utf-8"))
        body = f'<div class="scroll">{html_table(params_table(params))}</div>'
        caption += _fits_note(params)
    else:
        body = f'<div class="scroll">{html_table(pair_paper_columns(pd.read_csv(path)))}</div>'
    return (
        f'<figure id="{anchor}"{attrs}>\n<h3>{html.escape(item.title)}</h3>\n{body}\n'
        f"<figcaption>{html.escape(caption)}</figcaption>\n</figure>\n"
    )


def _dataset_items(folder: Path) -> list[Item]:
    """Table 3, then :data:`DATASET_ITEMS` with this dataset's validation figures inserted."""
    items = [_TABLE3]
    for item in DATASET_ITEMS:
        items.append(item)
        if item.path == "validation/fit.csv":
            for png in sorted((folder / "validation" / "figures").glob("*.png")):
                kind = png.stem
                items.append(
                    Item(
                        f"validation/figures/{png.name}",
                        f"Validation: {kind}",
                        f"Measured against model pressure for the lowest-FIT {kind} run.",
                    )
                )
    return items


def _section(
    folder: Path, items: Sequence[Item], prefix: str, taken: set[str], key_first: bool = False
) -> tuple[str, list[tuple[str, str]]]:
    """The HTML of one section's items that exist and its table-of-contents entries."""
    parts: list[str] = []
    toc: list[tuple[str, str]] = []
    for i, item in enumerate(items):
        path = folder / item.path
        if not path.is_file():
            if item.required:
                raise FileNotFoundError(f"{path}: required by the report but missing")
            continue
        anchor = _anchor(f"{prefix}-{Path(item.path).stem}", taken)
        block = _render_item(path, item, anchor)
        if key_first and i == 0:
            block = f'<div class="key">\n{block}</div>\n'
        parts.append(block)
        toc.append((anchor, item.title))
    return "".join(parts), toc


def build_report(
    results_dir: str | Path,
    datasets: Sequence[str],
    meta: Mapping[str, Any],
    title: str = "spa: reproduction report",
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

    Returns
    -------
    str
        A complete HTML5 document. It references nothing outside itself (figures are
        ``data:`` URIs), has no script, and depends only on the files read and the arguments:
        the same inputs give the same string.

    Raises
    ------
    FileNotFoundError
        If a required table or figure (Tables 1-2, Figs. 4-5, and per dataset
        ``params.yaml``, Fig. 2a-c and ``validation/fit.csv``) is missing. Optional outputs
        (Table 3, Figs. 6-9, sine and chirp tables) are skipped when absent.
    ValueError
        If ``datasets`` is a string or names a dataset twice.
    """
    if isinstance(datasets, str):
        raise ValueError("datasets must be a sequence of dataset names, not one string")
    if len(set(datasets)) != len(datasets):
        raise ValueError(f"datasets names a dataset twice: {list(datasets)}")
    results = Path(results_dir)
    taken: set[str] = {"contents", "analytic"}
    sections: list[tuple[str, str, str, list[tuple[str, str]]]] = []

    body, toc = _section(results / "analytic", ANALYTIC_ITEMS, "analytic", taken)
    sections.append(("analytic", "Analytic (averaged model)", body, toc))
    for name in datasets:
        folder = results / name
        anchor = _anchor(f"dataset-{name}", taken)
        body, toc = _section(folder, _dataset_items(folder), anchor, taken, key_first=True)
        present = [p for p in _LONG_TABLES if (folder / p).is_file()]
        if present:
            listed = " and ".join(f"{name}/{p}" for p in present)
            body += (
                f'<p class="note">Per-level and per-step values: {html.escape(listed)} in the '
                "results folder (not reproduced here).</p>\n"
            )
        sections.append((anchor, f"Dataset {name}", body, toc))

    e = html.escape
    meta_html = "".join(
        f"<dt>{e(str(k))}</dt><dd>{e(format_value(v))}</dd>" for k, v in meta.items()
    )
    meta_html += f"<dt>datasets</dt><dd>{e(', '.join(datasets))}</dd>"
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
        f"<title>{e(title)}</title>\n<style>{_CSS}</style>\n</head>\n<body>\n"
        f"<header>\n<h1>{e(title)}</h1>\n<p>Tables and figures of one run reproducing "
        f'{e(_PAPER)}</p>\n<dl class="meta">{meta_html}</dl>\n</header>\n'
        f'<nav id="contents">\n<strong>Contents</strong>\n<ol>\n{nav}</ol>\n</nav>\n'
        f"<main>\n{content}</main>\n</body>\n</html>\n"
    )
