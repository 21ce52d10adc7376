"""Figures of the analytic stage (paper Figs. 4 and 5), drawn from tidy tables.

Each function takes the exact table that is written as CSV beside the PNG and returns a
matplotlib Figure built without pyplot (no global state, no backend switch; PNG output goes
through Agg). Save it with
:func:`spa.plots.save.save_figure`.
"""

from __future__ import annotations

from string import ascii_lowercase
from typing import TYPE_CHECKING

import numpy as np
import pandas as pd

from spa._docs import fill_doc
from spa.model.modulators import MODULATOR_ORDER, get_kind
from spa.model.params import ValveParams
from spa.openloop.paper import PAPER_FIG5_ORDER
from spa.plots.style import MODULATOR_COLOURS, MODULATOR_NAMES, new_figure

if TYPE_CHECKING:
    from matplotlib.figure import Figure

__all__ = [
    "TAU_SPREAD",
    "cost_legend",
    "plot_cost_sweeps",
    "plot_equilibrium",
    "sweep_optimum",
    "tau_log_scale",
]

TAU_SPREAD = 10.0
"""Ratio of the modulators' largest ``tau_m`` above which Fig. 5's ``tau_m`` row is drawn on
a logarithmic axis (:func:`tau_log_scale`)."""

#: Display names, in the paper's panel order of Fig. 5, and colours (:mod:`spa.plots.style`).
_LABELS = MODULATOR_NAMES
_COLOURS = MODULATOR_COLOURS


def _panel_order() -> list[str]:
    """Fig. 5's panels: the paper's order, then any further kind in table order."""
    return [*PAPER_FIG5_ORDER, *(k for k in MODULATOR_ORDER if k not in PAPER_FIG5_ORDER)]


_MS_TICKS = [12.5, 20, 30, 50, 100, 200, 500, 1000]
_HZ_TICKS = [1, 2, 5, 10, 20, 50, 80]


def _require(df: pd.DataFrame, columns: list[str], what: str) -> None:
    missing = [c for c in columns if c not in df.columns]
    if missing:
        raise ValueError(f"{what}: missing column(s) {missing}; got {list(df.columns)}")


def sweep_optimum(sweep: pd.DataFrame) -> pd.Series:
    """The row of one modulator's sweep that its Table 2 names as the optimum.

    With ``J_exact`` (a dataset's tuning), the tuning's rule: the smallest ``J``, ties within
    :data:`spa.tuning.exact.COST_TIE` broken by ``J_exact``
    (:func:`spa.tuning.exact.best_first`); without it (the analytic Table 2,
    :func:`spa.tuning.cost.optimum`), the first grid value, in the sweep's own order, where
    ``J`` is smallest. So the legend of Fig. 4 names the optimum of Table 2, also where
    ``J`` is flat to round-off (LPWM, whose ``J`` is 0 up to 1e-14 bar everywhere).

    Parameters
    ----------
    sweep : pandas.DataFrame
        Rows of one modulator of :func:`spa.tuning.sweep_frame`, in grid order; ``J``, and
        ``J_exact`` when the tuning computed it.

    Returns
    -------
    pandas.Series
        The optimum's row.

    Examples
    --------
    >>> f = pd.DataFrame({"x_ms": [10.0, 20.0], "J": [2e-15, 1e-15], "J_exact": [0.07, 0.6]})
    >>> float(sweep_optimum(f)["x_ms"]), float(sweep_optimum(f.drop(columns="J_exact"))["x_ms"])
    (10.0, 20.0)
    """
    if "J_exact" in sweep.columns:
        from spa.tuning.exact import best_first

        return best_first(sweep, "J").iloc[0]
    j = sweep["J"].to_numpy(dtype=float)
    return sweep.iloc[int(np.nanargmin(j))]


