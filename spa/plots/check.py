"""A figure read as a person reads it: checks on a drawn matplotlib figure.

Each check is a function of a :class:`~matplotlib.figure.Figure` alone: it draws the figure
(on an Agg canvas, attached where it has none; no file written) and returns one sentence per
problem found, naming the axes (its title) and
what is wrong; an empty list is a pass. :func:`figure_problems` runs them all.

* :func:`legend_overlaps`: a legend's box covers plotted data (a line's segments or markers,
  error bars, scatter points, bars, images or colour meshes), in display coordinates, within
  the axes the data is drawn in;
* :func:`missing_tick_labels`: an axis of an axes that shows data has no tick label, and no
  axes sharing it below (x) or to its left (y), or a twin, labels it instead;
* :func:`small_axis_labels`: an axis label's font is smaller than its tick labels';
* :func:`shared_styles`: two series of one axes share colour, line style and marker;
* :func:`cut_off`: a title, label, annotation or legend reaches past the figure's edge (the
  saved image would cut it);
* :func:`legend_over_titles`: a legend's box covers an axes' title or the figure's title;
* :func:`empty_parentheses`: a text of the figure (a legend entry, a title, a label, a note)
  holds parentheses with nothing inside, an optional remark left out
  (:func:`spa.plots.words.noted`).

:func:`caption_problems` (of :mod:`spa.plots.caption_check`, exported here too) reads a
caption against the figure: each colour, line style and marker it names (in the words of
:mod:`spa.plots.words`) must be drawn by some artist. What an axes draws, in display
coordinates, is read by the helpers of :mod:`spa.plots.drawn`.

Examples
--------
>>> from matplotlib.figure import Figure
>>> fig = Figure(figsize=(4, 3))
>>> ax = fig.add_subplot()
>>> _ = ax.plot([0, 1], [0, 1], color="C0", label="a")
>>> _ = ax.plot([0, 1], [1, 0], color="C0", label="b")
>>> shared_styles(fig)
["axes 0: series 'a' and 'b' share colour #1f77b4, line style '-' and no marker"]
"""

from __future__ import annotations

import re
from typing import TYPE_CHECKING, Any

import numpy as np

from spa._docs import fill_doc
from spa.plots.caption_check import caption_problems
from spa.plots.drawn import (
    _NO_LINE,
    _boxes,
    _draw,
    _has_data,
    _name,
    _points,
    _segments,
    _shows,
    _tick_labels,
)

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.backend_bases import RendererBase
    from matplotlib.figure import Figure
    from matplotlib.transforms import Bbox

__all__ = [
    "caption_problems",
    "cut_off",
    "empty_parentheses",
    "figure_problems",
    "legend_over_titles",
    "legend_overlaps",
    "missing_tick_labels",
    "shared_styles",
    "small_axis_labels",
]


def figure_problems(fig: Figure) -> list[str]:
    """Every problem the checks of this module find in ``fig``.

    Parameters
    ----------
    fig : matplotlib.figure.Figure
        The figure, as it would be saved (it is drawn once, on an Agg canvas).

    Returns
    -------
    list of str
        :func:`legend_overlaps`, :func:`missing_tick_labels`, :func:`small_axis_labels`,
        :func:`shared_styles`, :func:`cut_off` and :func:`legend_over_titles`, in that
        order; empty when the figure passes.

    Examples
    --------
    >>> from matplotlib.figure import Figure
    >>> fig = Figure(figsize=(4, 3), layout="constrained")
    >>> ax = fig.add_subplot()
    >>> _ = ax.plot([0, 1], [1, 0], label="falling")
    >>> _ = ax.set_ylabel("P (bar)", fontsize=8)
    >>> _ = ax.legend(loc="upper left")
    >>> for problem in figure_problems(fig):
    ...     print(problem)
    the legend of axes 0 ('P (bar)') covers its lines
    axes 0 ('P (bar)'): y-label 'P (bar)' is 8 pt, its tick labels 10 pt
    """
    renderer = _draw(fig)
    return [
        *_legend_overlaps(fig, renderer),
        *_missing_tick_labels(fig),
        *small_axis_labels(fig, drawn=True),
        *shared_styles(fig),
        *_cut_off(fig, renderer),
        *_legend_over_titles(fig, renderer),
        *empty_parentheses(fig),
    ]


_EMPTY_PARENS = re.compile(r"\(\s*\)")


