"""What a drawn figure shows: its data, in display coordinates, for the figure checks.

The helpers of :mod:`spa.plots.check` (the layout of a figure) and
:mod:`spa.plots.caption_check` (its caption against its styles): draw a figure on an Agg
canvas, name an axes, and list what an axes draws (lines, markers, bars, images, colour
meshes) where it draws it.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.backend_bases import RendererBase
    from matplotlib.figure import Figure
    from matplotlib.transforms import Bbox

__all__: list[str] = []

#: Line styles and markers that draw nothing.
_NO_LINE = {"None", "none", "", " "}


def _draw(fig: Figure) -> RendererBase:
    """Draw ``fig`` on an Agg canvas (made if it has none) and return the renderer."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    canvas = fig.canvas if isinstance(fig.canvas, FigureCanvasAgg) else FigureCanvasAgg(fig)
    canvas.draw()
    return canvas.get_renderer()


def _name(ax: Axes, i: int) -> str:
    title = ax.get_title() or ax.get_title("left") or ax.get_ylabel()
    return f"axes {i}" + (f" ({title.splitlines()[0]!r})" if title else "")


def _tick_labels(axis: Any) -> list[Any]:
    return [
        t for t in axis.get_ticklabels(which="both") if t.get_visible() and t.get_text().strip()
    ]


def _shows(line: Any) -> bool:
    """Whether a line draws anything: visible, a line or a marker, a finite point."""
    if not line.get_visible():
        return False
    if line.get_linestyle() in _NO_LINE and str(line.get_marker()) in _NO_LINE:
        return False
    xy = np.asarray(line.get_xydata(), dtype=float)
    return bool(xy.size and np.isfinite(xy).all(axis=1).any())


def _has_data(ax: Axes) -> bool:
    return (
        any(_shows(line) for line in ax.get_lines())
        or any(c.get_visible() for c in ax.collections)
        or any(im.get_visible() for im in ax.images)
        or any(p.get_visible() for p in ax.patches)
    )


def _segments(ax: Axes) -> list[tuple[np.ndarray, np.ndarray, float]]:
    """Display-coordinate segments ``(start, end)`` of the lines and line collections of
    ``ax``, with half their width in pixels."""
    from matplotlib.cbook import STEP_LOOKUP_MAP
    from matplotlib.collections import LineCollection

    px = ax.figure.dpi / 72.0
    out = []
    for line in ax.get_lines():
        if not _shows(line) or line.get_linestyle() in _NO_LINE:
            continue
        x, y = (np.asarray(v, dtype=float) for v in line.get_data())
        x, y = STEP_LOOKUP_MAP[line.get_drawstyle()](x, y)
        xy = line.get_transform().transform(np.column_stack([x, y]))
        out.append((xy[:-1], xy[1:], 0.5 * line.get_linewidth() * px))
    for coll in ax.collections:
        if not (isinstance(coll, LineCollection) and coll.get_visible()):
            continue
        width = 0.5 * float(np.max(coll.get_linewidth(), initial=1.0)) * px
        for seg in coll.get_segments():
            xy = coll.get_transform().transform(np.asarray(seg, dtype=float))
            if len(xy) > 1:
                out.append((xy[:-1], xy[1:], width))
    return out


def _points(ax: Axes) -> list[tuple[np.ndarray, float]]:
    """Display-coordinate markers and scatter points of ``ax``, with their radius in pixels."""
    from matplotlib.collections import PathCollection

    px = ax.figure.dpi / 72.0
    out = []
    for line in ax.get_lines():
        if _shows(line) and str(line.get_marker()) not in _NO_LINE:
            xy = line.get_transform().transform(np.asarray(line.get_xydata(), dtype=float))
            out.append((xy, 0.5 * line.get_markersize() * px))
    for coll in ax.collections:
        if isinstance(coll, PathCollection) and coll.get_visible():
            xy = coll.get_offset_transform().transform(np.asarray(coll.get_offsets(), float))
            size = float(np.sqrt(np.max(coll.get_sizes(), initial=36.0)))
            out.append((xy, 0.5 * size * px))
    return out


def _boxes(ax: Axes, renderer: RendererBase) -> list[Bbox]:
    """Display-coordinate boxes of the bars, images and colour meshes of ``ax``."""
    from matplotlib.collections import QuadMesh
    from matplotlib.container import BarContainer

    out = [
        p.get_window_extent(renderer)
        for c in ax.containers
        if isinstance(c, BarContainer)
        for p in c.patches
        if p.get_visible()
    ]
    out += [im.get_window_extent(renderer) for im in ax.images if im.get_visible()]
    for coll in ax.collections:
        if isinstance(coll, QuadMesh) and coll.get_visible():
            values = np.ma.masked_invalid(np.ma.asarray(coll.get_array()))
            if values.count():
                out.append(coll.get_window_extent(renderer))
    return out
