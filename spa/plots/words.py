"""The style table of the figures in words: what each colour, line style and marker is called,
and the captions written from the tables the figures are drawn with.

A caption that names a style takes the word from here, and the figure takes the style from
the same table, so that the two cannot drift; :func:`spa.plots.check.caption_problems`
checks each style word of a caption against the drawn artists. This module imports nothing
(the registry of outputs, :mod:`spa.pipeline.stage_table`, reads its captions when the workflow
is parsed).

>>> LINE_STYLE_WORDS["--"], MARKER_WORDS["s"]
('dashed', 'square')
>>> shade_words(-0.45)
"a darker shade of the panel's colour"
>>> shade_words(0.0)
"the panel's colour"
"""

from __future__ import annotations

from typing import Final

__all__ = [
    "CHANGED_RING",
    "COLOUR_WORDS",
    "CONTROLLER_STYLES",
    "FIG10_CAPTION",
    "FIG11_CAPTION",
    "LINE_STYLE_WORDS",
    "MARKER_WORDS",
    "O1_CAPTION",
    "O1_CONDITIONAL",
    "SETTING_MARKERS",
    "SET_POINT_STYLE",
    "STEP_STYLES",
    "noted",
    "shade_words",
]

#: The word for each colour of the palette (:data:`spa.plots.style.OKABE_ITO`) and of the
#: other colours the figures draw with, lower-case hex. ``grey`` stands for every
#: achromatic colour between black and white (:func:`spa.plots.check.caption_problems`).
COLOUR_WORDS: Final[dict[str, str]] = {
    "black": "#000000",
    "orange": "#e69f00",
    "sky blue": "#56b4e9",
    "bluish green": "#009e73",
    "yellow": "#f0e442",
    "blue": "#0072b2",
    "vermillion": "#d55e00",
    "reddish purple": "#cc79a7",
    "red": "#c0392b",
    "grey": "grey",
}

#: Fig. O1's ring around a session whose interval excludes its valve's previous one.
CHANGED_RING: Final = COLOUR_WORDS["red"]

#: Matplotlib's line styles in words.
LINE_STYLE_WORDS: Final[dict[str, str]] = {
    "-": "solid",
    "--": "dashed",
    ":": "dotted",
    "-.": "dash-dot",
}

#: Matplotlib's markers in words (singular; a caption may use the plural).
MARKER_WORDS: Final[dict[str, str]] = {
    "o": "circle",
    "s": "square",
    "D": "diamond",
    "^": "upward triangle",
    "v": "downward triangle",
    "P": "filled plus",
    "X": "filled cross",
    "h": "hexagon",
}

#: Markers of the settings of one modulator type, in numeric order
#: (:func:`spa.plots.style.setting_styles`).
SETTING_MARKERS: Final = ("o", "s", "D", "^", "v", "P", "X", "h")

#: Fig. 10's controllers, where the three share a panel of one setting: key -> (line style,
#: lightness (:func:`spa.plots.style.shade` of the panel's colour), legend name, name in
#: the caption).
CONTROLLER_STYLES: Final[dict[str, tuple[str, float, str, str]]] = {
    "fixed": ("-", -0.45, "fixed PI", "fixed PI"),
    "scheduled": ("--", 0.0, "scheduled PI", "gain-scheduled PI"),
    "scheduled_ff": (
        "-.",
        0.4,
        "scheduled PI + feed-forward",
        "gain-scheduled PI with the averaged model's feed-forward",
    ),
}

#: Fig. 11's steps: direction -> (line style, marker face: "filled" or "hollow").
STEP_STYLES: Final[dict[str, tuple[str, str]]] = {"up": ("-", "filled"), "down": (":", "hollow")}

#: The set-point's line in Fig. 10: colour (grey), line style.
SET_POINT_STYLE: Final = ("0.6", ":")


def noted(text: str, note: str) -> str:
    """``text`` with ``note`` in parentheses after it, or ``text`` alone when ``note`` is
    blank: a legend or a title never shows empty parentheses.

    Examples
    --------
    >>> noted("d: no discharge fit", "k2 from the fallback")
    'd: no discharge fit (k2 from the fallback)'
    >>> noted("d: no discharge fit", "")
    'd: no discharge fit'
    """
    note = note.strip()
    return f"{text} ({note})" if note else text


def shade_words(amount: float) -> str:
    """A lightness of :func:`spa.plots.style.shade` in words, relative to the panel's colour."""
    if amount == 0.0:
        return "the panel's colour"
    return f"a {'darker' if amount < 0 else 'lighter'} shade of the panel's colour"


def _fig10_caption() -> str:
    parts = [
        f"{caption} ({LINE_STYLE_WORDS[ls]}, {shade_words(amount)})"
        for ls, amount, _, caption in CONTROLLER_STYLES.values()
    ]
    listed = ", ".join(parts[:-1]) + " and " + parts[-1]
    return (
        "Cycle-mean pressure over the set-point staircase up and down, one panel per "
        f"setting, in its modulator's colour: {listed}; the set-point "
        f"{LINE_STYLE_WORDS[SET_POINT_STYLE[1]]} grey."
    )


def _fig11_caption() -> str:
    first = MARKER_WORDS[SETTING_MARKERS[0]]
    up, down = STEP_STYLES["up"], STEP_STYLES["down"]
    return (
        "Rise time (10-90 %) and overshoot of each staircase step against the set-point "
        "after it, one column per controller. Each setting in its modulator's colour; the "
        f"first setting of a modulator with {first}s, any further one with another marker "
        f"and shade. Rising steps: {LINE_STYLE_WORDS[up[0]]} lines, {up[1]} markers; falling "
        f"steps, which the exhaust limits: {LINE_STYLE_WORDS[down[0]]} lines, {down[1]} "
        "markers."
    )


FIG10_CAPTION: Final = _fig10_caption()
"""Fig. 10's caption, from :data:`CONTROLLER_STYLES`."""

FIG11_CAPTION: Final = _fig11_caption()
"""Fig. 11's caption, from :data:`SETTING_MARKERS`."""

O1_CAPTION: Final = (
    "Each identified parameter against the session's date (dataset.yaml recorded:; undated "
    "sessions after the dated ones, by name, and said so on the axis) with its 95 % "
    "interval, one colour per rig; for each valve (its rig and the dataset's own valve name; "
    "a simulated dataset is a valve of its own) with two sessions or more, the "
    f"least-squares trend ({LINE_STYLE_WORDS['--']}) and a red {MARKER_WORDS['o']} around "
    "a session whose interval excludes the previous session's of the same valve: the valve "
    "changed."
)
"""Fig. O1's caption."""

O1_CONDITIONAL: Final = (LINE_STYLE_WORDS["--"], "red", MARKER_WORDS["o"])
"""Style words of :data:`O1_CAPTION` for what Fig. O1 draws only when the sessions have it
(a valve's trend, a changed valve's ring): :func:`spa.plots.check.caption_problems`'s
``conditional``."""
