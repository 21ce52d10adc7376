"""The linearity cost from the exact periodic steady state instead of the averaged Eq. 5.

The paper's cost (Eq. 25, :func:`spa.tuning.cost.linearity_cost`) measures the averaged
equilibrium ``P_eq(xi)`` against the line ``k2*xi``. For a constant input the pulse train is
periodic and the exact plant settles on a periodic orbit; :func:`exact_cost` puts the orbit's
exact time mean (:func:`spa.model.steady_state.periodic_mean`: Appendix B's ``P+``/``P-`` for
PWM, IPFM and IIPFM, the true first-order pattern for ΔΣM) in place of ``P_eq``. Where the
two costs differ, the averaging assumption does not hold for the valve at hand.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import numpy.typing as npt
import pandas as pd

from spa._docs import fill_doc
from spa.model._broadcast import Floats
from spa.model.modulators import get_kind
from spa.model.params import ValveParams, valve_params
from spa.tuning.cost import _on_xi_grid, deviation_cost

__all__ = ["COST_TIE", "best_first", "exact_cost", "exact_costs", "exact_curve", "tied_optimum"]

#: Costs (bar) that differ by less than this are equal when settings are ranked. Model-inverse
#: PWM makes ``J`` zero by construction: its ``J`` over the sweep is rounding error (below
#: 1e-13), and ranking by it would pick an arbitrary setting. Its settings are then ranked by
#: the other cost. For the paper's four modulators the costs of grid neighbours differ by far
#: more, and nothing changes.
COST_TIE = 1e-9


@fill_doc
def exact_curve(
    kind: str,
    value: npt.ArrayLike,
    params: ValveParams | None = None,
    n_xi: int = 100,
    *,
    gain: npt.ArrayLike | None = None,
) -> npt.NDArray[np.float64]:
    """Exact mean pressure of the periodic steady state on the grid of ``n_xi`` fractions.

    Parameters
    ----------
    %(kind)s
    value : array_like of float
        Swept parameter value(s) (:func:`spa.tuning.cost.modulator_settings`).
    %(params)s
    n_xi : int, default 100
        Points ``xi_i = i/(n_xi - 1)``.
    gain : array_like of float, optional
        IPFM/IIPFM gain instead of the default.

    Returns
    -------
    numpy.ndarray
        Shape ``value.shape + (n_xi,)``: the cycle mean at each ``xi_i``, bar. For ΔΣM each
        ``xi_i`` is the fraction ``i/(n_xi - 1)`` exactly (its pattern repeats every
        ``(n_xi - 1)/gcd`` clock periods).

    Raises
    ------
    ValueError
        As :func:`spa.tuning.cost.linearity_cost`.
    """
    p = valve_params(params)
    _, xi, grid = _on_xi_grid(kind, value, p, n_xi, gain)
    mean = get_kind(kind).periodic_mean(xi, grid, p, max_denominator=xi.size - 1)
    return np.asarray(mean, dtype=np.float64)


@fill_doc
def exact_cost(
    kind: str,
    value: npt.ArrayLike,
    params: ValveParams | None = None,
    n_xi: int = 100,
    *,
    gain: npt.ArrayLike | None = None,
) -> Floats:
    """Linearity cost ``J_exact`` of Eq. 25 with the exact periodic steady state.

    Parameters
    ----------
    %(cost_args)s

    Returns
    -------
    numpy.ndarray or numpy.float64
        ``sum_i |P_mean(xi_i) - k2*xi_i|`` in bar, of the shape of ``value`` (broadcast with
        ``gain``), with ``P_mean`` the exact time mean over one cycle of the periodic orbit
        (:func:`exact_curve`).

    Raises
    ------
    ValueError
        As :func:`spa.tuning.cost.linearity_cost`.

    Notes
    -----
    Under fast switching (periods far below ``tau2`` and ``c1*sqrt(P)``) the orbit is close
    to its average and ``J_exact`` to ``J``. The holds make the orbit linger at ``P+`` for
    ``t_off`` and at ``P-`` for ``t_on``, which Eq. 5 does not see.

    Examples
    --------
    >>> from spa.tuning.cost import linearity_cost
    >>> j, j_exact = linearity_cost("iipfm", 0.0195), exact_cost("iipfm", 0.0195)
    >>> round(float(j), 2), round(float(j_exact), 2)
    (3.63, 3.62)
    """
    p = valve_params(params)
    curve = exact_curve(kind, value, p, n_xi, gain=gain)
    xi = np.linspace(0.0, 1.0, curve.shape[-1])
    return np.asarray(deviation_cost(curve, xi, p.k2), dtype=np.float64)[()]


def exact_costs(
    kind: str,
    values: Sequence[float],
    valves: Sequence[ValveParams],
    n_xi: int = 100,
) -> npt.NDArray[np.float64]:
    """:func:`exact_cost` of one setting on each of several valves, in one batch.

    Parameters
    ----------
    kind : str
        Modulator type.
    values : sequence of float
        The swept parameter's value on each valve.
    valves : sequence of ValveParams
        As many as ``values`` (the corners of a parameter box, say).
    n_xi : int, default 100
        As :func:`exact_cost`.

    Returns
    -------
    numpy.ndarray
        ``J_exact`` of each (value, valve), bit for bit :func:`exact_cost`'s: a kind whose
        orbit is iterated (ΔΣM) computes every valve's orbits in one Newton iteration
        (:meth:`spa.model.modulators.ModulatorKind.periodic_means`).

    Examples
    --------
    >>> a, b = ValveParams(), ValveParams(c1=0.6)
    >>> costs = exact_costs("dsm", [0.02, 0.03], [a, b], n_xi=20)
    >>> bool(costs[1] == exact_cost("dsm", 0.03, b, 20))
    True
    """
    grids, xi = [], None
    for value, valve in zip(values, valves, strict=True):
        _, xi, grid = _on_xi_grid(kind, value, valve, n_xi, None)
        grids.append(grid)
    if xi is None:
        return np.zeros(0)
    curves = get_kind(kind).periodic_means(xi, grids, list(valves), max_denominator=xi.size - 1)
    return np.array(
        [
            deviation_cost(np.asarray(curve, dtype=np.float64), xi, valve.k2)
            for curve, valve in zip(curves, valves, strict=True)
        ],
        dtype=np.float64,
    )


def best_first(frame: pd.DataFrame, score: str) -> pd.DataFrame:
    """Rows of ``frame`` ranked by ``score``, ties within :data:`COST_TIE` by the other cost.

    Parameters
    ----------
    frame : pandas.DataFrame
        Settings with columns ``J`` and ``J_exact`` (bar; NaN where infeasible).
    score : {"J", "J_exact"}
        The cost that ranks; the other breaks its ties.

    Returns
    -------
    pandas.DataFrame
        ``frame`` sorted best first (a stable sort: equal rows keep their order); rows
        whose ``score`` is NaN last.

    Examples
    --------
    >>> f = pd.DataFrame({"J": [2e-15, 1e-15, 3.6], "J_exact": [0.07, 0.6, 3.6]})
    >>> best_first(f, "J").index.tolist()
    [0, 1, 2]
    """
    other = "J_exact" if score == "J" else "J"
    bucket = np.round(frame[score].to_numpy(dtype=float) / COST_TIE)
    keys = pd.DataFrame({"_bucket": bucket, "_other": frame[other].to_numpy(dtype=float)})
    order = keys.sort_values(["_bucket", "_other"], kind="stable", na_position="last").index
    return frame.iloc[order.to_numpy()]


def tied_optimum(
    kind: str,
    values: npt.NDArray[np.float64],
    j: npt.NDArray[np.float64],
    params: ValveParams | None = None,
    n_xi: int = 100,
) -> int:
    """Index of the smallest ``J``, ties within :data:`COST_TIE` broken by ``J_exact``.

    Parameters
    ----------
    kind : str
        Modulator kind.
    values, j : numpy.ndarray
        The sweep's grid and its ``J`` (NaN where infeasible), as from
        :func:`spa.tuning.cost.sweep`; at least one finite.
    params : ValveParams, optional
        Valve parameters; nominal when omitted.
    n_xi : int, default 100
        Points of ``xi`` in ``J_exact``.

    Returns
    -------
    int
        The first index of the smallest ``J`` unless several settings tie with it; then the
        tied setting with the smallest :func:`exact_cost` (computed for the tied ones only).

    Examples
    --------
    >>> tied_optimum("pwm", np.array([10.0, 20.0]), np.array([1e-15, 2e-15]))
    1
    """
    j = np.asarray(j, dtype=np.float64)
    i = int(np.nanargmin(j))
    tied = np.flatnonzero(np.round(j / COST_TIE) == np.round(j[i] / COST_TIE))
    if tied.size < 2:
        return i
    exact = np.asarray(exact_cost(kind, np.asarray(values)[tied], params, n_xi), dtype=float)
    return int(tied[int(np.nanargmin(exact))])
