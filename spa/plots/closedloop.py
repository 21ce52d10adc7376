"""Figures of the closed loop: Fig. 10 (staircase responses) and Fig. 11 (metrics against the
operating point), for every modulator setting and controller."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import pandas as pd

from spa.plots.reduce import plot_reduced
from spa.plots.style import (
    MODULATOR_COLOURS,
    new_figure,
    ordered_settings,
    setting_kind,
    setting_styles,
    shade,
)
from spa.plots.words import CONTROLLER_STYLES, LINE_STYLE_WORDS, SET_POINT_STYLE, STEP_STYLES

if TYPE_CHECKING:
    from matplotlib.figure import Figure

__all__ = ["CONTROLLER_STYLES", "fig10", "fig11", "no_design"]


def _colour(label: str) -> str:
    """A setting's colour: its modulator type's (declared by the type's module)."""
    kind = setting_kind(label)
    return MODULATOR_COLOURS[kind] if kind is not None else "#808080"


def no_design(text: str) -> Figure:
    """A figure that says why there is nothing to draw (no loop designed for the valve).

    Parameters
    ----------
    text : str
        The closed-loop sentence (``controllers.yaml``'s ``sentence``).

    Returns
    -------
    matplotlib.figure.Figure
        One empty axes-free panel holding ``text``, wrapped.
    """
    import textwrap

    fig = new_figure(figsize=(10.0, 2.4), layout="constrained")
    fig.text(0.02, 0.5, textwrap.fill(text, 110), va="center", ha="left", fontsize=10)
    return fig


def fig10(traces: pd.DataFrame) -> Figure:
    """Cycle-mean pressure over the set-point staircase, one panel per setting.

    Parameters
    ----------
    traces : pandas.DataFrame
        ``modulator``, ``controller``, ``t``, ``r``, ``p_mean``
        (:class:`spa.closedloop.comparison.ClosedLoopResult`'s ``traces``).

    Returns
    -------
    matplotlib.figure.Figure
        Two panels a row, each in its modulator's colour; the controllers told apart by line
        style and lightness (:data:`CONTROLLER_STYLES`); one legend, below the panels.
    """
    labels = ordered_settings(traces["modulator"])
    ncols = 2 if len(labels) > 1 else 1
    nrows = math.ceil(len(labels) / ncols)
    fig = new_figure(figsize=(10.0, 2.2 * nrows + 1.0), layout="constrained")
    axes = fig.subplots(nrows, ncols, sharex=True, sharey=True, squeeze=False).ravel()
    for ax, label in zip(axes, labels, strict=False):
        sel = traces[traces["modulator"] == label]
        first = sel[sel["controller"] == sel["controller"].iloc[0]]
        colour = _colour(label)
        grey, dots = SET_POINT_STYLE
        plot_reduced(ax, first["t"], first["r"], color=grey, lw=1.0, ls=dots, label="set-point")
        for name, (ls, amount, text, _) in CONTROLLER_STYLES.items():
            rows = sel[sel["controller"] == name]
            if len(rows):
                plot_reduced(
                    ax, rows["t"], rows["p_mean"], ls=ls, color=shade(colour, amount), lw=1.1,
                    label=text,
                )  # fmt: skip
        ax.set_title(label, fontsize=10, color=colour)
        ax.grid(alpha=0.3)
    for ax in axes[len(labels) :]:
        ax.axis("off")
    for i, ax in enumerate(axes[: len(labels)]):
        if i + ncols >= len(labels):  # nothing drawn below: this panel reads the time axis
            ax.set_xlabel("t (s)")
            ax.xaxis.set_tick_params(labelbottom=True)
    for ax in axes[::ncols]:
        ax.set_ylabel("cycle-mean P (bar)")
    from matplotlib.lines import Line2D

    handles = [Line2D([], [], color=SET_POINT_STYLE[0], lw=1.0, ls=SET_POINT_STYLE[1])]
    texts = ["set-point"]
    for name, (ls, amount, text, _) in CONTROLLER_STYLES.items():
        if (traces["controller"] == name).any():
            handles.append(Line2D([], [], ls=ls, color=shade("#808080", amount), lw=1.1))
            texts.append(text)
    fig.legend(
        handles, texts, loc="outside lower center", ncols=len(handles), fontsize=9,
        title="line style and shade of the panel's colour: controller", title_fontsize=9,
    )  # fmt: skip
    fig.suptitle("Fig. 10: closed-loop staircase, fixed against gain-scheduled PI", fontsize=11)
    return fig


def fig11(steps: pd.DataFrame) -> Figure:
    """Rise time and overshoot of each staircase step against its set-point, per controller.

    Parameters
    ----------
    steps : pandas.DataFrame
        One row per step (:class:`spa.closedloop.comparison.ClosedLoopResult`'s ``steps``), with
        ``experiment``, ``modulator``, ``controller``, ``r0``, ``r1`` and the metrics.

    Returns
    -------
    matplotlib.figure.Figure
        One column per controller, a row per metric. Each setting in its modulator's colour
        (:func:`spa.plots.style.setting_styles`: the settings of one type by marker and
        shade); steps up solid with filled markers, steps down dotted with hollow ones. The
        legend sits right of the panels.
    """
    from matplotlib.lines import Line2D

    rows = steps[steps["experiment"] == "staircase"]
    styles = setting_styles(rows["modulator"])
    up_ls, down_ls = STEP_STYLES["up"][0], STEP_STYLES["down"][0]
    names = [n for n in CONTROLLER_STYLES if (rows["controller"] == n).any()]
    metrics = (("rise_time", "rise time 10–90 % (s)"), ("overshoot", "overshoot (%)"))
    fig = new_figure(figsize=(11.0, 5.6), layout="constrained")
    axes = fig.subplots(len(metrics), len(names), sharex=True, sharey="row", squeeze=False)
    for j, name in enumerate(names):
        sel = rows[rows["controller"] == name]
        axes[0, j].set_title(CONTROLLER_STYLES[name][2], fontsize=10)
        for i, (metric, text) in enumerate(metrics):
            ax = axes[i, j]
            for label, style in styles.items():
                c = sel[sel["modulator"] == label]
                up, down = c[c["r1"] > c["r0"]], c[c["r1"] < c["r0"]]
                ax.plot(up["r1"], up[metric], ls=up_ls, ms=5, lw=1.1, label=label, **style)
                ax.plot(down["r1"], down[metric], ls=down_ls, ms=5, lw=1.0, mfc="white", **style)
            ax.grid(alpha=0.3)
            if j == 0:
                ax.set_ylabel(text)
    for ax in axes[-1]:
        ax.set_xlabel("set-point after the step (bar)")
    handles = [Line2D([], [], ls="-", lw=1.1, ms=5, **style) for style in styles.values()]
    texts = list(styles)
    handles += [
        Line2D([], [], ls=up_ls, marker="o", color="0.3", lw=1.1, ms=5),
        Line2D([], [], ls=down_ls, marker="o", mfc="white", color="0.3", lw=1.0, ms=5),
    ]
    texts += [
        f"step {way} ({LINE_STYLE_WORDS[ls]}, {face})" for way, (ls, face) in STEP_STYLES.items()
    ]
    fig.legend(handles, texts, loc="outside right upper", fontsize=9)
    fig.suptitle("Fig. 11: closed-loop step metrics against the operating point", fontsize=11)
    return fig