def empty_parentheses(fig: Figure) -> list[str]:
    """Every text of ``fig`` (legend entries and titles, axes titles and labels, notes, the
    figure's title) that holds ``()``: an optional parenthetical left empty.

    Examples
    --------
    >>> from matplotlib.figure import Figure
    >>> fig = Figure(figsize=(4, 3))
    >>> ax = fig.add_subplot()
    >>> _ = ax.plot([0, 1], [0, 1], label="no discharge fit ()")
    >>> _ = ax.legend()
    >>> empty_parentheses(fig)
    ["text 'no discharge fit ()' has empty parentheses"]
    """
    from matplotlib.text import Text

    found = []
    for text in fig.findobj(Text):
        words = text.get_text()
        if text.get_visible() and _EMPTY_PARENS.search(words):
            found.append(f"text {words!r} has empty parentheses")
    return list(dict.fromkeys(found))


@fill_doc
def legend_overlaps(fig: Figure) -> list[str]:
    """Legends whose box covers plotted data.

    %(figure_check)s
        One sentence per legend and axes whose data it covers.

    Notes
    -----
    The legend's box (its frame, or its text and padding where it has none) is widened by
    half the line width or marker size of each artist tested, and a framed one by one point
    more: a line touching the frame counts. The data counted are the segments of each line
    (after its draw style, such as steps) and of each line collection (error bars), each
    marker, scatter point, bar and the extent of each image and colour mesh; only within the
    axes that draws them (clipped).
    Grid lines, spans and filled bands are background and are not counted.
    """
    return _legend_overlaps(fig, _draw(fig))


@fill_doc
def missing_tick_labels(fig: Figure) -> list[str]:
    """Axes that show data but leave an axis without tick labels.

    %(figure_check)s
        One sentence per unlabelled axis. An axis without labels passes when an axes that
        shares it (``sharex``/``sharey``, or a twin) labels it and sits below it (x) or to
        its left (y), or at the same place (a twin). Colour bars and axes turned off are
        left out.
    """
    _draw(fig)
    return _missing_tick_labels(fig)


def small_axis_labels(fig: Figure, drawn: bool = False) -> list[str]:
    """Axis labels in a smaller font than the tick labels of their axis.

    Parameters
    ----------
    fig : matplotlib.figure.Figure
    drawn : bool, default False
        Whether ``fig`` was just drawn (its tick labels are up to date).

    Returns
    -------
    list of str
        One sentence per such label (colour bars included).
    """
    if not drawn:
        _draw(fig)
    problems = []
    for i, ax in enumerate(fig.axes):
        if not ax.get_visible() or not ax.axison:
            continue
        for name, axis in (("x", ax.xaxis), ("y", ax.yaxis)):
            label = axis.label
            if not (label.get_visible() and label.get_text().strip()):
                continue
            sizes = [t.get_fontsize() for t in _tick_labels(axis)]
            if sizes and label.get_fontsize() < max(sizes):
                problems.append(
                    f"{_name(ax, i)}: {name}-label {label.get_text()!r} is "
                    f"{label.get_fontsize():g} pt, its tick labels {max(sizes):g} pt"
                )
    return problems


@fill_doc
def shared_styles(fig: Figure) -> list[str]:
    """Series of one axes that cannot be told apart: same colour, line style and marker.

    %(figure_check)s
        One sentence per pair. A series is a line (``Line2D``); lines of one legend label
        are one series; an error bar's caps and bars belong to its data line.
    """
    from matplotlib.colors import to_hex
    from matplotlib.container import ErrorbarContainer

    problems = []
    for i, ax in enumerate(fig.axes):
        parts = {
            id(line)
            for c in ax.containers
            if isinstance(c, ErrorbarContainer)
            for line in c.lines[1]
        }
        seen: dict[tuple[str, str | None, str | None], str] = {}
        named: set[str] = set()
        for line in ax.get_lines():
            if id(line) in parts or not _shows(line):
                continue
            label = str(line.get_label())
            series = label if not label.startswith("_") else f"unlabelled line {label}"
            if series in named:  # one series drawn in pieces
                continue
            named.add(series)
            ls = None if line.get_linestyle() in _NO_LINE else str(line.get_linestyle())
            mk = None if str(line.get_marker()) in _NO_LINE else str(line.get_marker())
            key = (to_hex(line.get_color()), ls, mk)
            if key in seen:
                problems.append(
                    f"{_name(ax, i)}: series {seen[key]!r} and {series!r} share colour "
                    f"{key[0]}, line style {ls!r} and " + (f"marker {mk!r}" if mk else "no marker")
                )
            else:
                seen[key] = series
    return problems


