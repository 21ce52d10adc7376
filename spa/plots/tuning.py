"""Figures of the tuning stage (a dataset's own Figs. 4 and 5), drawn from tidy tables.

They are the analytic stage's figures (:mod:`spa.plots.analytic`) with what the exact
periodic steady state adds: Fig. 4 draws ``J_exact`` dashed beside each ``J`` curve, Fig. 5
the exact cycle mean dotted beside each ``P_eq`` curve. Like the analytic figures, each
function takes the table written as CSV beside the PNG and returns a matplotlib Figure.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
import pandas as pd

from spa._docs import fill_doc
from spa.model.params import ValveParams
from spa.plots.analytic import (
    _COLOURS,
    _panel_order,
    _require,
    cost_legend,
    plot_cost_sweeps,
    plot_equilibrium,
)

if TYPE_CHECKING:
    from matplotlib.figure import Figure

__all__ = ["plot_tuning_equilibrium", "plot_tuning_sweeps"]


@fill_doc
def plot_tuning_sweeps(
    sweeps: pd.DataFrame, title: str | None = None, params: ValveParams | None = None
) -> Figure:
    """Fig. 4 for one valve: ``J`` (solid, Eq. 25) and ``J_exact`` (dashed) per modulator.

    Parameters
    ----------
    sweeps : pandas.DataFrame
        :func:`spa.tuning.sweep_frame` with ``exact=True``: columns ``modulator``, ``x_ms``,
        ``J`` and ``J_exact`` (NaN points are left out).
    title : str, optional
        Figure title (e.g. the dataset's name).
    params : ValveParams, optional
        The valve: marks PWM's periods below ``t_on + t_off``
        (:func:`spa.plots.analytic.plot_cost_sweeps`).

    %(table_figure)s

    Notes
    -----
    The axes are those of :func:`spa.plots.analytic.plot_cost_sweeps`. Where the dashed curve
    leaves the solid one, the averaged model of Eq. 5 no longer describes the orbit's mean:
    at long periods the pressure swings between near 0 and near ``k2`` and its mean becomes
    almost linear in the duty while the chattering grows.
    """
    _require(sweeps, ["modulator", "x_ms", "J", "J_exact"], "sweeps")
    from matplotlib.lines import Line2D

    fig = plot_cost_sweeps(sweeps, params=params)
    ax = fig.axes[0]
    for kind in _panel_order():
        d = sweeps[(sweeps["modulator"] == kind) & np.isfinite(sweeps["J_exact"])]
        if not d.empty:
            d = d.sort_values("x_ms")
            ax.plot(d["x_ms"], d["J_exact"], color=_COLOURS[kind], lw=1.0, ls="--")
    handles, labels = ax.get_legend_handles_labels()
    handles.append(Line2D([], [], color="k", lw=1.0, ls="--"))
    labels.append("dashed: J_exact (exact periodic steady state)")
    cost_legend(fig, handles, labels)
    ax.set_title(
        (f"{title}: " if title else "") + "linearity cost J (Eq. 25, solid) and J_exact (dashed)",
        fontsize=10,
    )
    return fig


def plot_tuning_equilibrium(curves: pd.DataFrame) -> Figure:
    """Fig. 5 for one valve: ``P_eq`` and ``tau_m`` at the optima, with the exact mean.

    Parameters
    ----------
    curves : pandas.DataFrame
        :func:`spa.tuning.equilibrium_frame` with ``exact=True`` (column ``p_exact``).

    Returns
    -------
    matplotlib.figure.Figure
        :func:`spa.plots.analytic.plot_equilibrium`, with the exact cycle mean of the
        periodic steady state dotted on each top panel.

    Raises
    ------
    ValueError
        If a column is missing.
    """
    _require(curves, ["modulator", "xi", "p_exact"], "curves")
    fig = plot_equilibrium(curves)
    kinds = [k for k in _panel_order() if (curves["modulator"] == k).any()]
    tops = fig.axes[: len(kinds)]
    for ax, kind in zip(tops, kinds, strict=True):
        d = curves[curves["modulator"] == kind].sort_values("xi")
        ax.plot(d["xi"], d["p_exact"], color="k", lw=1.0, ls=":", label="exact cycle mean")
    tops[0].legend(fontsize=8, loc="upper left")
    return fig
