"""The figure of the actuator's own laws against the paper's, with their simultaneous bands and
the pressures the data visited (docs/model.md, "The general two-mode model").

As every figure here, in two steps: :func:`laws_data` builds a tidy table from
``params.yaml``'s content and :func:`laws_figure` draws exactly that table.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

import numpy as np
import pandas as pd

from spa.identification.laws_bands import MODES
from spa.model.laws.rates import closed_rate, open_rate
from spa.model.params import ValveParams
from spa.plots.style import OKABE_ITO, legend_beside, new_figure

if TYPE_CHECKING:
    from matplotlib.figure import Figure

__all__ = ["laws_data", "laws_figure"]

_IDENTIFIED, _PAPER, _VISITED = OKABE_ITO[6], OKABE_ITO[5], "0.9"
_TITLES = {"open": "valve open: f_open(P)", "closed": "valve closed: f_closed(P)"}
_SERIES = ("identified", "lo", "hi", "paper")


def laws_data(params: Mapping[str, Any]) -> pd.DataFrame:
    """Tidy data of the laws' figure from ``params.yaml``'s content.

    Parameters
    ----------
    params : mapping
        :meth:`spa.identification.IdentificationResult.to_dict`'s content, whose ``laws:``
        record carries ``bands`` and ``visited``
        (:func:`spa.identification.laws_record.laws_record`).

    Returns
    -------
    pandas.DataFrame
        ``mode`` (``open``, ``closed``), ``series`` (``identified``: the identified law's
        rate; ``lo``, ``hi``: its simultaneous band; ``paper``: the paper's law with the
        paper's identified ``c1``, ``k2``, ``tau2``; ``visited``: two rows, the lowest and
        highest pressure the data visited in that mode), ``p`` (bar), ``dpdt`` (bar/s, NaN
        for ``visited``), and the attribute ``chosen`` (``attrs``).

    Raises
    ------
    ValueError
        If the ``laws:`` record has no ``bands`` (the laws were not fitted: say why, from
        its ``reason``), or a parameter is missing; named.
    """
    record = params.get("laws")
    if not isinstance(record, Mapping) or not isinstance(record.get("bands"), Mapping):
        why = record.get("reason", "no laws: record") if isinstance(record, Mapping) else ""
        raise ValueError(f"params.yaml: laws: has no bands (the laws were not fitted: {why})")
    values = {}
    for name in ("c1", "k2", "tau2", "t_on", "t_off"):
        item = params.get(name)
        value = item.get("value") if isinstance(item, Mapping) else item
        if value is None:
            raise ValueError(f"params.yaml: no value for {name!r}; the paper's laws need it")
        values[name] = float(value)
    paper = ValveParams(**values)
    bands = record["bands"]
    grid = np.asarray(bands["grid"], dtype=np.float64)
    parts = []
    for mode, law in zip(MODES, (open_rate, closed_rate), strict=True):
        rec = bands[mode]
        for series in _SERIES[:3]:
            key = "rate" if series == "identified" else series
            rate = np.array([np.nan if v is None else v for v in rec[key]], dtype=np.float64)
            parts.append(pd.DataFrame({"mode": mode, "series": series, "p": grid, "dpdt": rate}))
        parts.append(pd.DataFrame({"mode": mode, "series": "paper", "p": grid,
                                   "dpdt": law(grid, paper)}))  # fmt: skip
        span = (record.get("visited") or {}).get(mode) or [None, None]
        parts.append(
            pd.DataFrame(
                {
                    "mode": mode,
                    "series": "visited",
                    "p": [np.nan if v is None else float(v) for v in span],
                    "dpdt": np.nan,
                }
            )
        )
    data = pd.concat(parts, ignore_index=True)
    data.attrs["chosen"] = str(record.get("chosen", "paper"))
    return data


def laws_figure(data: pd.DataFrame) -> Figure:
    """The identified laws against the paper's, each mode in its panel.

    Parameters
    ----------
    data : pandas.DataFrame
        Output of :func:`laws_data`.

    Returns
    -------
    matplotlib.figure.Figure
        Per mode: the identified rate (solid) inside its simultaneous 95 % band (filled), the
        paper's (dashed), and the pressures the data visited in that mode shaded grey; the
        rates outside the shading are extrapolated.

    Raises
    ------
    ValueError
        If a column or a mode is missing; named.
    """
    missing = [c for c in ("mode", "series", "p", "dpdt") if c not in data.columns]
    if missing:
        raise ValueError(f"laws data lack column(s) {missing}; it has {list(data.columns)}")
    fig = new_figure(figsize=(8.0, 3.4), layout="constrained")
    axes = fig.subplots(1, 2)
    chosen = data.attrs.get("chosen", "")
    for ax, mode in zip(axes, MODES, strict=True):
        d = data[data["mode"] == mode]
        if d.empty:
            raise ValueError(f"laws data have no rows for mode {mode!r}")

        def series(name: str, d: pd.DataFrame = d) -> pd.DataFrame:
            return d[d["series"] == name]

        span = series("visited")["p"].to_numpy()
        if span.size == 2 and np.all(np.isfinite(span)):
            ax.axvspan(span[0], span[1], color=_VISITED, zorder=0, label="pressures visited")
        lo, hi = series("lo"), series("hi")
        ax.fill_between(lo["p"], lo["dpdt"], hi["dpdt"].to_numpy(), color=_IDENTIFIED,
                        alpha=0.25, lw=0, label="95 % simultaneous band")  # fmt: skip
        own = series("identified")
        ax.plot(own["p"], own["dpdt"], color=_IDENTIFIED, lw=1.5, label="identified laws")
        pap = series("paper")
        ax.plot(pap["p"], pap["dpdt"], color=_PAPER, lw=1.2, ls="--", label="paper's laws")
        ax.axhline(0.0, color="0.5", lw=0.5)
        ax.set_xlabel("P (bar)")
        ax.set_ylabel("dP/dt (bar/s)")
        ax.set_title(_TITLES[mode])
    legend_beside(axes[1], frameon=False)
    if chosen:
        fig.suptitle(f"The actuator's laws (chosen: {chosen})")
    return fig
