"""How a modulator that inverts a valve model (LPWM) fares when the model is wrong.

The inverse uses each corner of the identified parameters' 95 % box while the plant keeps the
estimate; the linearity costs ``J`` (averaged, Eq. 25) and ``J_exact`` (exact periodic orbit)
show what an identification error costs. Kinds that take nothing from the valve are
insensitive by construction and have no corners.
"""

from __future__ import annotations

import itertools
from collections.abc import Mapping

import numpy as np
import pandas as pd

from spa import _checks as checks
from spa.model.averaging import equilibrium
from spa.model.modulators import Modulator
from spa.model.params import ValveParams
from spa.model.steady_state import periodic_mean
from spa.tuning.cost import deviation_cost

__all__ = ["valve_sensitivity"]


def valve_sensitivity(
    mod: Modulator | Mapping[str, object],
    params: ValveParams,
    intervals: Mapping[str, tuple[float, float]],
    n_xi: int = 100,
) -> pd.DataFrame:
    """``J`` and ``J_exact`` with the inverse at each corner of the parameters' box.

    Parameters
    ----------
    mod : Modulator or mapping
        A setting of a kind that takes valve parameters (LPWM); its own valve settings are
        replaced, corner by corner.
    params : ValveParams
        The plant (the identified estimate).
    intervals : mapping
        ``name -> (lo, hi)`` of the valve parameters (``params.yaml``'s 95 % intervals);
        parameters without an interval keep the estimate.
    n_xi : int, default 100
        Points ``xi_i = i/(n_xi - 1)`` of the costs.

    Returns
    -------
    pandas.DataFrame
        One row for the estimate (``case = "estimate"``), then one per corner
        (``corner-<lo/hi pattern>``): the inverse's ``c1, k2, tau2, t_on, t_off``, ``J`` and
        ``J_exact`` in bar.

    Raises
    ------
    ValueError
        If the kind takes nothing from the valve.

    Examples
    --------
    >>> t = valve_sensitivity({"type": "lpwm", "f_w": 20.0}, ValveParams(),
    ...                       {"t_on": (0.002, 0.004)}, n_xi=20)
    >>> t["case"].tolist()
    ['estimate', 'corner-lo', 'corner-hi']
    """
    m = Modulator.from_mapping(mod)
    names = [k for k in m.spec.optional if k in params.as_dict()]
    if not names:
        raise ValueError(f"{m.label}: takes no valve parameters; nothing to be sensitive to")
    n = checks.integer("n_xi", n_xi, minimum=2)
    xi = np.linspace(0.0, 1.0, n)
    base = {k: v for k, v in m.settings.items() if k not in names}
    varied = [k for k in names if k in intervals]
    cases = [("estimate", params.as_dict())]
    for pattern in itertools.product((0, 1), repeat=len(varied)):
        valve = params.as_dict()
        for k, i in zip(varied, pattern, strict=True):
            valve[k] = float(intervals[k][i])
        cases.append(("corner-" + "-".join("lo" if i == 0 else "hi" for i in pattern), valve))
    rows = []
    for case, valve in cases:
        inverse = {**base, **{k: valve[k] for k in names}}
        p_eq = equilibrium(m.kind, xi, params, **inverse)
        p_ex = periodic_mean(m.kind, xi, params, **inverse)
        rows.append(
            {
                "case": case,
                **{k: valve[k] for k in names},
                "J": float(deviation_cost(p_eq, xi, params.k2)),
                "J_exact": float(deviation_cost(p_ex, xi, params.k2)),
            }
        )
    return pd.DataFrame(rows)
