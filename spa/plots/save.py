"""Saving a figure for a paper: a PNG and its SVG copy, byte for byte the same on every run.

Every figure of the pipeline goes through :func:`save_figure`. The caller writes the plotted
data beside it as CSV (:func:`spa.io.write_csv`).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from pathlib import Path
from typing import Any, Final

from spa.io import PNG_DPI

__all__ = [
    "MIN_WIDTH_PX",
    "PNG_COMPRESS_LEVEL",
    "PNG_DPI",
    "SVG_HASHSALT",
    "draw",
    "save_figure",
    "vector_path",
]

MIN_WIDTH_PX: Final = 1000
"""The PNG is at least this wide: a narrow figure gets a higher resolution."""
PNG_COMPRESS_LEVEL: Final = 3
"""zlib level of the PNG (Pillow's default is 6): the same pixels, encoded in about 60 % of
the time, files about 13 % larger (``benchmarks/README.md``, "A dataset's analysis")."""
SVG_HASHSALT: Final = "spa"
"""Salt of the SVG's element ids (matplotlib draws them at random otherwise)."""


def vector_path(png: str | Path) -> Path:
    """The SVG copy's path beside a PNG: ``fig4.png`` -> ``fig4.svg``."""
    return Path(png).with_suffix(".svg")


def save_figure(
    fig: Any,
    path: str | Path,
    dpi: int = PNG_DPI,
    min_width: int = MIN_WIDTH_PX,
    vector: bool = True,
) -> None:
    """Save a matplotlib figure as PNG and SVG, without time stamps or version strings.

    Parameters
    ----------
    fig : matplotlib.figure.Figure
        The figure.
    path : str or Path
        The PNG; the SVG goes beside it (:func:`vector_path`). Folders are created.
    dpi : int, optional
        PNG resolution (default :data:`PNG_DPI`); raised where needed so that the PNG is at
        least ``min_width`` pixels wide. Rasterised artists of the SVG use the same.
    min_width : int, optional
        Smallest PNG width in pixels (default :data:`MIN_WIDTH_PX`; 0: none).
    vector : bool, optional
        Write the SVG copy (default True).

    Raises
    ------
    ValueError
        If ``path`` does not end in ``.png`` or ``dpi`` is not positive.

    Notes
    -----
    Same figure, same bytes: the PNG has no ``Software`` entry, the SVG no ``Date`` and no
    ``Creator`` (matplotlib's version), its ids are salted with :data:`SVG_HASHSALT` and its
    text is drawn as paths (no font needed to open it).

    The layout (``layout="constrained"``) is computed once, when the PNG is drawn; the SVG
    keeps it (the figure's layout engine is then switched off) rather than computing it
    again, which was a third of the SVG's time. The SVG's text and axes are placed where
    the PNG's are, to a fraction of a point.
    """
    import matplotlib

    png = Path(path)
    if png.suffix != ".png":
        raise ValueError(f"{png}: a figure is saved as .png (its SVG copy beside it)")
    if dpi <= 0:
        raise ValueError(f"dpi must be positive, got {dpi}")
    dpi = max(int(dpi), math.ceil(min_width / fig.get_figwidth()))
    png.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(
        png,
        dpi=dpi,
        metadata={"Software": None},
        pil_kwargs={"compress_level": PNG_COMPRESS_LEVEL},
    )
    if vector:
        if fig.get_layout_engine() is not None:
            fig.set_layout_engine("none")  # keep the layout the PNG's drawing computed
        style = {"svg.hashsalt": SVG_HASHSALT, "svg.fonttype": "path", "svg.image_inline": True}
        with matplotlib.rc_context(style):
            fig.savefig(
                vector_path(png), format="svg", dpi=dpi, metadata={"Date": None, "Creator": None}
            )
    _close(fig)


def draw(path: str | Path | None, make: Callable[..., Any], *args: Any, **kwargs: Any) -> None:
    """Draw ``make(*args, **kwargs)`` and save it with :func:`save_figure`, if ``path`` is set.

    Parameters
    ----------
    path : str, Path or None
        The PNG; None when the run draws no figures for the dataset (config ``figures``: the
        stage's figure outputs are absent, ``output.get(key)`` is None). Then nothing is made,
        not even the figure: a job that draws nothing never imports matplotlib.
    make : callable
        Returns the matplotlib figure.
    *args, **kwargs
        Passed to ``make``.
    """
    if path is not None:
        save_figure(make(*args, **kwargs), path)


def _close(fig: Any) -> None:
    """Release a figure: a pyplot one from pyplot's list, any one's canvas."""
    import sys

    plt = sys.modules.get("matplotlib.pyplot")  # loaded by the caller only: never import it here
    if plt is not None:
        plt.close(fig)
