"""A trace drawn at the cost of its pixels: reduced, before it is drawn, to the samples that
each pixel column of its axes shows.

A line through the first, last, smallest and largest sample of each pixel column (M4;
Jugel et al., *M4: a visualization-oriented time series data aggregation*, VLDB 2014) covers
the same pixels as a line through every sample: every peak, every dip and the envelope of
chattering stay. A trace of 55 000 samples on an axes 1 500 pixels wide is drawn from at
most 6 000. The reduction is tsdownsample's (Rust, the library behind plotly-resampler).
Only the drawing is reduced: the CSV beside a figure holds what the stage computed
(:mod:`spa.plots.save`).

>>> import numpy as np
>>> t = np.arange(100_000.0); p = np.zeros_like(t); p[51_234] = 1.0
>>> i = reduce_indices(t, p, columns=500)
>>> len(i) <= 2_000, 51_234 in i, int(i[0]), int(i[-1])
(True, True, 0, 99999)
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any, Final

import numpy as np
import numpy.typing as npt

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.lines import Line2D

__all__ = ["PER_COLUMN", "REDUCE", "axes_columns", "plot_reduced", "reduce_indices"]

PER_COLUMN: Final = 4
"""Samples kept per pixel column: its first, last, smallest and largest (M4). A trace with
more than this many samples per column is reduced; one with fewer is drawn as it is."""

REDUCE: dict[str, bool] = {"on": True}
"""Switch of the reduction (``REDUCE["on"] = False``: every sample drawn), for the test that
compares the two drawings."""


def reduce_indices(x: Any, y: Any, columns: int) -> npt.NDArray[np.intp]:
    """The samples of ``y(x)`` a line needs to look the same at ``columns`` pixel columns.

    Parameters
    ----------
    x : array_like
        Abscissa, non-decreasing and finite (on a log axis, its logarithm).
    y : array_like
        Ordinate; NaN samples stay where they are an extreme (the line's gaps stay).
    columns : int
        Pixel columns across the span of ``x``.

    Returns
    -------
    numpy.ndarray of int
        Sorted indices into ``x``: per column of equal width in ``x``, the first, last,
        smallest and largest sample (M4), with the first and last sample; every index when
        there are at most :data:`PER_COLUMN` samples per column.

    Raises
    ------
    ValueError
        If ``columns < 1``, the lengths differ, or ``x`` decreases or is not finite.
    """
    if columns < 1:
        raise ValueError(f"columns must be >= 1, got {columns}")
    x_ = np.ascontiguousarray(x, dtype=np.float64)
    y_ = np.ascontiguousarray(y, dtype=np.float64)
    if x_.shape != y_.shape or x_.ndim != 1:
        raise ValueError(f"x and y must be 1-D of one length, got {x_.shape} and {y_.shape}")
    n = x_.size
    if n <= PER_COLUMN * columns:
        return np.arange(n)
    if not np.isfinite(x_).all() or np.any(np.diff(x_) < 0):
        raise ValueError("x must be finite and non-decreasing to be reduced per pixel column")
    if x_[-1] == x_[0]:
        return np.arange(n)
    from tsdownsample import M4Downsampler, NaNM4Downsampler

    down = NaNM4Downsampler() if np.isnan(y_).any() else M4Downsampler()
    kept = down.downsample(x_, y_, n_out=PER_COLUMN * columns).astype(np.intp)
    return np.unique(np.concatenate((kept, [0, n - 1])))


def axes_columns(ax: Axes, dpi: float | None = None) -> int:
    """The pixel columns of ``ax`` in the saved PNG: its width before the layout (an upper
    bound: constrained layout only narrows it) at the resolution the PNG is saved at.

    Parameters
    ----------
    ax : matplotlib.axes.Axes
    dpi : float, optional
        Resolution; default the PNG's (:func:`spa.plots.save.png_dpi` of the figure).
    """
    from spa.plots.save import png_dpi

    fig = ax.figure
    dpi = png_dpi(fig) if dpi is None else dpi
    return max(1, math.ceil(ax.get_position().width * fig.get_figwidth() * dpi))


def plot_reduced(ax: Axes, x: Any, y: Any, *args: Any, **style: Any) -> list[Line2D]:
    """``ax.plot(x, y, *args, **style)`` through the samples the axes' pixels can show.

    Parameters
    ----------
    ax : matplotlib.axes.Axes
        Its x scale (linear or log) is set before the call: on a log axis the columns are
        of equal width in ``log10(x)``.
    x, y : array_like
        The trace, ``x`` non-decreasing (a time); one that is not is drawn whole.
    *args, **style
        Passed to :meth:`~matplotlib.axes.Axes.plot`; ``columns=`` (int) overrides the
        axes' pixel columns (:func:`axes_columns`).

    Returns
    -------
    list of matplotlib.lines.Line2D
        What :meth:`~matplotlib.axes.Axes.plot` returns.
    """
    columns = style.pop("columns", None)
    x_ = np.asarray(x, dtype=np.float64)
    y_ = np.asarray(y, dtype=np.float64)
    if REDUCE["on"] and x_.size > 2:
        cols = int(columns) if columns is not None else axes_columns(ax)
        along = x_
        if ax.get_xscale() == "log":
            with np.errstate(divide="ignore", invalid="ignore"):
                along = np.log10(x_)
        if np.isfinite(along).all() and not np.any(np.diff(along) < 0):
            keep = reduce_indices(along, y_, cols)
            x_, y_ = x_[keep], y_[keep]
    return ax.plot(x_, y_, *args, **style)
