"""Figures of the identification (paper Fig. 2) and of the model validation.

Every figure comes in two steps: ``*_data`` builds a tidy DataFrame (save it as CSV beside
the PNG) and the plotting function draws exactly that table and returns a
:class:`matplotlib.figure.Figure`. The figures are built with the object-oriented API (no
pyplot state, no GUI backend), so they render headless; save them with
:func:`spa.plots.save.save_figure`.
"""

from __future__ import annotations

import textwrap
from collections.abc import Callable, Mapping
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt
import pandas as pd

from spa.identification import ChargeFit, DischargeFit
from spa.plots.reduce import plot_reduced
from spa.plots.style import OKABE_ITO, legend_beside, new_figure
from spa.validation import ValidationResult

if TYPE_CHECKING:
    from matplotlib.figure import Figure

__all__ = [
    "fig2a",
    "fig2a_data",
    "fig2b",
    "fig2b_data",
    "fig2c",
    "fig2c_data",
    "validation_data",
    "validation_figure",
]


#: Measured in vermillion, model and fits in blue (Okabe–Ito, :mod:`spa.plots.style`).
_MEASURED, _MODEL = OKABE_ITO[6], OKABE_ITO[5]


def _check_columns(data: pd.DataFrame, columns: list[str], name: str = "data") -> None:
    if not isinstance(data, pd.DataFrame):
        raise ValueError(f"{name} must be a pandas DataFrame, got {type(data).__name__}")
    missing = [c for c in columns if c not in data.columns]
    if missing:
        raise ValueError(f"{name} lacks column(s) {missing}; it has {list(data.columns)}")


def _rate_data(
    points: pd.DataFrame,
    p_end: float,
    n_line: int,
    curves: Mapping[str, Callable[[npt.NDArray[np.float64]], npt.NDArray[np.float64]]],
) -> pd.DataFrame:
    """Tidy data of a rate figure: a fit's points, then its curves ``dP/dt(P)``.

    Parameters
    ----------
    points : pandas.DataFrame
        ``points`` of a :class:`ChargeFit` or :class:`DischargeFit`.
    p_end : float
        The curves run from 0 to the larger of this and the points' largest pressure, bar.
    n_line : int
        Points of each curve.
    curves : mapping of str to callable
        Series name to ``dP/dt`` (bar/s) as a function of ``P`` (bar).

    Returns
    -------
    pandas.DataFrame
        ``series`` (``"measured"``: points in the fit; ``"excluded"``: points after the edge
        left out by the window; then the curves' names), ``run``, ``p`` (bar), ``dpdt`` (bar/s).
    """
    series = np.where(points["used"].to_numpy(), "measured", "excluded")
    meas = pd.DataFrame(
        {"series": series, "run": points["run"], "p": points["p"], "dpdt": points["dpdt"]}
    )
    p_line = np.linspace(0.0, max(float(points["p"].max()), p_end), n_line)
    lines = [
        pd.DataFrame({"series": name, "run": "", "p": p_line, "dpdt": dpdt(p_line)})
        for name, dpdt in curves.items()
    ]
    return pd.concat([meas, *lines], ignore_index=True)


def _rate_figure(data: pd.DataFrame, lines: dict[str, dict[str, Any]], title: str) -> Figure:
    """dP/dt against P: excluded and measured points, then the named fitted lines."""
    _check_columns(data, ["series", "p", "dpdt"])
    fig = new_figure(figsize=(5.0, 3.6), layout="constrained")
    ax = fig.add_subplot()
    for name, style in (
        ("excluded", {"color": "0.75", "s": 2}),
        ("measured", {"color": "k", "s": 2}),
    ):
        d = data[data["series"] == name]
        ax.scatter(d["p"], d["dpdt"], label=name, rasterized=True, **style)
    for name, style in lines.items():
        d = data[data["series"] == name]
        ax.plot(d["p"], d["dpdt"], label=name, **style)
    ax.set_xlabel("P (bar)")
    ax.set_ylabel("dP/dt (bar/s)")
    ax.set_title(title)
    ax.legend(frameon=False)
    return fig


def fig2a_data(fit: ChargeFit, n_line: int = 50) -> pd.DataFrame:
    """Tidy data of Fig. 2a: ``dP/dt`` against ``P`` while charging, and the fitted line.

    Parameters
    ----------
    fit : ChargeFit
        Result of :func:`spa.identification.fit_charge`.
    n_line : int, optional
        Points of the fitted line.

    Returns
    -------
    pandas.DataFrame
        ``series`` (``"measured"``: points in the fit; ``"excluded"``: points after the edge
        left out by the window; ``"fit"``: the line), ``run``, ``p`` (bar), ``dpdt`` (bar/s).
    """
    return _rate_data(
        fit.points, fit.k2.value, n_line, {"fit": lambda p: fit.slope * p + fit.intercept}
    )


