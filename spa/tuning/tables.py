"""Tidy tables of the tuning: the sweeps of Fig. 4, Table 2 and the curves of Fig. 5.

* :func:`sweep_frame` – the four sweeps of ``J`` (and optionally ``J_exact``) in one table;
* :func:`optimum_table` – the analytic stage's Table 2 at the nominal valve, beside the
  paper's printed values;
* :func:`tuning_table` – a dataset's Table 2: the optimum of each modulator for its own
  valve, with ``J`` at the paper's settings, ``J_exact`` and intervals;
* :func:`equilibrium_frame` – ``P_eq`` (and optionally the exact cycle mean) and ``tau_m``
  against ``xi`` at given settings (Fig. 5).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import replace

import numpy as np
import numpy.typing as npt
import pandas as pd

from spa import _checks as checks
from spa._docs import fill_doc
from spa._memo import memoised
from spa.model.averaging import equilibrium_pressure, time_constant, time_fractions
from spa.model.modulators import MODULATOR_ORDER, get_kind
from spa.model.params import ValveParams, valve_params
from spa.tuning.cost import (
    PAPER_TABLE2,
    SWEPT_PARAMETER,
    check_sweeps,
    constraint,
    linearity_cost,
    mean_pressure,
    modulator_settings,
    optimum,
    paper_setting,
    setting,
    sweep,
)
from spa.tuning.exact import best_first, exact_costs, tied_optimum
from spa.tuning.intervals import INTERVAL_METHOD, box_points, spread
from spa.tuning.recommend import TuningOptions, candidate_frame

__all__ = ["equilibrium_frame", "optimum_table", "sweep_frame", "tuning_table"]

#: The paper's Table 2 columns of a kind it does not have.
_NO_PAPER = (np.nan, np.nan, "")


@fill_doc
def sweep_frame(
    sweeps: Mapping[str, Mapping[str, float]],
    params: ValveParams | None = None,
    n_xi: int = 100,
    exact: bool = False,
) -> pd.DataFrame:
    """The four sweeps of Fig. 4 as one tidy table.

    Parameters
    ----------
    sweeps : mapping
        ``kind -> {"start", "stop", "step"}`` for all four kinds (``analytic.sweeps``).
    %(params)s
    n_xi : int, default 100
        Points of ``xi`` in the cost.
    exact : bool, default False
        Add the column ``J_exact`` (:func:`spa.tuning.cost.linearity_cost` with ``exact``).

    Returns
    -------
    pandas.DataFrame
        Columns ``modulator``, ``parameter``, ``value`` (in ``unit``), ``unit``, ``x_ms`` (the
        common axis of Fig. 4: PWM period ``1000/f_w``, otherwise ``1000*value``), ``J``
        (NaN where infeasible), and ``J_exact`` when asked.

    Raises
    ------
    ValueError
        If a kind is missing, a grid is bad, or a delay is longer than a whole sweep
        (:func:`spa.tuning.cost.check_sweeps`).
    """
    p = valve_params(params)
    parts = []
    for kind, g in check_sweeps(sweeps, p).items():
        values, cost = sweep(kind, p, g["start"], g["stop"], g["step"], n_xi)
        name, unit = SWEPT_PARAMETER[kind]
        x_ms = get_kind(kind).axis_ms(values)
        parts.append(
            pd.DataFrame(
                {
                    "modulator": kind,
                    "parameter": name,
                    "value": values,
                    "unit": unit,
                    "x_ms": np.round(x_ms, 9),
                    "J": cost,
                }
            )
        )
        if exact:  # kept between runs: the grid's exact costs do not depend on the constraints
            key = {"kind": kind, "values": values.tolist(), "params": p, "n_xi": n_xi}
            j_exact = memoised(
                "tuning-exact-sweep",
                key,
                lambda k=kind, v=values: linearity_cost(k, v, p, n_xi, exact=True),
            )
            parts[-1]["J_exact"] = np.where(np.isfinite(cost), j_exact, np.nan)
    return pd.concat(parts, ignore_index=True)


def optimum_table(
    sweeps: Mapping[str, Mapping[str, float]],
    params: ValveParams | None = None,
    n_xi: int = 100,
) -> pd.DataFrame:
    """Table 2: the optimum of each sweep beside the paper's printed values.

    Parameters
    ----------
    sweeps, params, n_xi
        As :func:`sweep_frame`.

    Returns
    -------
    pandas.DataFrame
        One row per modulator: ``modulator``, ``constraint``, ``J_min``, ``parameter``,
        ``optimum`` and ``unit`` (Hz for PWM, ms otherwise), ``gain`` (IPFM 1, IIPFM
        ``1 + t_on/t_l``, else empty), ``paper_J_min``, ``paper_optimum`` (printed values, for
        reference only), ``analytic_optimum`` (Eq. 29's ``t_l*`` for IIPFM, else empty).
    """
    p = valve_params(params)
    rows = []
    for kind, g in check_sweeps(sweeps, p).items():
        value, j_min = optimum(kind, p, g["start"], g["stop"], g["step"], n_xi)
        name, unit = SWEPT_PARAMETER[kind]
        scale, shown = (1.0, "Hz") if unit == "Hz" else (1e3, "ms")
        settings = modulator_settings(kind, value, p)
        paper_j, paper_value, _ = PAPER_TABLE2.get(kind, _NO_PAPER)
        rows.append(
            {
                "modulator": kind,
                "constraint": constraint(kind, p),
                "J_min": j_min,
                "parameter": name,
                "optimum": round(value * scale, 9),
                "unit": shown,
                "gain": settings.get("gain", np.nan),
                "paper_J_min": paper_j,
                "paper_optimum": paper_value,
                "analytic_optimum": get_kind(kind).analytic_optimum(p),
            }
        )
    return pd.DataFrame(rows)


@fill_doc
def equilibrium_frame(
    optima: Mapping[str, float],
    params: ValveParams | None = None,
    n_xi: int = 100,
    exact: bool = False,
) -> pd.DataFrame:
    """Equilibrium pressure and time constant against ``xi`` at given settings (Fig. 5).

    Parameters
    ----------
    optima : mapping
        ``kind -> value`` of the swept parameter (Hz for PWM, s otherwise); settings from
        :func:`modulator_settings`.
    %(params)s
    n_xi : int, default 100
        Points of ``xi`` in [0, 1].
    exact : bool, default False
        Add the column ``p_exact``: the exact cycle mean of the periodic steady state
        (:func:`spa.tuning.cost.mean_pressure` with ``exact``).

    Returns
    -------
    pandas.DataFrame
        Columns ``modulator``, ``parameter``, ``value``, ``gain``, ``xi``, ``p_eq`` (Eq. 5),
        ``p_target`` (``k2*xi``), ``tau_m`` (Eq. 9; NaN in the dead-zone and past saturation),
        and ``p_exact`` when asked.
    """
    p = valve_params(params)
    xi = np.linspace(0.0, 1.0, checks.integer("n_xi", n_xi, minimum=2))
    parts = []
    for kind in MODULATOR_ORDER:
        if kind not in optima:
            continue
        settings = modulator_settings(kind, optima[kind], p)
        a1, a2 = time_fractions(kind, xi, p, **settings)
        parts.append(
            pd.DataFrame(
                {
                    "modulator": kind,
                    "parameter": SWEPT_PARAMETER[kind][0],
                    "value": settings[SWEPT_PARAMETER[kind][0]],
                    "gain": settings.get("gain", np.nan),
                    "xi": xi,
                    "p_eq": equilibrium_pressure(a1, a2, p),
                    "p_target": p.k2 * xi,
                    "tau_m": time_constant(a1, a2, p),
                }
            )
        )
        if exact:
            parts[-1]["p_exact"] = mean_pressure(kind, xi, p, settings, exact=True)
    if not parts:
        raise ValueError(f"optima: expected some of {list(MODULATOR_ORDER)}, got {sorted(optima)}")
    return pd.DataFrame(pd.concat(parts, ignore_index=True))


def _best(frame: pd.DataFrame, column: str) -> pd.Series:
    """The row of ``frame`` with the smallest finite ``column`` (:func:`best_first`)."""
    return best_first(frame, column).iloc[0]


def _at_edge(rows: pd.DataFrame, value: float) -> bool:
    """Whether ``value`` is the first or the last setting of a sweep where ``J`` is defined."""
    defined = rows.loc[np.isfinite(rows["J"].to_numpy(dtype=float)), "value"]
    return bool(np.isfinite(value) and value in (defined.iloc[0], defined.iloc[-1]))


def _meeting_constraints(
    rows: pd.DataFrame, candidates: pd.DataFrame, kind: str, params: ValveParams
) -> pd.DataFrame:
    """The rows of one modulator's sweep whose setting (default gain) meets the constraints."""
    c = candidates[candidates["modulator"] == kind]
    gain = c["gain"].to_numpy(dtype=float)
    default = modulator_settings(kind, c["value"].to_numpy(dtype=float), params).get("gain")
    if default is not None:  # IIPFM's 1 + t_on/t_l (a gain sweep adds other rows)
        c = c[np.isclose(gain, np.asarray(default, dtype=float), rtol=1e-12, atol=0.0)]
    ok = c.loc[c["feasible"].to_numpy(dtype=bool), "value"].to_numpy(dtype=float)
    return rows[np.isin(rows["value"].to_numpy(dtype=float), ok)]


def _corner_optima(
    grids: Mapping[str, Mapping[str, float]], valves: Sequence[ValveParams], n_xi: int
) -> npt.NDArray[np.float64]:
    """``[optimum, J_min, J_exact at it]`` per valve and modulator (shape ``(valves,
    modulators, 3)``); each modulator's ``J_exact`` of every valve in one batch
    (:func:`spa.tuning.exact.exact_costs`)."""
    rows = np.empty((len(valves), len(grids), 3))
    for k, (kind, g) in enumerate(grids.items()):
        for v, params in enumerate(valves):
            values, j = sweep(kind, params, g["start"], g["stop"], g["step"], n_xi)
            if not np.any(np.isfinite(j)):  # the error of optimum(): no feasible grid point
                optimum(kind, params, g["start"], g["stop"], g["step"], n_xi)
            i = tied_optimum(kind, values, j, params, n_xi)
            rows[v, k, :2] = float(values[i]), float(j[i])
        rows[:, k, 2] = exact_costs(kind, rows[:, k, 0].tolist(), valves, n_xi)
    return rows


def tuning_table(
    sweeps: Mapping[str, Mapping[str, float]],
    params: ValveParams | None = None,
    n_xi: int = 100,
    intervals: Mapping[str, tuple[float, float]] | None = None,
    data: pd.DataFrame | None = None,
    options: TuningOptions | None = None,
    candidates: pd.DataFrame | None = None,
) -> pd.DataFrame:
    """Table 2 for one valve: each modulator's optimum, J and J_exact, with intervals.

    Parameters
    ----------
    sweeps, params, n_xi
        As :func:`sweep_frame`.
    intervals : mapping, optional
        95 % intervals of the valve parameters
        (:func:`~spa.identification.identified.read_intervals`);
        propagated by :func:`spa.tuning.intervals.propagate` (corners of the box).
    data : pandas.DataFrame, optional
        ``sweep_frame(sweeps, params, n_xi, exact=True)`` when already computed.
    options : TuningOptions, optional
        The constraints (switching rate, chattering, shortest pulse, ranges) that
        ``optimum_exact`` must meet; the defaults of
        :class:`~spa.tuning.recommend.TuningOptions` when omitted.
    candidates : pandas.DataFrame, optional
        :func:`spa.tuning.recommend.candidate_frame` of the same sweeps and ``options``
        when already computed.

    Returns
    -------
    pandas.DataFrame
        One row per modulator, with the columns

        * ``modulator``, ``parameter``, ``optimum`` (the grid value minimising ``J``, in
          ``unit``: Hz for PWM, ms otherwise), ``unit``, ``gain`` (IPFM 1, IIPFM
          ``1 + t_on/t_l``), ``J_min`` (``J`` there, Eq. 25);
        * ``analytic_optimum``: Eq. 29's ``t_l*`` in ms for IIPFM (empty for the others, and
          for IIPFM when ``c1*sqrt(k2/2)/tau2 >= 1``);
        * ``J_paper_setting``: ``J`` at the paper's setting (20 Hz, 20 ms; IIPFM with
          ``G = 1 + t_on/t_l``), the like-for-like value beside the paper's printed Table 2;
        * ``J_exact``: the exact periodic steady state's cost at ``optimum``;
        * ``optimum_lo``, ``optimum_hi``, ``J_min_lo``, ``J_min_hi``, ``J_exact_lo``,
          ``J_exact_hi``: the smallest and largest values over the corners of the
          parameters' 95 % box (each corner re-optimised), and ``interval_method``
          (``"corners"``, or ``"none"`` without intervals: then the ends equal the values);
        * ``label`` (the optimum's :attr:`~spa.model.modulators.Modulator.label`),
          ``J_exact_paper_setting``, ``optimum_exact`` and ``J_exact_min`` (the smallest
          ``J_exact`` over the settings that meet ``options``' constraints; NaN when none
          does), ``constraint`` (Section 5.1), ``paper_optimum`` and ``paper_J_min`` (the
          paper's printed Table 2, for reference only);
        * ``optimum_at_grid_edge`` and ``optimum_exact_at_grid_edge``: True when that
          optimum is the first or the last setting of the sweep (where ``J`` is defined), so
          that the true minimum may lie outside the grid.

    Notes
    -----
    Over the whole grid, ``J_exact`` falls towards 0 as the period grows: the pressure then
    swings from near 0 to near ``k2`` every cycle, and its cycle mean tends to ``k2`` times
    the duty, a line in ``xi``. Its unconstrained minimum therefore sits at the longest period
    of the grid, with a chattering of most of ``k2``; the chattering and switching
    constraints keep ``optimum_exact`` to usable settings.

    Raises
    ------
    ValueError
        As :func:`sweep_frame`.
    """
    p = valve_params(params)
    n = checks.integer("n_xi", n_xi, minimum=2)
    grids = check_sweeps(sweeps, p)
    if data is None:
        data = sweep_frame(grids, p, n, exact=True)
    if candidates is None:
        opts = replace(options or TuningOptions(), gain_sweep=None)
        candidates = candidate_frame(grids, p, n, opts, data)
    # the box's corners depend on the valve, the sweeps and n_xi alone, not on the
    # constraints: kept between runs of the pipeline (a tuning: change reuses them)
    lo, hi = memoised(
        "tuning-corners",
        {"params": p, "intervals": intervals or {}, "grids": grids, "n_xi": n},
        lambda: np.stack(spread(_corner_optima(grids, box_points(p, intervals), n))),
    )
    rows = []
    for i, kind in enumerate(grids):
        d = data[data["modulator"] == kind]
        best = _best(d, "J")
        usable = _meeting_constraints(d, candidates, kind, p)
        if np.isfinite(usable["J_exact"].to_numpy(dtype=float)).any():
            best_exact = _best(usable, "J_exact")
            value_exact, j_exact_min = float(best_exact["value"]), float(best_exact["J_exact"])
        else:
            value_exact = j_exact_min = np.nan
        value = float(best["value"])
        mod = setting(kind, value, p)
        paper = paper_setting(kind, p)
        scale = get_kind(kind).scale
        try:
            analytic = get_kind(kind).analytic_optimum(p)
        except ValueError:
            analytic = np.nan
        rows.append(
            {
                "modulator": kind,
                "parameter": SWEPT_PARAMETER[kind][0],
                "optimum": round(value * scale, 9),
                "unit": get_kind(kind).display_unit,
                "gain": mod.settings.get("gain", np.nan),
                "J_min": float(best["J"]),
                "analytic_optimum": analytic,
                "J_paper_setting": float(linearity_cost(kind, paper.value, p, n)),
                "J_exact": float(best["J_exact"]),
                "optimum_lo": round(lo[i, 0] * scale, 9),
                "optimum_hi": round(hi[i, 0] * scale, 9),
                "J_min_lo": lo[i, 1],
                "J_min_hi": hi[i, 1],
                "J_exact_lo": lo[i, 2],
                "J_exact_hi": hi[i, 2],
                "interval_method": INTERVAL_METHOD if intervals else "none",
                "label": mod.label,
                "J_exact_paper_setting": float(linearity_cost(kind, paper.value, p, n, exact=True)),
                "optimum_exact": round(value_exact * scale, 9),
                "J_exact_min": j_exact_min,
                "constraint": constraint(kind, p),
                "paper_optimum": PAPER_TABLE2.get(kind, _NO_PAPER)[1],
                "paper_J_min": PAPER_TABLE2.get(kind, _NO_PAPER)[0],
                "optimum_at_grid_edge": _at_edge(d, value),
                "optimum_exact_at_grid_edge": _at_edge(d, value_exact),
            }
        )
    return pd.DataFrame(rows)
