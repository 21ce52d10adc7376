"""Figures of the open-loop experiments (paper Figs. 6–9), drawn from tidy tables.

Each function takes the table the workflow writes beside the PNG (or, for Fig. 9, the maps)
and returns a matplotlib Figure built without pyplot; save it with
:func:`spa.io.save_figure`. `no_data_figure` stands in when a dataset has no run of a kind.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
import pandas as pd
from matplotlib.figure import Figure

from spa.model.modulators import MODULATOR_ORDER
from spa.openloop import PAPER_TIME_CONSTANTS
from spa.openloop.spectra import principal_domain_mask
from spa.plots.analytic import _COLOURS, _LABELS, _require

__all__ = ["fig6", "fig7a", "fig7b", "fig8", "fig9", "no_data_figure", "thin"]


def _kinds(df: pd.DataFrame) -> list[str]:
    """The modulators present, in the paper's Table 3 order."""
    return [k for k in MODULATOR_ORDER if (df["modulator"] == k).any()]


def thin(df: pd.DataFrame, max_points: int) -> pd.DataFrame:
    """Every k-th row, with k the smallest step leaving at most ``max_points`` rows.

    Examples
    --------
    >>> len(thin(pd.DataFrame({"t": range(10)}), 4))
    4
    """
    if max_points < 1:
        raise ValueError(f"max_points must be >= 1, got {max_points}")
    step = -(-len(df) // max_points)
    return df.iloc[:: max(step, 1)]


def no_data_figure(message: str) -> Figure:
    """A small figure that says why there is nothing to show."""
    fig = Figure(figsize=(6.0, 1.6), layout="constrained")
    ax = fig.add_subplot()
    ax.axis("off")
    ax.text(0.5, 0.5, message, ha="center", va="center", fontsize=10, wrap=True)
    return fig


def write_no_runs(
    message: str, tables: Sequence[str | Path], figures: Sequence[str | Path]
) -> None:
    """The outputs of an analysis for a dataset without runs of its kind: tables with the
    tag columns and no row, and figures that say ``message``."""
    from spa.io import save_figure, write_csv

    empty = pd.DataFrame(columns=["run", "modulator", "setting", "gain"])
    for path in tables:
        write_csv(empty, path)
    for path in figures:
        save_figure(no_data_figure(message), path)


def fig6(traces: pd.DataFrame) -> Figure:
    """Fig. 6: pressure against time under the staircase, one panel per modulator.

    Parameters
    ----------
    traces : pandas.DataFrame
        Columns ``modulator``, ``setting``, ``t`` (s), ``p`` (bar); one curve per setting.
    """
    _require(traces, ["modulator", "setting", "t", "p"], "traces")
    kinds = _kinds(traces)
    if not kinds:
        raise ValueError("traces: no known modulator")
    fig = Figure(figsize=(10.0, 2.4 * len(kinds)), layout="constrained")
    axes = fig.subplots(len(kinds), 1, sharex=True, squeeze=False)[:, 0]
    for ax, kind in zip(axes, kinds, strict=True):
        d = traces[traces["modulator"] == kind]
        for setting, g in d.groupby("setting", sort=False):
            ax.plot(g["t"], g["p"], lw=0.7, label=setting)
        ax.set_title(_LABELS[kind], fontsize=9, loc="left")
        ax.set_ylabel("P (bar)")
        ax.grid(True, lw=0.3, alpha=0.5)
        ax.legend(fontsize=7, loc="upper left", ncol=2)
    axes[-1].set_xlabel("time (s)")
    return fig


def fig7a(levels: pd.DataFrame, k2: float) -> Figure:
    """Fig. 7a: equilibrium pressure against input fraction, with the ideal line ``k2*xi``.

    Parameters
    ----------
    levels : pandas.DataFrame
        Columns ``modulator``, ``setting``, ``gain`` (IPFM/IIPFM gain: other than 1 is drawn
        with squares), ``xi``, ``p_eq`` (bar) and ``fit`` (% of the setting's line fit, shown
        in the legend).
    k2 : float
        Supply (saturation) pressure in bar, the slope of the ideal line.
    """
    _require(levels, ["modulator", "setting", "gain", "xi", "p_eq", "fit"], "levels")
    fig = Figure(figsize=(6.0, 4.5), layout="constrained")
    ax = fig.add_subplot()
    ax.plot([0.0, 1.0], [0.0, k2], "k--", lw=1.0, label=f"ideal: k2·ξ (k2 = {k2:.3f} bar)")
    for setting, g in levels.groupby("setting", sort=False):
        kind, gained = g["modulator"].iloc[0], g["gain"].iloc[0] != 1.0
        ax.plot(
            g["xi"],
            g["p_eq"],
            "s-" if gained else "o-",
            ms=4,
            lw=1.2,
            color=_COLOURS.get(kind),
            alpha=0.6 if gained else 1.0,
            label=f"{setting} (FIT {g['fit'].iloc[0]:.1f} %)",
        )
    ax.set_xlabel("input fraction ξ")
    ax.set_ylabel("equilibrium pressure (bar)")
    ax.set_xlim(0.0, 1.0)
    ax.grid(True, lw=0.3, alpha=0.5)
    ax.legend(fontsize=8, loc="upper left")
    ax.set_title("Static linearity: best setting of each modulator", fontsize=10)
    return fig


def fig7b(steps: pd.DataFrame) -> Figure:
    """Fig. 7b: time constant of each staircase step against the level stepped to.

    Parameters
    ----------
    steps : pandas.DataFrame
        Columns ``modulator``, ``setting``, ``gain`` (as in `fig7a`), ``xi_to`` and ``tau``
        (s, NaN skipped).
    """
    _require(steps, ["modulator", "setting", "gain", "xi_to", "tau"], "steps")
    fig = Figure(figsize=(6.0, 4.5), layout="constrained")
    ax = fig.add_subplot()
    for setting, g in steps.groupby("setting", sort=False):
        kind, gained = g["modulator"].iloc[0], g["gain"].iloc[0] != 1.0
        g = g[np.isfinite(g["tau"])]
        if g.empty:
            continue
        label = f"{setting}: {g['tau'].mean():.3f} ± {g['tau'].std():.3f} s"
        ax.plot(
            g["xi_to"],
            g["tau"],
            "s-" if gained else "o-",
            ms=4,
            color=_COLOURS.get(kind),
            alpha=0.6 if gained else 1.0,
            label=label,
        )
    paper = ", ".join(
        f"{_LABELS[k]} {m:.3f} ± {s:.3f} s" for k, (m, s) in PAPER_TIME_CONSTANTS.items()
    )
    ax.set_xlabel("input fraction after the step ξ")
    ax.set_ylabel("time constant (s), 63.2 % of the step")
    ax.grid(True, lw=0.3, alpha=0.5)
    ax.legend(fontsize=8, loc="lower right", title="mean ± sd", title_fontsize=8)
    ax.set_title(f"Step time constants (paper, bench: {paper})", fontsize=9)
    return fig


def fig8(aligned: pd.DataFrame) -> Figure:
    """Fig. 8: normalised pressure against input fraction after lag compensation.

    Parameters
    ----------
    aligned : pandas.DataFrame
        Columns ``modulator``, ``setting``, ``xi`` and ``p_norm``, and ``rms`` (the setting's
        RMS deviation from the line, shown in the legend).
    """
    _require(aligned, ["modulator", "setting", "xi", "p_norm", "rms"], "aligned")
    kinds = _kinds(aligned)
    if not kinds:
        raise ValueError("aligned: no known modulator")
    fig = Figure(figsize=(3.2 * len(kinds), 3.6), layout="constrained")
    axes = fig.subplots(1, len(kinds), sharey=True, squeeze=False)[0]
    for ax, kind in zip(axes, kinds, strict=True):
        ax.plot([0, 1], [0, 1], "k--", lw=1.0, label="ideal")
        for setting, g in aligned[aligned["modulator"] == kind].groupby("setting", sort=False):
            ax.plot(g["xi"], g["p_norm"], lw=0.6, label=f"{setting} (RMS {g['rms'].iloc[0]:.3f})")
        ax.set_title(_LABELS[kind], fontsize=9)
        ax.set_xlabel("input fraction ξ")
        ax.set_xlim(0.0, 1.0)
        ax.set_ylim(0.0, 1.05)
        ax.set_aspect("equal")
        ax.grid(True, lw=0.3, alpha=0.5)
        ax.legend(fontsize=6, loc="upper left")
    axes[0].set_ylabel("P / max(P)")
    return fig


def fig9(maps: Sequence[tuple[str, np.ndarray, np.ndarray]], vmax: float | None = None) -> Figure:
    """Fig. 9: bicoherence over the principal domain, one panel per map.

    Parameters
    ----------
    maps : sequence of (title, f, bic)
        Frequency axis (Hz) and map as returned by `spa.openloop.spectra.bicoherence`.
    vmax : float, optional
        Top of the common colour scale (default: the largest value in the panels' domains,
        capped at 1 so a few near-empty bins do not wash out the maps).
    """
    if not maps:
        raise ValueError("maps: nothing to plot")
    fig = Figure(figsize=(3.4 * len(maps), 3.4), layout="constrained")
    axes = fig.subplots(1, len(maps), squeeze=False)[0]
    shown = []
    for _, f, bic in maps:
        mask = principal_domain_mask(f)
        shown.append(np.where(mask, bic, np.nan))
    top = vmax if vmax is not None else min(1.0, float(max(np.nanmax(s) for s in shown)))
    image = None
    for ax, (title, f, _), z in zip(axes, maps, shown, strict=True):
        pos = f >= 0
        fp = f[pos]
        zz = z[np.ix_(pos, pos)]  # rows f1, columns f2
        step = fp[1] - fp[0] if fp.size > 1 else 1.0
        edges = np.concatenate((fp - step / 2, [fp[-1] + step / 2]))
        image = ax.pcolormesh(edges, edges, zz.T, vmin=0.0, vmax=top, cmap="viridis")
        ax.set_xlim(0.0, fp[-1])
        ax.set_ylim(0.0, fp[-1] / 2)
        ax.set_xlabel("f1 (Hz)")
        ax.set_title(title, fontsize=9)
    axes[0].set_ylabel("f2 (Hz)")
    fig.colorbar(image, ax=list(axes), label="bicoherence", shrink=0.9)
    return fig
