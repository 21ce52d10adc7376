"""Figures of the closed loop: Fig. 10 (staircase responses) and Fig. 11 (metrics against the
operating point), for every modulator setting and controller."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import pandas as pd

from spa.plots.style import MODULATOR_COLOURS, new_figure, ordered_settings, setting_colours

if TYPE_CHECKING:
    from matplotlib.figure import Figure

__all__ = ["CONTROLLER_STYLES", "fig10", "fig11"]

#: Line style and name of each controller, in every closed-loop figure.
CONTROLLER_STYLES: dict[str, tuple[str, str, str]] = {
    "fixed": ("-", "#000000", "fixed PI"),
    "scheduled": ("-", "#0072B2", "scheduled PI"),
    "scheduled_ff": ("--", "#D55E00", "scheduled PI + feed-forward"),
}


def _kind(label: str) -> str:
    return label.split("-", 1)[0]


def fig10(traces: pd.DataFrame) -> Figure:
    """Cycle-mean pressure over the set-point staircase, one panel per setting.

    Parameters
    ----------
    traces : pandas.DataFrame
        ``modulator``, ``controller``, ``t``, ``r``, ``p_mean``
        (:class:`spa.closedloop.stage.ClosedLoopResult`'s ``traces``).
    """
    labels = ordered_settings(traces["modulator"])
    ncols = 2 if len(labels) > 1 else 1
    nrows = math.ceil(len(labels) / ncols)
    fig = new_figure(figsize=(10.0, 2.2 * nrows + 0.6), layout="constrained")
    axes = fig.subplots(nrows, ncols, sharex=True, sharey=True, squeeze=False).ravel()
    for ax, label in zip(axes, labels, strict=False):
        sel = traces[traces["modulator"] == label]
        first = sel[sel["controller"] == sel["controller"].iloc[0]]
        ax.plot(first["t"], first["r"], color="0.6", lw=1.0, ls=":", label="set-point")
        for name, (ls, colour, text) in CONTROLLER_STYLES.items():
            rows = sel[sel["controller"] == name]
            if len(rows):
                ax.plot(rows["t"], rows["p_mean"], ls=ls, color=colour, lw=1.0, label=text)
        ax.set_title(label, fontsize=9, color=MODULATOR_COLOURS.get(_kind(label), "black"))
        ax.grid(alpha=0.3)
    for ax in axes[len(labels) :]:
        ax.axis("off")
    for ax in axes[(nrows - 1) * ncols :]:
        ax.set_xlabel("t (s)")
    for ax in axes[::ncols]:
        ax.set_ylabel("cycle-mean P (bar)")
    axes[0].legend(fontsize=7, loc="upper left")
    fig.suptitle("Fig. 10: closed-loop staircase, fixed against gain-scheduled PI", fontsize=10)
    return fig


def fig11(steps: pd.DataFrame) -> Figure:
    """Rise time and overshoot of each staircase step against its set-point, per controller.

    Parameters
    ----------
    steps : pandas.DataFrame
        One row per step (:class:`spa.closedloop.stage.ClosedLoopResult`'s ``steps``), with
        ``experiment``, ``modulator``, ``controller``, ``r0``, ``r1`` and the metrics.
    """
    rows = steps[steps["experiment"] == "staircase"]
    labels = ordered_settings(rows["modulator"])
    colours = dict(zip(labels, setting_colours(len(labels)), strict=True))
    names = [n for n in CONTROLLER_STYLES if (rows["controller"] == n).any()]
    metrics = (("rise_time", "rise time 10–90 % (s)"), ("overshoot", "overshoot (%)"))
    fig = new_figure(figsize=(10.0, 5.2), layout="constrained")
    axes = fig.subplots(len(metrics), len(names), sharex=True, sharey="row", squeeze=False)
    for j, name in enumerate(names):
        sel = rows[rows["controller"] == name]
        axes[0, j].set_title(CONTROLLER_STYLES[name][2], fontsize=9)
        for i, (metric, text) in enumerate(metrics):
            ax = axes[i, j]
            for label in labels:
                c = sel[sel["modulator"] == label]
                up, down = c[c["r1"] > c["r0"]], c[c["r1"] < c["r0"]]
                ax.plot(up["r1"], up[metric], "-^", ms=4, lw=1.0, color=colours[label], label=label)
                ax.plot(down["r1"], down[metric], ":v", ms=4, lw=0.8, color=colours[label])
            ax.grid(alpha=0.3)
            if j == 0:
                ax.set_ylabel(text, fontsize=8)
    for ax in axes[-1]:
        ax.set_xlabel("set-point after the step (bar)")
    axes[0, 0].legend(fontsize=7, title="▲ up, ▼ down", title_fontsize=7)
    fig.suptitle("Fig. 11: closed-loop step metrics against the operating point", fontsize=10)
    return fig