@fill_doc
def cut_off(fig: Figure) -> list[str]:
    """Texts and legends that reach past the edge of the figure.

    %(figure_check)s
        One sentence per legend or text (titles, axis labels, annotations, the figure's
        title; not tick labels, which the layout places) more than one pixel outside.
    """
    return _cut_off(fig, _draw(fig))


def _cut_off(fig: Figure, renderer: RendererBase) -> list[str]:
    from matplotlib.text import Text

    ticks = {
        id(t)
        for ax in fig.axes
        for axis in (ax.xaxis, ax.yaxis)
        for tick in (*axis.get_major_ticks(), *axis.get_minor_ticks())
        for t in (tick.label1, tick.label2)
    }
    off = {id(t) for ax in fig.axes if not ax.axison for t in (ax.xaxis.label, ax.yaxis.label)}
    page = fig.bbox
    problems = []
    for legend in [*(ax.get_legend() for ax in fig.axes), *fig.legends]:
        if legend is not None and legend.get_visible():
            ticks.update(id(t) for t in (*legend.get_texts(), legend.get_title()))
            box = legend.get_window_extent(renderer)
            if _past(box, page):
                first = legend.get_texts()[0].get_text() if legend.get_texts() else ""
                problems.append(f"the legend with {first!r} reaches past the figure's edge")
    for text in fig.findobj(Text):
        if id(text) in ticks or id(text) in off or not text.get_visible():
            continue
        if text.get_text().strip() and _past(text.get_window_extent(renderer), page):
            line = text.get_text().strip().splitlines()[0]
            problems.append(f"the text {line!r} reaches past the figure's edge")
    return problems


def _past(box: Bbox, page: Bbox) -> bool:
    return bool(
        box.x0 < page.x0 - 1 or box.y0 < page.y0 - 1 or box.x1 > page.x1 + 1 or box.y1 > page.y1 + 1
    )


# --- what a legend covers, and the checks on a drawn figure ----------------------------------


def _inside(xy: np.ndarray, box: tuple[float, float, float, float], pad: float) -> np.ndarray:
    x0, y0, x1, y1 = box
    return (
        (xy[:, 0] > x0 - pad)
        & (xy[:, 0] < x1 + pad)
        & (xy[:, 1] > y0 - pad)
        & (xy[:, 1] < y1 + pad)
    )


def _crosses(p0: np.ndarray, p1: np.ndarray, box: tuple[float, float, float, float]) -> np.ndarray:
    """Whether each segment ``p0 -> p1`` runs through the open box (Liang–Barsky)."""
    lo, hi = np.array(box[:2]), np.array(box[2:])
    d = p1 - p0
    t_in = np.zeros(len(p0))
    t_out = np.ones(len(p0))
    with np.errstate(divide="ignore", invalid="ignore"):
        for k in (0, 1):
            a, b = (lo[k] - p0[:, k]) / d[:, k], (hi[k] - p0[:, k]) / d[:, k]
            flat = d[:, k] == 0
            inside = (p0[:, k] > lo[k]) & (p0[:, k] < hi[k])
            t_in = np.maximum(
                t_in, np.where(flat, np.where(inside, -np.inf, np.inf), np.fmin(a, b))
            )
            t_out = np.minimum(
                t_out, np.where(flat, np.where(inside, np.inf, -np.inf), np.fmax(a, b))
            )
    finite = np.isfinite(p0).all(axis=1) & np.isfinite(p1).all(axis=1)
    return finite & (t_in < t_out)


def _clip(box: Bbox, pad: float, ax_box: Bbox) -> tuple[float, float, float, float] | None:
    x0, y0 = max(box.x0 - pad, ax_box.x0), max(box.y0 - pad, ax_box.y0)
    x1, y1 = min(box.x1 + pad, ax_box.x1), min(box.y1 + pad, ax_box.y1)
    return (x0, y0, x1, y1) if x0 < x1 and y0 < y1 else None


