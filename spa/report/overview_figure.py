"""Fig. O1: the identified valve across sessions (:mod:`spa.report.overview`)."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
import pandas as pd

from spa.plots.style import new_figure, setting_colours
from spa.plots.words import CHANGED_RING
from spa.report.overview import UNDATED, session_days, trend
from spa.report.params import PARAM_NAMES

if TYPE_CHECKING:
    from matplotlib.figure import Figure

__all__ = ["plot_overview"]

_SCALE = {
    "t_on": (1e3, "t_on (ms)"),
    "t_off": (1e3, "t_off (ms)"),
    "c1": (1.0, "c1 (s·bar$^{-1/2}$)"),
}
_SCALE |= {"k2": (1.0, "k2 (bar)"), "tau2": (1.0, "tau2 (s)")}


def plot_overview(table: pd.DataFrame) -> Figure:
    """Fig. O1: each parameter against the session, with its interval, trend and changes.

    Parameters
    ----------
    table : pandas.DataFrame
        :func:`spa.report.overview.overview_table`.

    Returns
    -------
    matplotlib.figure.Figure
        One panel per parameter; x the days since the first session when every session is
        dated, else the session's position in the table's order (dated sessions by date,
        then the undated ones by name; the axis says so); one colour per rig, the rigs in
        sorted order (the same rigs, the same colours, whatever the order of the datasets);
        error bars the 95 % intervals; the least-squares trend of each valve (column
        ``valve``, :func:`spa.report.overview.valve_identity`; the rig where absent) with two
        sessions or more dashed; a red ring on each session whose interval excludes the
        previous one's of its valve (``changed_<p>``). The legend, below the panels, names
        only the rigs with a point.
    """
    fig = new_figure(figsize=(7.0, 8.0), layout="constrained")
    axes = fig.subplots(len(PARAM_NAMES), 1, sharex=True)
    recorded = [str(r) for r in table.get("recorded", pd.Series(dtype=str))]
    x = session_days(recorded)
    dated = bool(len(recorded)) and UNDATED not in recorded
    rig_of = table.get("rig", pd.Series(dtype=str)).fillna("").astype(str).to_numpy()
    rigs = sorted(set(rig_of))
    valve_of = table["valve"].fillna("").astype(str).to_numpy() if "valve" in table else rig_of
    colours = dict(zip(rigs, setting_colours(len(rigs)), strict=True))
    for ax, p in zip(axes, PARAM_NAMES, strict=True):
        scale, label = _SCALE[p]
        value = table[p].to_numpy(float) * scale if len(table) else np.array([])
        lo = table[f"{p}_lo"].to_numpy(float) * scale if len(table) else value
        hi = table[f"{p}_hi"].to_numpy(float) * scale if len(table) else value
        for rig in rigs:
            m = (rig_of == rig) & np.isfinite(value)
            if not m.any():  # no point of this rig here: no legend entry either
                continue
            err = np.vstack([value[m] - lo[m], hi[m] - value[m]])
            ax.errorbar(
                x[m],
                value[m],
                yerr=np.abs(err),
                fmt="o",
                ms=4,
                capsize=2,
                color=colours[rig],
                label=rig,
            )
            for valve in sorted(set(valve_of[m])):  # one trend per valve, never across valves
                v = m & (valve_of == valve)
                a, b = trend(x[v], value[v])
                if np.isfinite(b):
                    ends = x[v][[0, -1]]
                    ax.plot(ends, a + b * ends, "--", color=colours[rig], lw=1, label="_trend")
        changed = table[f"changed_{p}"].to_numpy(bool) if len(table) else np.zeros(0, bool)
        if changed.any():
            ax.plot(
                x[changed],
                value[changed],
                "o",
                ms=11,
                mfc="none",
                mec=CHANGED_RING,
                mew=1.5,
                label="changed",
            )
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
    entries: dict[str, object] = {}
    for ax in axes:
        for h, lab in zip(*ax.get_legend_handles_labels(), strict=True):
            entries.setdefault(lab, h)
    changed = entries.pop("changed", None)
    labels = [r for r in rigs if r in entries] + (["changed"] if changed is not None else [])
    if labels:
        handles = [entries[r] for r in rigs if r in entries] + ([changed] if changed else [])
        fig.legend(handles, labels, loc="outside lower center", ncols=min(len(labels), 3))
    if dated:
        axes[-1].set_xlabel(f"days since the first session ({recorded[0]})")
    elif any(r != UNDATED for r in recorded):
        axes[-1].set_xlabel("session: the dated ones by date, then the undated ones by name")
    else:
        axes[-1].set_xlabel("session, in name order (no dataset has a recorded: date)")
        if 0 < len(table) <= 20:
            axes[-1].set_xticks(x, [str(d) for d in table["dataset"]], rotation=30, ha="right")
    fig.suptitle("Fig. O1: identified valve parameters across sessions", fontsize=11)
    return fig
