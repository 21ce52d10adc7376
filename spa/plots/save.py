"""Saving a figure: a PNG and, where asked, its SVG copy, byte for byte the same on every run.

Every figure of the pipeline goes through :func:`save_figure`. The caller writes the plotted
data beside it as CSV (:func:`spa.io.write_csv`): the full data, whatever the drawing reduced
(:mod:`spa.plots.reduce`). Which formats a job writes is :data:`FIGURE_FORMATS`
(:func:`set_figure_formats`: the pipeline's per-dataset jobs set it from the config key
``figure_formats``, default PNG alone; the analytic figures keep their SVG).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from pathlib import Path
from typing import Any, Final

from spa.io import PNG_DPI

__all__ = [
    "FIGURE_FORMATS",
    "FORMATS",
    "MIN_WIDTH_PX",
    "PNG_COMPRESS_LEVEL",
    "PNG_DPI",
    "SVG_HASHSALT",
    "draw",
    "png_dpi",
    "save_figure",
    "set_figure_formats",
    "vector_path",
]

MIN_WIDTH_PX: Final = 1000
"""The PNG is at least this wide: a narrow figure gets a higher resolution."""
PNG_COMPRESS_LEVEL: Final = 3
"""zlib level of the PNG (Pillow's default is 6): the same pixels, encoded in about 60 % of
the time, files about 13 % larger (``benchmarks/README.md``, "A dataset's analysis")."""
SVG_HASHSALT: Final = "spa"
"""Salt of the SVG's element ids (matplotlib draws them at random otherwise)."""


FORMATS: Final = ("png", "svg")
"""The formats a figure can be saved in: the PNG always, the SVG copy optionally."""

FIGURE_FORMATS: list[str] = ["png", "svg"]
"""The formats :func:`save_figure` writes when not told (:func:`set_figure_formats`)."""


def set_figure_formats(formats: Any) -> list[str]:
    """Set the formats :func:`save_figure` writes by default (config ``figure_formats``).

    Parameters
    ----------
    formats : sequence of str
        A subset of :data:`FORMATS` that holds ``"png"`` (the report embeds it).

    Returns
    -------
    list of str
        The formats set, in :data:`FORMATS` order.

    Raises
    ------
    ValueError
        Naming the config key, if a format is unknown or ``png`` is missing.

    Examples
    --------
    >>> set_figure_formats(["svg", "png"])
    ['png', 'svg']
    >>> set_figure_formats(["png"])
    ['png']
    """
    given = [str(f).lower() for f in (formats or [])]
    unknown = sorted(set(given) - set(FORMATS))
    if unknown or "png" not in given:
        raise ValueError(
            f"figure_formats: expected a list of {list(FORMATS)} that holds 'png', got {formats!r}"
        )
    FIGURE_FORMATS[:] = [f for f in FORMATS if f in given]
    return list(FIGURE_FORMATS)


def png_dpi(fig: Any, dpi: int = PNG_DPI, min_width: int = MIN_WIDTH_PX) -> int:
    """The resolution a figure's PNG is saved at: ``dpi``, raised so that the PNG is at least
    ``min_width`` pixels wide.

    Examples
    --------
    >>> from matplotlib.figure import Figure
    >>> png_dpi(Figure(figsize=(10, 3))), png_dpi(Figure(figsize=(4, 3)))
    (200, 250)
    """
    if dpi <= 0:
        raise ValueError(f"dpi must be positive, got {dpi}")
    return max(int(dpi), math.ceil(min_width / fig.get_figwidth()))


def vector_path(png: str | Path) -> Path:
    """The SVG copy's path beside a PNG: ``fig4.png`` -> ``fig4.svg``."""
    return Path(png).with_suffix(".svg")


def save_figure(
    fig: Any,
    path: str | Path,
    dpi: int = PNG_DPI,
    min_width: int = MIN_WIDTH_PX,
    vector: bool | None = None,
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
        Write the SVG copy; default: when :data:`FIGURE_FORMATS` holds ``"svg"``.

    Raises
    ------
    ValueError
        If ``path`` does not end in ``.png`` or ``dpi`` is not positive.

    Notes
    -----
    Same figure, same bytes: the PNG has no ``Software`` entry, the SVG no ``Date`` and no
    ``Creator`` (matplotlib's version), its ids are salted with :data:`SVG_HASHSALT` and its
    text is drawn as paths (no font needed to open it).

    The layout (``layout="constrained"``) is computed once, at the PNG's resolution, before
    anything is drawn (:func:`_lay_out`); the figure's layout engine is then removed, so that
    neither the PNG nor the SVG computes it again. The SVG's text and axes are placed where
    the PNG's are, to a fraction of a point.
    """
    import matplotlib

    png = Path(path)
    if png.suffix != ".png":
        raise ValueError(f"{png}: a figure is saved as .png (its SVG copy beside it)")
    dpi = png_dpi(fig, dpi, min_width)
    if vector is None:
        vector = "svg" in FIGURE_FORMATS
    png.parent.mkdir(parents=True, exist_ok=True)
    _lay_out(fig, dpi)
    fig.savefig(
        png,
        dpi=dpi,
        metadata={"Software": None},
        pil_kwargs={"compress_level": PNG_COMPRESS_LEVEL},
    )
    if vector:
        style = {"svg.hashsalt": SVG_HASHSALT, "svg.fonttype": "path", "svg.image_inline": True}
        with matplotlib.rc_context(style):
            fig.savefig(
                vector_path(png), format="svg", dpi=dpi, metadata={"Date": None, "Creator": None}
            )
    _close(fig)


def _lay_out(fig: Any, dpi: int) -> None:
    """Compute the figure's layout once, at ``dpi``, and remove its layout engine.

    ``savefig`` of a figure that has a layout engine draws it twice: once with drawing
    disabled, to run the engine, then for real. Running the engine here, with the renderer
    ``savefig`` would use at the PNG's resolution, and removing it leaves ``savefig`` one
    drawing: the same pixels, byte for byte (``tests/test_save.py``), in about a fifth less
    time (``benchmarks/README.md``, "Figures: one drawing a format"). The figure's canvas
    and resolution are left as they were.
    """
    engine = fig.get_layout_engine()
    if engine is None:
        return
    own = fig.dpi
    fig.set_dpi(dpi)  # the layout's text extents are measured at the PNG's resolution
    try:
        engine.execute(fig)
    finally:
        fig.set_dpi(own)
    fig.set_layout_engine(None)


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

    Notes
    -----
    In the pipeline's analysis job the files are kept in the results' store, keyed by
    ``make``, its arguments (pickled), the formats and the code
    (:func:`spa._memo.files_memoised`): a stage run again on the same data (a ``tuning:``
    change leaves Fig. 4's sweeps as they were) copies the figure instead of drawing it.
    Arguments that cannot be pickled, and a ``make`` without a module-level name, are drawn
    every time.
    """
    if path is None:
        return
    import pickle

    from spa._memo import files_memoised

    png = Path(path)
    paths = [png, *([vector_path(png)] if "svg" in FIGURE_FORMATS else [])]

    def write() -> None:
        save_figure(make(*args, **kwargs), png)

    name = f"{getattr(make, '__module__', '')}.{getattr(make, '__qualname__', '<unnamed>')}"
    try:
        if "<" in name:  # a lambda or a local function: its name does not say what it draws
            raise TypeError(name)
        blob = pickle.dumps((name, args, sorted(kwargs.items()), FIGURE_FORMATS), protocol=5)
    except (pickle.PicklingError, TypeError, AttributeError):
        write()
        return
    files_memoised("figures", blob, paths, write)


def _close(fig: Any) -> None:
    """Release a figure: a pyplot one from pyplot's list, any one's canvas."""
    import sys

    plt = sys.modules.get("matplotlib.pyplot")  # loaded by the caller only: never import it here
    if plt is not None:
        plt.close(fig)
