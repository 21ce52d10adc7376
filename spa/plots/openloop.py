"""Figures of the open-loop experiments (paper Figs. 6–9), drawn from tidy tables.

Each function takes the table the workflow writes beside the PNG (or, for Fig. 9, the maps)
and returns a matplotlib Figure built without pyplot; save it with
:func:`spa.plots.save.save_figure`. `no_data_figure` stands in when a dataset has no run of a kind.

Figs. 7a, 7b and 9 show the settings the paper shows (chosen by
:func:`spa.openloop.selection.paper_settings`) and, in a panel of their own, the sweep over
every setting of the dataset; Figs. 8 and 9 show the linear reference beside the runs.
"""

from __future__ import annotations

import textwrap
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import pandas as pd

from spa.model.modulators import MODULATOR_ORDER
from spa.openloop.paper import PAPER_TIME_CONSTANTS
from spa.openloop.reference import REFERENCE
from spa.openloop.spectra import principal_domain_mask
from spa.plots.analytic import _COLOURS, _LABELS, _require
from spa.plots.reduce import plot_reduced
from spa.plots.style import (
    legend_beside,
    minmax_indices,
    new_figure,
    ordered_settings,
    setting_colours,
    setting_sort_key,
)

if TYPE_CHECKING:
    from matplotlib.figure import Figure

__all__ = [
    "DECADE",
    "fig6",
    "fig7a",
    "fig7b",
    "fig8",
    "fig9",
    "fig9_data",
    "no_data_figure",
    "tau_outliers",
    "thin",
]

DECADE = 10.0
"""A step time constant this many times off the dataset's median is an outlier
(:func:`tau_outliers`)."""


def _kinds(df: pd.DataFrame) -> list[str]:
    """The modulators present, in the paper's Table 3 order."""
    return [k for k in MODULATOR_ORDER if (df["modulator"] == k).any()]


def _groups(df: pd.DataFrame):
    """``(setting, rows)`` in the settings' numeric order (:mod:`spa.plots.style`)."""
    for setting in ordered_settings(df["setting"]):
        yield setting, df[df["setting"] == setting]


def _sorted(table: pd.DataFrame) -> pd.DataFrame:
    """The rows in the numeric order of their ``setting`` (stable)."""
    keys = table["setting"].map(setting_sort_key)
    return table.iloc[sorted(range(len(table)), key=lambda i: keys.iloc[i])]