def fig2a(data: pd.DataFrame) -> Figure:
    """Fig. 2a: pressure rate against pressure while charging, with the fitted line.

    Parameters
    ----------
    data : pandas.DataFrame
        Output of :func:`fig2a_data`.

    Returns
    -------
    matplotlib.figure.Figure
    """
    return _rate_figure(data, {"fit": {"color": _MEASURED, "lw": 1.5}}, "(a) charging")


def fig2b_data(fit: DischargeFit, n_line: int = 100) -> pd.DataFrame:
    """Tidy data of Fig. 2b: ``dP/dt`` against ``P`` while exhausting, and the power laws.

    Parameters
    ----------
    fit : DischargeFit
        Result of :func:`spa.identification.fit_discharge`.
    n_line : int, optional
        Points of each curve.

    Returns
    -------
    pandas.DataFrame
        ``series`` (``"measured"``, ``"excluded"``, ``"power law"``: ``-a*P**b``,
        ``"b = 0.5"``: ``-sqrt(P)/c1``), ``run``, ``p`` (bar), ``dpdt`` (bar/s).
    """
    curves = {
        "power law": lambda p: -fit.a * p**fit.b,
        "b = 0.5": lambda p: -np.sqrt(p) / fit.c1.value,
    }
    return _rate_data(fit.points, 0.0, n_line, curves)


def fig2b(data: pd.DataFrame) -> Figure:
    """Fig. 2b: pressure rate against pressure while exhausting, with the power law.

    Parameters
    ----------
    data : pandas.DataFrame
        Output of :func:`fig2b_data`.

    Returns
    -------
    matplotlib.figure.Figure
    """
    lines = {
        "power law": {"color": _MEASURED, "lw": 1.5},
        "b = 0.5": {"color": _MODEL, "lw": 1.0, "ls": "--"},
    }
    return _rate_figure(data, lines, "(b) discharging")


def fig2c_data(trace: pd.DataFrame) -> pd.DataFrame:
    """Tidy data of Fig. 2c from a model trace of the pulse run.

    Parameters
    ----------
    trace : pandas.DataFrame
        ``t``, ``p``, ``valve``, ``p_model``: a trace of
        :attr:`spa.identification.DelayFit.traces` or :attr:`ValidationResult.trace`.

    Returns
    -------
    pandas.DataFrame
        ``t`` (s), ``valve`` (0/1), ``p`` (measured, bar), ``p_model`` (bar).
    """
    _check_columns(trace, ["t", "p", "valve", "p_model"], "trace")
    return trace[["t", "valve", "p", "p_model"]].reset_index(drop=True)


