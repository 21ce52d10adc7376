"""The linearity cost from the exact periodic steady state instead of the averaged Eq. 5.

The paper's cost (Eq. 25, :func:`spa.tuning.cost.linearity_cost`) measures the averaged
equilibrium ``P_eq(xi)`` against the line ``k2*xi``. For a constant input the pulse train is
periodic and the exact plant settles on a periodic orbit; :func:`exact_cost` puts the orbit's
exact time mean (:func:`spa.model.periodic.periodic_mean`: Appendix B's ``P+``/``P-`` for
PWM, IPFM and IIPFM, the true first-order pattern for ΔΣM) in place of ``P_eq``. Where the
two costs differ, the averaging assumption does not hold for the valve at hand.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from spa import _checks as checks
from spa._docs import fill_doc
from spa.model._broadcast import Floats
from spa.model.modulators import get_kind
from spa.model.params import ValveParams
from spa.tuning.cost import _on_xi_grid, deviation_cost

__all__ = ["exact_cost", "exact_curve"]


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
    p = checks.valve_params(params)
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
    p = checks.valve_params(params)
    curve = exact_curve(kind, value, p, n_xi, gain=gain)
    xi = np.linspace(0.0, 1.0, curve.shape[-1])
    return np.asarray(deviation_cost(curve, xi, p.k2), dtype=np.float64)[()]