def thin(df: pd.DataFrame, max_points: int, x: str = "t") -> pd.DataFrame:
    """At most ``max_points`` rows of a trace that draw like all of them: per column of ``x``
    its first and last row and the rows of the smallest and largest value of every other
    numeric column (:func:`spa.plots.style.minmax_indices`), so that every peak and the
    envelope of chattering stay; without a column ``x``, every k-th row.

    Examples
    --------
    >>> trace = pd.DataFrame({"t": range(10000), "p": [0.0] * 9999 + [1.0]})
    >>> small = thin(trace, 400)
    >>> len(small) <= 400, float(small["p"].max())
    (True, 1.0)
    """
    if max_points < 1:
        raise ValueError(f"max_points must be >= 1, got {max_points}")
    if len(df) <= max_points:
        return df
    if x not in df.columns:
        return df.iloc[:: -(-len(df) // max_points)]
    ys = [c for c in df.select_dtypes("number").columns if c != x]
    columns = max(1, max_points // (2 + 2 * len(ys)))
    return df.iloc[minmax_indices(df[x], [df[c] for c in ys], columns)]


def no_data_figure(message: str) -> Figure:
    """A small figure that says why there is nothing to show."""
    fig = new_figure(figsize=(6.0, 1.6), layout="constrained")
    ax = fig.add_subplot()
    ax.axis("off")
    ax.text(0.5, 0.5, message, ha="center", va="center", fontsize=10, wrap=True)
    return fig


def write_no_runs(
    message: str, tables: Sequence[str | Path], figures: Sequence[str | Path | None]
) -> None:
    """The outputs of an analysis for a dataset without runs of its kind: tables with the
    tag columns and no row, and figures that say ``message`` (a None path: not drawn, see
    :func:`spa.plots.save.draw`)."""
    from spa.io import write_csv
    from spa.plots.save import draw

    empty = pd.DataFrame(columns=["run", "modulator", "setting", "gain"])
    for path in tables:
        write_csv(empty, path)
    for path in figures:
        draw(path, no_data_figure, message)


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
    fig = new_figure(figsize=(10.0, 2.4 * len(kinds)), layout="constrained")
    axes = fig.subplots(len(kinds), 1, sharex=True, squeeze=False)[:, 0]
    for ax, kind in zip(axes, kinds, strict=True):
        groups = list(_groups(traces[traces["modulator"] == kind]))
        for (setting, g), colour in zip(groups, setting_colours(len(groups)), strict=True):
            plot_reduced(ax, g["t"], g["p"], lw=0.8, color=colour, label=setting)
        ax.set_title(_LABELS[kind], fontsize=9, loc="left")
        ax.set_ylabel("P (bar)")
        ax.grid(True, lw=0.3, alpha=0.5)
        ax.legend(fontsize=8, loc="upper left", ncol=2)
    axes[-1].set_xlabel("time t (s)")
    return fig


def _sweep_panel(
    ax,
    table: pd.DataFrame,
    value: str,
    *,
    shown: Sequence[str] = (),
    error: tuple[str, str] | str | None = None,
    paper: str | None = None,
    reference: float | None = None,
    ylabel: str = "",
    other: tuple[str, str, float | None] | None = None,
    outline: str = "",
) -> None:
    """One bar per setting of ``table`` (in its order), coloured by modulator.

    ``shown`` settings are outlined (``outline``: the legend entry saying what that means);
    ``error`` is a column of symmetric errors or a pair of
    columns (low, high); ``paper`` a column of the paper's values (black diamonds);
    ``reference`` a level drawn as a dashed line (the linear reference); ``other`` a second
    measure of every setting, ``(column, label, reference)``: hollow circles, and its
    reference as a dotted line.
    """
    from matplotlib.colors import to_rgba

    table = _sorted(table)
    x = np.arange(len(table))
    y = table[value].to_numpy(dtype=float)
    # alpha in the colours, not as an argument: it would turn the edge colour "none" black
    colours = [to_rgba(_COLOURS.get(k, "0.5"), 0.85) for k in table["modulator"]]
    outlined = set(shown)
    edges = [to_rgba("k" if s in outlined else "none") for s in table["setting"]]
    ax.bar(x, y, color=colours, edgecolor=edges, linewidth=1.2)
    if isinstance(error, str) and error in table.columns:
        ax.errorbar(x, y, yerr=table[error].to_numpy(dtype=float), fmt="none", ecolor="k", lw=0.8)
    elif isinstance(error, tuple) and all(c in table.columns for c in error):
        lo, hi = (table[c].to_numpy(dtype=float) for c in error)
        ax.errorbar(x, y, yerr=[y - lo, hi - y], fmt="none", ecolor="k", lw=0.8)
    if paper is not None and paper in table.columns and table[paper].notna().any():
        ax.plot(x, table[paper].to_numpy(dtype=float), "kD", ms=4, label="paper (bench)")
    if reference is not None and np.isfinite(reference):
        ax.axhline(
            reference, color="0.3", ls="--", lw=1.0, label=f"linear reference {reference:.3g}"
        )
    if other is not None and other[0] in table.columns and table[other[0]].notna().any():
        column, label, level = other
        y2 = table[column].to_numpy(dtype=float)
        ax.plot(x, y2, "o", mfc="white", mec="k", ms=4, label=label)
        if level is not None and np.isfinite(level):
            ax.axhline(level, color="0.3", ls=":", lw=1.0, label=f"{label}: linear {level:.3g}")
        top = np.nanmax(np.r_[y, y2, 0.0])
        if top > 0:  # room for a two-row legend above the tallest bar
            ax.set_ylim(top=1.45 * top)
    ax.set_xticks(x, table["setting"], rotation=60, ha="right", fontsize=8)
    ax.set_ylabel(ylabel)
    ax.grid(True, axis="y", lw=0.3, alpha=0.5)
    handles, labels = ax.get_legend_handles_labels()
    if outline and outlined & set(table["setting"]):
        from matplotlib.patches import Patch

        handles.append(Patch(fc="none", ec="k", lw=1.2))
        labels.append(outline)
    if handles:
        ax.legend(
            handles, labels, fontsize=8, loc="upper left",
            **({"ncols": 2} if other is not None else {}),
        )  # fmt: skip


def fig7a(
    levels: pd.DataFrame, k2: float, sweep: pd.DataFrame | None = None, note: str = ""
) -> Figure:
    """Fig. 7a: equilibrium pressure against input fraction, with the ideal line ``k2*xi``.

    Parameters
    ----------
    levels : pandas.DataFrame
        The levels of the settings shown: columns ``modulator``, ``setting``, ``gain``
        (IPFM/IIPFM gain: other than 1 is drawn with squares), ``xi``, ``p_eq`` (bar) and
        ``fit`` (% of the setting's line fit, shown in the legend).
    k2 : float
        Supply (saturation) pressure in bar, the slope of the ideal line.
    sweep : pandas.DataFrame, optional
        Table 3 of every setting (``modulator``, ``setting``, ``fit``, optionally
        ``paper_fit``): drawn as a second panel, FIT per setting.
    note : str, optional
        Added to the title (e.g. which settings stand in for missing paper settings).
    """
    _require(levels, ["modulator", "setting", "gain", "xi", "p_eq", "fit"], "levels")
    fig = new_figure(figsize=(6.0 if sweep is None else 11.0, 4.8), layout="constrained")
    axes = fig.subplots(1, 1 if sweep is None else 2, squeeze=False)[0]
    ax = axes[0]
    ax.plot([0.0, 1.0], [0.0, k2], "k--", lw=1.0, label=f"ideal: k2·ξ (k2 = {k2:.3f} bar)")
    for setting, g in _groups(levels):
        ax.plot(
            g["xi"], g["p_eq"], **_style(g), lw=1.2,
            label=f"{setting} (FIT {g['fit'].iloc[0]:.1f} %)",
        )  # fmt: skip
    ax.set_xlabel("input fraction ξ")
    ax.set_ylabel("equilibrium pressure (bar)")
    ax.set_xlim(0.0, 1.0)
    ax.grid(True, lw=0.3, alpha=0.5)
    ax.legend(fontsize=8, loc="upper left")
    ax.set_title(_title("Static linearity", note), fontsize=9)
    if sweep is not None:
        _require(sweep, ["modulator", "setting", "fit"], "sweep")
        _sweep_panel(
            axes[1], sweep, "fit", shown=levels["setting"].unique(), paper="paper_fit",
            ylabel="FIT of the line through the levels (%)",
        )  # fmt: skip
        axes[1].set_title("Every setting (outlined: shown on the left)", fontsize=9)
    return fig


def _title(text: str, note: str, width: int = 60) -> str:
    """A panel's title and its note, each wrapped to ``width`` characters."""
    return "\n".join(textwrap.fill(part, width) for part in (text, note) if part)


def _style(g: pd.DataFrame) -> dict:
    """A setting's line: its modulator's colour; a gain other than 1 dashed, with squares."""
    gained = bool(g["gain"].iloc[0] != 1.0)
    colour = _COLOURS.get(g["modulator"].iloc[0], "0.5")
    return {
        "color": colour,
        "marker": "s" if gained else "o",
        "ms": 4,
        "ls": "--" if gained else "-",
    }


def tau_outliers(tau: pd.Series | np.ndarray, factor: float = DECADE) -> np.ndarray:
    """Outlying step time constants: more than ``factor`` times below or above the median of
    all the steps of a dataset (a robust rule: the median, unlike the mean or the sd, does
    not move with the outliers themselves).

    A time constant a decade below the others is not the plant's response but a crossing of
    the 63.2 % level by a single pulse or by the chattering of a long-period modulator on a
    step of a few mbar (full config: 13 ms for IPFM 50 ms and 14 ms for PWM 5 Hz, both
    0.1 -> 0.2 with steps of 11 and 15 mbar, against a median of 0.75 s).

    Parameters
    ----------
    tau : array_like
        Time constants in s (NaN: no time constant, never an outlier).
    factor : float, optional
        How many times off the median (default :data:`DECADE`).

    Returns
    -------
    numpy.ndarray of bool

    Examples
    --------
    >>> tau_outliers([0.5, 0.6, 0.7, 0.8, 0.9, 0.013, np.nan]).tolist()
    [False, False, False, False, False, True, False]
    """
    if not factor > 1.0:
        raise ValueError(f"factor must be > 1, got {factor}")
    t = np.asarray(tau, dtype=float)
    ok = np.isfinite(t) & (t > 0)
    out = np.zeros(t.shape, dtype=bool)
    if not ok.any():
        return out
    median = float(np.median(t[ok]))
    out[ok] = (t[ok] < median / factor) | (t[ok] > median * factor)
    return out


def fig7b(steps: pd.DataFrame, sweep: pd.DataFrame | None = None, note: str = "") -> Figure:
    """Fig. 7b: time constant of each staircase step against the level stepped to.

    Parameters
    ----------
    steps : pandas.DataFrame
        The steps of the settings shown: columns ``modulator``, ``setting``, ``gain`` (as in
        `fig7a`), ``xi_to`` and ``tau`` (s, NaN skipped); optionally ``outlier``
        (:func:`tau_outliers`), drawn as black crosses and named in the legend. The legend's
        mean ± sd are over every step, as Table 3's.
    sweep : pandas.DataFrame, optional
        Table 3 of every setting (``modulator``, ``setting``, ``tau_mean``, ``tau_sd``):
        drawn as a second panel, mean ± sd per setting; optionally ``n_outliers``, the
        setting's outlying steps, written as "×n" above its bar.
    note : str, optional
        Added to the title.
    """
    _require(steps, ["modulator", "setting", "gain", "xi_to", "tau"], "steps")
    fig = new_figure(figsize=(6.0 if sweep is None else 11.0, 4.8), layout="constrained")
    axes = fig.subplots(1, 1 if sweep is None else 2, squeeze=False)[0]
    ax = axes[0]
    for setting, g in _groups(steps):
        g = g[np.isfinite(g["tau"])]
        if g.empty:
            continue
        label = f"{setting}: {g['tau'].mean():.3f} ± {g['tau'].std():.3f} s"
        ax.plot(g["xi_to"], g["tau"], **_style(g), label=label)
    if "outlier" in steps.columns and steps["outlier"].astype(bool).any():
        far = steps[steps["outlier"].astype(bool)]
        ax.plot(
            far["xi_to"], far["tau"], "x", color="k", ms=9, mew=2,
            label=f"outlier: over {DECADE:g}× off the dataset's median τ",
        )  # fmt: skip
    paper = ", ".join(
        f"{_LABELS[k]} {m:.3f} ± {s:.3f} s" for k, (m, s) in PAPER_TIME_CONSTANTS.items()
    )
    ax.set_xlabel("input fraction after the step ξ")
    ax.set_ylabel("time constant (s), 63.2 % of the step")
    ax.grid(True, lw=0.3, alpha=0.5)
    legend_beside(ax, fontsize=8, title="mean ± sd", title_fontsize=8)
    ax.set_title(_title(f"Step time constants (paper, bench: {paper})", note), fontsize=9)
    if sweep is not None:
        _require(sweep, ["modulator", "setting", "tau_mean", "tau_sd"], "sweep")
        _sweep_panel(
            axes[1], sweep, "tau_mean", shown=steps["setting"].unique(), error="tau_sd",
            ylabel="time constant, mean ± sd over the steps (s)",
        )  # fmt: skip
        axes[1].set_title("Every setting (outlined: shown on the left)", fontsize=9)
        if "n_outliers" in sweep.columns:
            table = _sorted(sweep)
            top = (table["tau_mean"] + table["tau_sd"].fillna(0.0)).to_numpy(dtype=float)
            for x, (n, y) in enumerate(zip(table["n_outliers"], top, strict=True)):
                if n > 0:
                    axes[1].annotate(
                        f"×{int(n)}", (x, y), xytext=(0, 2), textcoords="offset points",
                        ha="center", va="bottom", fontsize=8,
                    )  # fmt: skip
            axes[1].set_title(
                "Every setting (outlined: shown on the left;\n×n: n outliers in the mean)",
                fontsize=9,
            )
    return fig


def fig8(aligned: pd.DataFrame, reference: pd.DataFrame | None = None, note: str = "") -> Figure:
    """Fig. 8: normalised pressure against input fraction after lag compensation.

    Parameters
    ----------
    aligned : pandas.DataFrame
        Columns ``modulator``, ``setting``, ``xi`` and ``p_norm``, and ``rms`` (the setting's
        RMS deviation from the line, shown in the legend).
    reference : pandas.DataFrame, optional
        The linear reference's ``xi``, ``p_norm`` and ``rms``, drawn in grey on every panel.
    note : str, optional
        The figure's title (e.g. the sine frequency against the plant's corner frequency).
    """
    _require(aligned, ["modulator", "setting", "xi", "p_norm", "rms"], "aligned")
    kinds = _kinds(aligned)
    if not kinds:
        raise ValueError("aligned: no known modulator")
    if reference is not None:
        _require(reference, ["xi", "p_norm", "rms"], "reference")
    ncols = min(len(kinds), 2)
    nrows = -(-len(kinds) // ncols)
    fig = new_figure(figsize=(5.8 * ncols, 3.9 * nrows + 0.5), layout="constrained")
    grid = fig.subplots(nrows, ncols, sharex=True, sharey=True, squeeze=False).ravel()
    for ax in grid[len(kinds) :]:
        fig.delaxes(ax)
    axes = grid[: len(kinds)]
    for ax, kind in zip(axes, kinds, strict=True):
        ax.plot([0, 1], [0, 1], "k--", lw=1.0, label="ideal: P/max(P) = ξ")
        if reference is not None:
            rms = float(reference["rms"].iloc[0])
            ax.plot(
                reference["xi"], reference["p_norm"], color="0.6", lw=1.0,
                label=f"{REFERENCE} first-order plant (RMS {rms:.3f})",
            )  # fmt: skip
        groups = list(_groups(aligned[aligned["modulator"] == kind]))
        for (setting, g), colour in zip(groups, setting_colours(len(groups)), strict=True):
            ax.plot(
                g["xi"], g["p_norm"], lw=0.9, color=colour,
                label=f"{setting} (RMS {g['rms'].iloc[0]:.3f})",
            )  # fmt: skip
        ax.set_title(_LABELS[kind], fontsize=10)
        ax.set_xlim(0.0, 1.0)
        ax.set_ylim(0.0, 1.05)
        ax.grid(True, lw=0.3, alpha=0.5)
        handles, labels = ax.get_legend_handles_labels()
        n_common = 2 if reference is not None else 1
        legend_beside(
            ax, handles[n_common:], labels[n_common:], fontsize=8,
            title="setting (RMS deviation)", title_fontsize=8,
        )  # fmt: skip
    for i, ax in enumerate(axes):
        ax.set_xlabel("input fraction ξ")
        ax.set_ylabel("P / max(P)")
        ax.label_outer()
        if i + ncols >= len(axes):  # no panel below: this one reads the ξ axis
            ax.xaxis.set_tick_params(labelbottom=True)
            ax.set_xlabel("input fraction ξ")
    handles, labels = axes[0].get_legend_handles_labels()
    fig.legend(
        handles[:n_common], labels[:n_common], loc="outside lower center", ncol=2, fontsize=8
    )
    if note:
        fig.suptitle(textwrap.fill(note, int(15 * 5.8 * ncols)), fontsize=9)
    return fig


def fig9_data(maps: Sequence[tuple[str, np.ndarray, np.ndarray, float, float]]) -> pd.DataFrame:
    """Tidy data of Fig. 9's maps: every bin of each principal domain.

    Parameters
    ----------
    maps : sequence of (name, f, bic, threshold, fmin)
        As :func:`fig9`'s ``maps``, with the setting's name first.

    Returns
    -------
    pandas.DataFrame
        ``setting``, ``f1``, ``f2`` (Hz), ``bicoherence``, ``significant`` (coloured in the
        figure: above the threshold and ``f2 >= fmin``).
    """
    parts = []
    for name, f, bic, threshold, fmin in maps:
        i, j = np.nonzero(principal_domain_mask(f))
        shown = principal_domain_mask(f, fmin)
        if np.isfinite(threshold):
            shown &= bic > threshold
        parts.append(
            pd.DataFrame(
                {
                    "setting": name,
                    "f1": f[i],
                    "f2": f[j],
                    "bicoherence": bic[i, j],
                    "significant": shown[i, j],
                }
            )
        )
    return pd.concat(parts, ignore_index=True)


def fig9(
    maps: Sequence[tuple[str, np.ndarray, np.ndarray, float, float]],
    sweep: pd.DataFrame | None = None,
    shown: Sequence[str] = (),
    note: str = "",
) -> Figure:
    """Fig. 9: bicoherence over the principal domain, one panel per map, on a fixed [0, 1] scale.

    Parameters
    ----------
    maps : sequence of (title, f, bic, threshold, fmin)
        Frequency axis (Hz), map (`spa.openloop.spectra.bicoherence`), significance
        threshold and the lowest ``f2`` summarised (Hz): bins at or below the threshold, and
        the rows below ``fmin``, are masked (drawn light grey). A NaN threshold masks nothing
        (HOSA's normalisation has none).
    sweep : pandas.DataFrame, optional
        The bicoherence table of every setting (``modulator``, ``setting``,
        ``significant_fraction``, optionally ``significant_fraction_min``/``_max`` over noise
        seeds and ``significant_fraction_no_ringing``), with the linear reference's row
        (``modulator == "linear"``): drawn below the maps, the significant fraction per
        setting (bars) and without the sensor's ringing (hollow circles).
    shown : sequence of str, optional
        The settings whose maps are shown (outlined in the sweep panel).
    note : str, optional
        The figure's title.
    """
    if not maps:
        raise ValueError("maps: nothing to plot")
    n = len(maps)
    ncols = min(n, 3)  # a page wide: at most three maps a row
    nrows = -(-n // ncols)
    heights = [1.0] * nrows + ([1.4] if sweep is not None else [])
    fig = new_figure(figsize=(8.0, 2.3 * sum(heights) + 0.4), layout="constrained")
    grid = fig.add_gridspec(len(heights), ncols, height_ratios=heights)
    image = None
    axes = [fig.add_subplot(grid[i // ncols, i % ncols]) for i in range(n)]
    for ax, (title, f, bic, threshold, fmin) in zip(axes, maps, strict=True):
        domain = principal_domain_mask(f)
        visible = principal_domain_mask(f, fmin)
        if np.isfinite(threshold):
            visible &= bic > threshold
        pos = f >= 0
        fp = f[pos]
        step = fp[1] - fp[0] if fp.size > 1 else 1.0
        edges = np.concatenate((fp - step / 2, [fp[-1] + step / 2]))
        grey = np.where(domain, 1.0, np.nan)[np.ix_(pos, pos)]  # rows f1, columns f2
        ax.pcolormesh(
            edges, edges, grey.T, vmin=0.0, vmax=1.0, cmap="Greys", alpha=0.15, rasterized=True
        )
        z = np.where(visible, bic, np.nan)[np.ix_(pos, pos)]
        image = ax.pcolormesh(
            edges, edges, z.T, vmin=0.0, vmax=1.0, cmap="viridis", rasterized=True
        )
        ax.set_xlim(0.0, fp[-1])
        ax.set_ylim(0.0, fp[-1] / 2)
        ax.set_xlabel("f1 (Hz)")
        ax.set_ylabel("f2 (Hz)")
        ax.set_title(title, fontsize=9)
    fig.colorbar(image, ax=axes, label="bicoherence (significant bins)", shrink=0.9)
    if sweep is not None:
        _require(sweep, ["modulator", "setting", "significant_fraction"], "sweep")
        runs = sweep[sweep["modulator"] != REFERENCE]
        ref_rows = sweep[sweep["modulator"] == REFERENCE]
        ref = ref_rows["significant_fraction"]
        quiet = "significant_fraction_no_ringing"
        quiet_ref = ref_rows[quiet] if quiet in ref_rows.columns else ref.iloc[:0]
        _sweep_panel(
            fig.add_subplot(grid[nrows, :]), runs, "significant_fraction",
            shown=shown,
            error=("significant_fraction_min", "significant_fraction_max"),
            reference=float(ref.iloc[0]) if ref.size else None,
            ylabel="fraction of the domain significant",
            outline="outlined: its map is shown above",
            other=(quiet, "without the sensor's ringing",
                   float(quiet_ref.iloc[0]) if quiet_ref.size else None),
        )  # fmt: skip
    if note:
        fig.suptitle(textwrap.fill(note, 120), fontsize=9)
    return fig
