"""A caption read against its figure: each style word it names must be drawn.

:func:`caption_problems` reads a caption against the figure: each colour, line style and
marker it names (in the words of :mod:`spa.plots.words`) must be drawn by some artist. The
layout of the figure itself is read by :mod:`spa.plots.check`, which also exports
:func:`caption_problems`.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import TYPE_CHECKING

from spa.plots.drawn import _NO_LINE, _has_data, _shows

if TYPE_CHECKING:
    from matplotlib.figure import Figure

__all__ = ["caption_problems"]


def caption_problems(fig: Figure, caption: str, conditional: Iterable[str] = ()) -> list[str]:
    """The style words of ``caption`` that no artist of ``fig`` draws.

    Parameters
    ----------
    fig : matplotlib.figure.Figure
    caption : str
        The figure's caption.
    conditional : iterable of str, optional
        Style words the caption names for what is drawn only when the data has it (Fig. O1's
        trend and ring: :data:`spa.plots.words.O1_CONDITIONAL`): not a problem when absent.

    Returns
    -------
    list of str
        One sentence per word (a colour, line style or marker of :mod:`spa.plots.words`,
        or ``filled``/``hollow`` markers) that the caption names and no line, collection or
        patch of the figure's axes has; empty when every word is drawn, or when the figure
        draws no data (it says why there is nothing to draw).

    Notes
    -----
    A colour word matches an artist of exactly that colour (``grey``: any grey strictly
    between black and white); ``triangle`` matches any triangle marker. Longer words are
    read first (``sky blue`` is not ``blue``), whole words only (``bluish`` is not ``blue``).

    Examples
    --------
    >>> from matplotlib.figure import Figure
    >>> fig = Figure()
    >>> _ = fig.add_subplot().plot([0, 1], [0, 1], "o--", color="#0072B2")
    >>> caption_problems(fig, "one setting (blue, dashed, circles)")
    []
    >>> for problem in caption_problems(fig, "fixed PI (black), down triangles"):
    ...     print(problem)
    the caption says 'black' but nothing is drawn black
    the caption says 'triangle' but no marker is a triangle
    """
    import re

    from spa.plots.words import COLOUR_WORDS, LINE_STYLE_WORDS, MARKER_WORDS

    if not any(ax.get_visible() and _has_data(ax) for ax in fig.axes):
        return []  # a figure that says why there is nothing to draw
    text = caption.lower()
    drawn = _drawn_styles(fig)
    problems: list[str] = []
    maybe = {str(w).lower() for w in conditional}

    def said(word: str) -> bool:
        nonlocal text
        # whole words: "bluish" is not "blue", "least-squares" is no marker
        pattern = re.compile(rf"(?<![\w-]){re.escape(word)}(s|es)?(?![\w-])")
        if not pattern.search(text):
            return False
        text = pattern.sub(" ", text)  # read once: "sky blue" is not "blue" too
        return word not in maybe

    for word in sorted(COLOUR_WORDS, key=len, reverse=True):
        if said(word) and not _has_colour(drawn["colours"], COLOUR_WORDS[word]):
            problems.append(f"the caption says {word!r} but nothing is drawn {word}")
    for style, word in LINE_STYLE_WORDS.items():
        if said(word) and style not in drawn["line styles"]:
            problems.append(f"the caption says {word!r} but no line is {word}")
    markers = sorted(MARKER_WORDS.items(), key=lambda kv: len(kv[1]), reverse=True)
    for marker, word in markers:
        if said(word) and marker not in drawn["markers"]:
            problems.append(f"the caption says {word!r} but no marker is a {word}")
    if said("triangle") and not drawn["markers"] & {"^", "v", "<", ">"}:
        problems.append("the caption says 'triangle' but no marker is a triangle")
    for word in ("filled", "hollow"):
        if said(word) and word not in drawn["faces"]:
            problems.append(f"the caption says {word!r} but no marker is {word}")
    return problems


def _drawn_styles(fig: Figure) -> dict[str, set[str]]:
    """Colours (hex), line styles, markers and marker faces (filled, hollow) of the lines,
    collections and patches of every visible axes of ``fig``."""
    from matplotlib.colors import to_hex

    out: dict[str, set[str]] = {"colours": set(), "line styles": set(), "markers": set()}
    out["faces"] = set()
    for ax in fig.axes:
        if not ax.get_visible():
            continue
        for line in ax.get_lines():
            if not _shows(line):
                continue
            ls, mk = line.get_linestyle(), str(line.get_marker())
            if ls not in _NO_LINE:
                out["line styles"].add(str(ls))
                out["colours"].add(to_hex(line.get_color()))
            if mk not in _NO_LINE:
                out["markers"].add(mk)
                face, edge = line.get_markerfacecolor(), line.get_markeredgecolor()
                hollow = str(face).lower() == "none" or to_hex(face) in {"#ffffff"}
                out["faces"].add("hollow" if hollow else "filled")
                out["colours"].add(to_hex(edge))
                if not hollow:
                    out["colours"].add(to_hex(face))
        for coll in ax.collections:
            if coll.get_visible():
                for rgba in (*coll.get_edgecolor(), *coll.get_facecolor()):
                    if rgba[3] > 0:
                        out["colours"].add(to_hex(rgba))
        for patch in ax.patches:
            if patch.get_visible():
                out["colours"].add(to_hex(patch.get_facecolor()))
    return out


def _has_colour(colours: set[str], want: str) -> bool:
    """Whether ``want`` (hex, or ``"grey"``: any grey between black and white) is drawn."""
    if want != "grey":
        return want.lower() in colours
    return any(c[1:3] == c[3:5] == c[5:7] and c not in ("#000000", "#ffffff") for c in colours)
