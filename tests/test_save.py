"""spa.plots.save: the PNG's pixels are a plain savefig's; the SVG keeps the PNG's layout."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from PIL import Image

from spa.plots.save import PNG_DPI, save_figure
from spa.plots.style import new_figure


def _figure():
    fig = new_figure(figsize=(7.0, 4.0), layout="constrained")
    axes = fig.subplots(1, 2)
    t = np.linspace(0.0, 10.0, 3000)
    for i, ax in enumerate(axes):
        ax.plot(t, np.sin(t * (i + 1)), label="a rather long label")
        ax.set_xlabel("time (s)")
        ax.set_ylabel("pressure (bar)")
        ax.legend()
    return fig


def test_png_pixels_are_those_of_a_plain_savefig(tmp_path: Path) -> None:
    save_figure(_figure(), tmp_path / "a.png")
    _figure().savefig(tmp_path / "b.png", dpi=PNG_DPI)
    ours, plain = (np.asarray(Image.open(tmp_path / f)) for f in ("a.png", "b.png"))
    assert ours.shape == plain.shape and np.array_equal(ours, plain)


def test_the_svg_keeps_the_layout_the_png_computed(tmp_path: Path) -> None:
    fig = _figure()
    save_figure(fig, tmp_path / "a.png")
    plain = _figure()
    plain.savefig(tmp_path / "b.png", dpi=PNG_DPI)  # constrained layout at the PNG's dpi
    for ax, ref in zip(fig.axes, plain.axes, strict=True):
        assert np.array_equal(ax.get_position().bounds, ref.get_position().bounds)
    svg = (tmp_path / "a.svg").read_text()
    assert svg.count('<g id="axes_') == 2 and "<dc:date>" not in svg


def _varied(shape: str):
    """Figures whose constrained layout has work to do: a suptitle, a legend beside, log axes."""
    fig = new_figure(figsize=(9.0, 5.0), layout="constrained")
    rows, cols = (2, 3) if shape == "grid" else (1, 1)
    t = np.logspace(-2, 2, 400)
    for i, ax in enumerate(np.atleast_1d(fig.subplots(rows, cols)).ravel()):
        ax.loglog(t, t ** (0.5 + i), label=f"curve {i}")
        ax.set_title(f"panel {i}")
        ax.set_ylabel("cost (bar$^2$)")
    fig.suptitle("a title over every panel")
    fig.axes[-1].legend(loc="upper left", bbox_to_anchor=(1.02, 1.0))
    return fig


def test_one_layout_gives_the_bytes_of_savefig_s_two_drawings(tmp_path: Path) -> None:
    """The layout computed before drawing (save._lay_out) is savefig's own: PNG bytes equal."""
    for shape in ("grid", "single"):
        save_figure(_varied(shape), tmp_path / f"{shape}.png", vector=False)
        _varied(shape).savefig(
            tmp_path / f"{shape}-plain.png",
            dpi=PNG_DPI,
            metadata={"Software": None},
            pil_kwargs={"compress_level": 3},
        )
        assert (tmp_path / f"{shape}.png").read_bytes() == (
            tmp_path / f"{shape}-plain.png"
        ).read_bytes()


def test_the_figure_keeps_its_canvas_and_resolution(tmp_path: Path) -> None:
    fig = _varied("grid")
    canvas, dpi = fig.canvas, fig.dpi
    save_figure(fig, tmp_path / "a.png", vector=False)
    assert fig.canvas is canvas and fig.dpi == dpi and fig.get_layout_engine() is None