def _covered(ax: Axes, legend_box: Bbox, renderer: RendererBase, framed: bool) -> list[str]:
    """What data of ``ax`` the legend box covers (kinds of artist, once each)."""
    ax_box = ax.get_window_extent(renderer)
    point = ax.figure.dpi / 72.0 if framed else 0.0
    found = []
    for p0, p1, half in _segments(ax):
        box = _clip(legend_box, point + half, ax_box)
        if box is not None and _crosses(p0, p1, box).any():
            found.append("lines")
            break
    for xy, radius in _points(ax):
        box = _clip(legend_box, 0.0, ax_box)
        if box is not None and _inside(xy, box, point + radius).any():
            found.append("markers")
            break
    for b in _boxes(ax, renderer):
        box = _clip(legend_box, point, ax_box)
        if box is not None and b.x0 < box[2] and box[0] < b.x1 and b.y0 < box[3] and box[1] < b.y1:
            found.append("bars or images")
            break
    return found


def _legend_overlaps(fig: Figure, renderer: RendererBase) -> list[str]:
    legends = [
        (ax.get_legend(), ax, f"the legend of {_name(ax, i)}") for i, ax in enumerate(fig.axes)
    ]
    legends += [(leg, None, "the figure's legend") for leg in fig.legends]
    problems = []
    for legend, owner, where in legends:
        if legend is None or not legend.get_visible():
            continue
        box = legend.get_window_extent(renderer)
        for i, ax in enumerate(fig.axes):
            if not ax.get_visible():
                continue
            found = " and ".join(_covered(ax, box, renderer, legend.get_frame_on()))
            if found:
                whose = "its" if ax is owner else f"those of {_name(ax, i)}:"
                problems.append(f"{where} covers {whose} {found}")
    return problems


def _missing_tick_labels(fig: Figure) -> list[str]:
    axes = [a for a in fig.axes if a.get_visible() and a.axison and not hasattr(a, "_colorbar")]
    problems = []
    for i, ax in enumerate(fig.axes):
        if ax not in axes or not _has_data(ax):
            continue
        box = ax.get_position()
        for name in ("x", "y"):
            if _tick_labels(getattr(ax, f"{name}axis")):
                continue
            if not any(_labels_for(ax, o, name, box) for o in axes if o is not ax):
                problems.append(f"{_name(ax, i)}: the {name}-axis has no tick labels")
    return problems


def _labels_for(ax: Axes, other: Axes, name: str, box: Any) -> bool:
    """Whether ``other`` shares ``ax``'s ``name`` axis, labels it and sits below it (x) or to
    its left (y), or at its place."""
    group = ax.get_shared_x_axes() if name == "x" else ax.get_shared_y_axes()
    if not group.joined(ax, other) or not _tick_labels(getattr(other, f"{name}axis")):
        return False
    o = other.get_position()
    eps = 1e-6
    if name == "x":
        return o.x0 < box.x1 and box.x0 < o.x1 and o.y0 <= box.y0 + eps
    return o.y0 < box.y1 and box.y0 < o.y1 and o.x0 <= box.x0 + eps


@fill_doc
def legend_over_titles(fig: Figure) -> list[str]:
    """Legends whose box covers a title (an axes' or the figure's).

    %(figure_check)s
        One sentence per legend and title it covers.
    """
    return _legend_over_titles(fig, _draw(fig))


def _legend_over_titles(fig: Figure, renderer: RendererBase) -> list[str]:
    titles = [
        t
        for ax in fig.axes
        if ax.get_visible()
        for t in (ax.title, ax._left_title, ax._right_title)
    ]
    if fig._suptitle is not None:
        titles.append(fig._suptitle)
    titles = list({id(t): t for t in titles}.values())
    legends = [ax.get_legend() for ax in fig.axes] + list(fig.legends)
    legends = list({id(leg): leg for leg in legends if leg is not None}.values())
    problems = []
    for legend in legends:
        if legend is None or not legend.get_visible():
            continue
        box = legend.get_window_extent(renderer)
        for title in titles:
            if not (title.get_visible() and title.get_text().strip()):
                continue
            t = title.get_window_extent(renderer)
            if box.x0 < t.x1 and t.x0 < box.x1 and box.y0 < t.y1 and t.y0 < box.y1:
                first = legend.get_texts()[0].get_text() if legend.get_texts() else ""
                problems.append(
                    f"the legend with {first!r} covers the title {title.get_text().strip()!r}"
                )
    return problems