def _zoom_edge(data: pd.DataFrame, after: float = 0.03) -> float:
    """The rising edge after which the model pressure rises most within ``after`` s.

    There the hold of ``t_on`` before the rise stands out of the sensor's noise best (the
    paper zooms on one edge at 3 s); without rising edges, the middle of the run.
    """
    t = data["t"].to_numpy()
    v = data["valve"].to_numpy()
    rising = np.flatnonzero((v[1:] == 1) & (v[:-1] == 0)) + 1
    if rising.size == 0:
        return float(t[t.size // 2])
    p = data["p_model"].to_numpy(dtype=float)
    end = np.minimum(np.searchsorted(t, t[rising] + after), t.size - 1)
    return float(t[rising[np.argmax(p[end] - p[rising])]])


def fig2c(
    data: pd.DataFrame,
    zoom_at: float | None = None,
    zoom_span: tuple[float, float] = (-0.01, 0.04),
) -> Figure:
    """Fig. 2c: the pulse run, command and measured vs model pressure, with a zoom on an edge.

    Parameters
    ----------
    data : pandas.DataFrame
        Output of :func:`fig2c_data`.
    zoom_at : float, optional
        Time (s) of the edge to zoom on; by default the rising edge after which the model
        pressure rises most (:func:`_zoom_edge`).
    zoom_span : (float, float), optional
        Zoom window relative to ``zoom_at``, s.

    Returns
    -------
    matplotlib.figure.Figure
        Top: the whole run (command on the right axis). Bottom: the zoom, showing the pressure
        holding for ``t_on`` after the edge.
    """
    _check_columns(data, ["t", "valve", "p", "p_model"])
    if zoom_span[0] >= zoom_span[1]:
        raise ValueError(f"zoom_span must be increasing, got {zoom_span!r}")
    at = _zoom_edge(data, zoom_span[1]) if zoom_at is None else float(zoom_at)
    fig = new_figure(figsize=(7.0, 5.6), layout="constrained")
    ax, az = fig.subplots(2, 1, height_ratios=[3, 2])
    margin = zoom_span[1] - zoom_span[0]  # the zoom draws every sample near its window
    window = data["t"].between(at + zoom_span[0] - margin, at + zoom_span[1] + margin)
    for a, marker, part in ((ax, "", data), (az, ".", data[window])):
        t = part["t"]
        plot_reduced(
            a, t, part["p"], color=_MEASURED, lw=1.0, marker=marker, ms=4, label="measured"
        )
        plot_reduced(a, t, part["p_model"], color=_MODEL, lw=1.5, ls="--", label="model")
        a.set_ylabel("P (bar)")
        a.grid(True, lw=0.3, alpha=0.5)
        cmd = a.twinx()
        plot_reduced(cmd, t, part["valve"], drawstyle="steps-post", color="0.35", lw=0.8)
        cmd.set_ylim(-0.05, 3.0)
        cmd.set_yticks([0, 1])
        cmd.set_ylabel("valve command")
    # above the axes, right of the title (which is on the left): the pulse train fills the
    # panel, and neither covers the other
    ax.legend(frameon=False, loc="lower right", bbox_to_anchor=(1.0, 1.0), ncols=2, borderaxespad=0)
    ax.set_title("(c) pulse response", loc="left")
    ax.axvspan(at + zoom_span[0], at + zoom_span[1], color="0.8")
    ax.set_xlabel("t (s)")
    sel = (data["t"] >= at + zoom_span[0]) & (data["t"] <= at + zoom_span[1])
    if sel.any():
        lo = float(min(data.loc[sel, "p"].min(), data.loc[sel, "p_model"].min()))
        hi = float(max(data.loc[sel, "p"].max(), data.loc[sel, "p_model"].max()))
        pad = 0.1 * (hi - lo) + 1e-3
        az.set_ylim(lo - pad, hi + pad)
    az.set_xlim(at + zoom_span[0], at + zoom_span[1])
    az.axvline(at, color="0.3", lw=1.0, ls=":")
    az.annotate(
        "valve opened", xy=(at, 1.0), xycoords=("data", "axes fraction"), xytext=(3, -12),
        textcoords="offset points", fontsize=8, color="0.3",
    )  # fmt: skip
    az.set_title(f"zoom on the edge at {at:.3f} s (grey band above)", fontsize=9)
    az.set_xlabel("t (s)")
    return fig


def validation_data(result: ValidationResult) -> pd.DataFrame:
    """Tidy data of a validation overlay.

    Parameters
    ----------
    result : ValidationResult
        Output of :func:`spa.validation.validate_run`.

    Returns
    -------
    pandas.DataFrame
        ``t``, ``valve``, ``p``, ``p_model``, ``error`` (``p - p_model``, bar).
    """
    tr = result.trace
    return pd.DataFrame(
        {
            "t": tr["t"],
            "valve": tr["valve"],
            "p": tr["p"],
            "p_model": tr["p_model"],
            "error": tr["p"] - tr["p_model"],
        }
    )


def validation_figure(data: pd.DataFrame, title: str = "") -> Figure:
    """Measured against model pressure for one run, with the error below.

    Parameters
    ----------
    data : pandas.DataFrame
        Output of :func:`validation_data`.
    title : str, optional
        Title, e.g. the run kind and FIT %.

    Returns
    -------
    matplotlib.figure.Figure
    """
    _check_columns(data, ["t", "p", "p_model"])
    fig = new_figure(figsize=(7.0, 4.5), layout="constrained")
    ax, ae = fig.subplots(2, 1, sharex=True, height_ratios=[3, 1])
    err = data["error"] if "error" in data.columns else data["p"] - data["p_model"]
    plot_reduced(ax, data["t"], data["p"], color=_MEASURED, lw=0.8, label="measured")
    plot_reduced(ax, data["t"], data["p_model"], color=_MODEL, lw=1.0, ls="--", label="model")
    ax.set_ylabel("P (bar)")
    legend_beside(ax, frameon=False)
    if title:
        ax.set_title(textwrap.fill(title, 70), fontsize=11)
    plot_reduced(ae, data["t"], err, color="k", lw=0.6)
    ae.axhline(0.0, color="0.5", lw=0.6)
    ae.set_ylabel("error (bar)")
    ae.set_xlabel("t (s)")
    return fig