@fill_doc
def plot_cost_sweeps(sweeps: pd.DataFrame, params: ValveParams | None = None) -> Figure:
    """Fig. 4: the linearity cost ``J`` of every modulator kind on one axis.

    Parameters
    ----------
    sweeps : pandas.DataFrame
        Tidy sweep table (:func:`spa.tuning.sweep_frame`) with columns ``modulator``,
        ``x_ms`` and ``J`` (NaN points are left out).
    params : ValveParams, optional
        The valve: PWM periods below ``t_on + t_off`` are shaded and marked (see Notes).

    %(table_figure)s

    Notes
    -----
    As in the paper, the common x axis is a time in ms: the PWM period ``T_W = 1/f_W``, the
    IPFM pulse width ``t_h``, the IIPFM pulse separation ``t_l`` and the ΔΣM period. The axis
    is logarithmic (the grids span 12.5–1000 ms and all minima lie near 20–50 ms); a
    secondary top axis reads the PWM frequency ``f_W = 1000/T_W`` in Hz. Each curve's minimum
    is marked and given in the legend.

    PWM's linear range ``t_on/T_W < ξ < 1 - t_off/T_W`` closes at ``T_W = t_on + t_off``
    (13 ms, 76.9 Hz, for the nominal valve): at shorter periods no pulse both opens and
    closes the valve, the averaged (and the exact) equilibrium is a step from 0 to ``k2`` at
    ``ξ = t_on/T_W``, and ``J`` on its grid of ``N`` input fractions moves in plateaus and
    jumps as that step passes the grid's points. With ``params`` that range is shaded.
    """
    _require(sweeps, ["modulator", "x_ms", "J"], "sweeps")
    fig = new_figure(figsize=(8.0, 5.2), layout="constrained")
    ax = fig.add_subplot()
    for kind in MODULATOR_ORDER:  # legend in the order of every table
        label = _LABELS[kind]
        d = sweeps[(sweeps["modulator"] == kind) & np.isfinite(sweeps["J"])]
        if d.empty:
            continue
        best = sweep_optimum(d)
        d = d.sort_values("x_ms")
        spec = get_kind(kind)
        label = f"{label} ({spec.axis_name}): min {best['J']:.2f} at {best['x_ms']:.4g} ms"
        if spec.unit == "Hz":
            label += f" ({1e3 / best['x_ms']:.4g} Hz)"
        ax.plot(d["x_ms"], d["J"], color=_COLOURS[kind], lw=1.5, label=label)
        ax.plot(best["x_ms"], best["J"], "o", color=_COLOURS[kind], ms=5)
    if params is not None and params.on_loss + params.off_loss > 0.0:
        limit = 1e3 * (params.on_loss + params.off_loss)
        lo = float(sweeps.loc[sweeps["modulator"] == MODULATOR_ORDER[0], "x_ms"].min())
        if lo < limit:
            ax.axvspan(
                lo, limit, color="0.85", lw=0, zorder=0,
                label=f"PWM T_W < t_on + t_off = {limit:.3g} ms ({1e3 / limit:.3g} Hz): "
                "no linear range,\nP_eq is a 0 → k2 step; J steps as it crosses the ξ grid",
            )  # fmt: skip
    from matplotlib.ticker import FixedLocator, FormatStrFormatter, NullFormatter

    ax.set_xscale("log")
    ax.xaxis.set_major_locator(FixedLocator(_MS_TICKS))
    ax.xaxis.set_major_formatter(FormatStrFormatter("%g"))
    ax.xaxis.set_minor_formatter(NullFormatter())
    ax.set_xlabel("modulator parameter: T_W, t_h, t_l, T_ΔΣ (ms)")
    ax.set_ylabel("linearity cost J (bar)")
    ax.grid(True, which="both", lw=0.3, alpha=0.5)
    cost_legend(fig, *ax.get_legend_handles_labels())
    top = ax.secondary_xaxis("top", functions=(_inverse_ms, _inverse_ms))
    top.xaxis.set_major_locator(FixedLocator(_HZ_TICKS))
    top.xaxis.set_major_formatter(FormatStrFormatter("%g"))
    top.xaxis.set_minor_formatter(NullFormatter())
    top.set_xlabel("PWM frequency f_W (Hz)")
    ax.set_title("Linearity cost versus modulator parameter (Eq. 25)", fontsize=10)
    return fig


def cost_legend(fig: Figure, handles: list, labels: list[str]) -> None:
    """Fig. 4's legend, below the axes (replacing any): it never covers a curve."""
    for legend in list(fig.legends):
        legend.remove()
    fig.legend(handles, labels, loc="outside lower center", ncols=2, fontsize=8)


def _inverse_ms(x: np.ndarray) -> np.ndarray:
    """``1000/x`` (ms <-> Hz), safe at 0."""
    x = np.asarray(x, dtype=np.float64)
    out = np.full(x.shape, np.inf)
    np.divide(1e3, x, out=out, where=x != 0)
    return out


