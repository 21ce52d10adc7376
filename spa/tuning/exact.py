"""The linearity cost from the exact periodic steady state instead of the averaged Eq. 5.

The paper's cost (Eq. 25, :func:`spa.tuning.cost.linearity_cost`) measures the averaged
equilibrium ``P_eq(xi)`` against the line ``k2*xi``. For a constant input the pulse train is
periodic and the exact plant settles on a periodic orbit; ``linearity_cost(..., exact=True)``
puts the orbit's exact time mean (:func:`spa.tuning.cost.mean_pressure`: Appendix B's
``P+``/``P-`` for PWM, IPFM and IIPFM, the true first-order pattern for ΔΣM) in place of
``P_eq``: ``J_exact``. Where the two costs differ, the averaging assumption does not hold for
the valve at hand. This module computes ``J_exact`` of several valves in one batch
(:func:`exact_costs`) and ranks settings with ties between the two costs.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import numpy.typing as npt
import pandas as pd

from spa.model.modulators import get_kind
from spa.model.params import ValveParams
from spa.tuning.cost import _on_xi_grid, deviation_cost, linearity_cost

__all__ = ["COST_TIE", "best_first", "exact_costs", "tied_optimum"]

#: Costs (bar) that differ by less than this are equal when settings are ranked. Model-inverse
#: PWM makes ``J`` zero by construction: its ``J`` over the sweep is rounding error (below
#: 1e-13), and ranking by it would pick an arbitrary setting. Its settings are then ranked by
#: the other cost. For the paper's four modulators the costs of grid neighbours differ by far
#: more, and nothing changes.
COST_TIE = 1e-9


def exact_costs(
    kind: str,
    values: Sequence[float],
    valves: Sequence[ValveParams],
    n_xi: int = 100,
) -> npt.NDArray[np.float64]:
    """``J_exact`` of one setting on each of several valves, in one batch.

    Parameters
    ----------
    kind : str
        Modulator type.
    values : sequence of float
        The swept parameter's value on each valve.
    valves : sequence of ValveParams
        As many as ``values`` (the corners of a parameter box, say).
    n_xi : int, default 100
        As :func:`spa.tuning.cost.linearity_cost`.

    Returns
    -------
    numpy.ndarray
        ``J_exact`` of each (value, valve), bit for bit
        ``linearity_cost(kind, value, valve, n_xi, exact=True)``'s: a kind whose
        orbit is iterated (ΔΣM) computes every valve's orbits in one Newton iteration
        (:meth:`spa.model.modulators.ModulatorKind.periodic_means`).

    Examples
    --------
    >>> a, b = ValveParams(), ValveParams(c1=0.6)
    >>> costs = exact_costs("dsm", [0.02, 0.03], [a, b], n_xi=20)
    >>> bool(costs[1] == linearity_cost("dsm", 0.03, b, 20, exact=True))
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
        tied setting with the smallest ``J_exact`` (computed for the tied ones only).

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
    tied_values = np.asarray(values)[tied]
    exact = np.asarray(linearity_cost(kind, tied_values, params, n_xi, exact=True), dtype=float)
    return int(tied[int(np.nanargmin(exact))])