def tau_log_scale(curves: pd.DataFrame, spread: float = TAU_SPREAD) -> bool:
    """Whether Fig. 5's shared ``tau_m`` axis should be logarithmic.

    True when the largest finite ``tau_m`` of one modulator is ``spread`` times (or more)
    that of another: on a linear axis the smaller would be a flat line at 0 (one modulator
    near saturation reaches minutes, the others stay below seconds).

    Examples
    --------
    >>> f = pd.DataFrame({"modulator": ["pwm", "pwm", "lpwm"], "tau_m": [0.5, 2.0, 600.0]})
    >>> tau_log_scale(f), tau_log_scale(f[f["modulator"].isin(["pwm"])])
    (True, False)
    """
    tau = pd.to_numeric(curves["tau_m"], errors="coerce")
    ok = np.isfinite(tau) & (tau > 0)
    peaks = tau[ok].groupby(curves.loc[ok, "modulator"]).max()
    return bool(len(peaks) > 1 and peaks.max() >= spread * peaks.min())


def plot_equilibrium(curves: pd.DataFrame) -> Figure:
    """Fig. 5: equilibrium pressure and time constant against the input fraction.

    Parameters
    ----------
    curves : pandas.DataFrame
        Tidy table (:func:`spa.tuning.equilibrium_frame`) with columns ``modulator``,
        ``parameter``, ``value``, ``gain``, ``xi``, ``p_eq``, ``p_target``, ``tau_m``.

    Returns
    -------
    matplotlib.figure.Figure
        Two rows by one column per modulator, in the paper's order (PWM, IPFM, ΔΣM, IIPFM):
        top, ``P_eq`` (Eq. 5) with the linear target ``k2*xi`` dashed; bottom, ``tau_m``
        (Eq. 9; gaps where it is undefined: dead-zone and past saturation), on a shared
        axis, logarithmic when the modulators' largest ``tau_m`` lie an order of magnitude
        or more apart (:func:`tau_log_scale`).

    Raises
    ------
    ValueError
        If a column is missing or there is no modulator to plot.
    """
    _require(
        curves,
        ["modulator", "parameter", "value", "gain", "xi", "p_eq", "p_target", "tau_m"],
        "curves",
    )
    kinds = [k for k in _panel_order() if (curves["modulator"] == k).any()]
    if not kinds:
        raise ValueError(f"curves: no known modulator in {sorted(set(curves['modulator']))}")
    fig = new_figure(figsize=(3.0 * len(kinds), 5.2), layout="constrained")
    axes = fig.subplots(2, len(kinds), sharex=True, sharey="row", squeeze=False)
    for col, kind in enumerate(kinds):
        d = curves[curves["modulator"] == kind].sort_values("xi")
        first = d.iloc[0]
        value = float(first["value"])
        if first["parameter"] == "f_w":
            setting = f"f_W = {value:g} Hz"
        else:
            setting = f"{get_kind(kind).axis_name} = {value * 1e3:g} ms"
        if np.isfinite(first["gain"]) and first["parameter"] == "t_l":
            setting += f", G = {float(first['gain']):.3g}"
        top, bottom = axes[0, col], axes[1, col]
        top.plot(d["xi"], d["p_target"], "k--", lw=1.0, label="k2·ξ (linear)")
        top.plot(d["xi"], d["p_eq"], color=_COLOURS[kind], lw=1.6, label="P_eq (Eq. 5)")
        top.set_title(f"({ascii_lowercase[col]}) {_LABELS[kind]}: {setting}", fontsize=9)
        bottom.plot(d["xi"], d["tau_m"], color=_COLOURS[kind], lw=1.6)
        bottom.set_xlabel("input fraction ξ")
        for ax in (top, bottom):
            ax.grid(True, lw=0.3, alpha=0.5)
            ax.set_xlim(0.0, 1.0)
    axes[0, 0].set_ylabel("equilibrium pressure (bar)")
    if tau_log_scale(curves):  # one modulator's tau_m would flatten the others' at 0
        axes[1, 0].set_yscale("log")
        axes[1, 0].set_ylabel("time constant τ_m (s, log scale)")
    else:
        axes[1, 0].set_ylabel("time constant τ_m (s)")
    axes[0, 0].legend(fontsize=8, loc="upper left")
    return fig
