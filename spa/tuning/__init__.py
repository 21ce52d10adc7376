"""Tuning the modulators for linearity by optimisation (docs/model.md section 4, paper Section 5).

Each modulator has one principal parameter: ``f_w`` (Hz) for PWM, the pulse width ``t_h``
(s) for IPFM, the pulse separation ``t_l`` (s) for IIPFM (with the dead-zone-free gain
``G = 1 + t_on/t_l``, Eq. 17) and the clock period (s) for ΔΣM. The cost of Eq. 25 measures
how far the averaged equilibrium curve ``P_eq(xi)`` (Eq. 5) is from the line ``k2*xi``; the
sweep evaluates it on a grid of the parameter, all grid points at once.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
import numpy.typing as npt
import pandas as pd

from spa import _checks as checks
from spa.model.averaging import Floats, equilibrium_pressure, time_constant, time_fractions
from spa.model.modulators import MODULATORS
from spa.model.params import ValveParams

__all__ = [
    "PAPER_TABLE2",
    "SWEPT_PARAMETER",
    "constraint",
    "equilibrium_frame",
    "feasible",
    "iipfm_optimal_t_l",
    "linearity_cost",
    "modulator_settings",
    "optimum",
    "optimum_table",
    "sweep",
    "sweep_frame",
    "sweep_grid",
]

#: The swept parameter of each modulator: ``kind -> (setting name, unit)``.
SWEPT_PARAMETER: Mapping[str, tuple[str, str]] = {
    "pwm": ("f_w", "Hz"),
    "ipfm": ("t_h", "s"),
    "iipfm": ("t_l", "s"),
    "dsm": ("period", "s"),
}

#: Table 2 as printed in the paper: ``kind -> (J_min, selected parameter, unit)``.
#: Reference values for comparison columns only; nothing here is computed from them.
PAPER_TABLE2: Mapping[str, tuple[float, float, str]] = {
    "pwm": (10.5, 20.0, "Hz"),
    "ipfm": (12.5, 20.0, "ms"),
    "iipfm": (4.8, 20.0, "ms"),
    "dsm": (9.6, 20.0, "ms"),
}

#: Display names, in the paper's order.
_LABELS: Mapping[str, str] = {"pwm": "PWM", "ipfm": "IPFM", "iipfm": "IIPFM", "dsm": "ΔΣM"}


def _kind(kind: str) -> str:
    if kind not in MODULATORS:
        raise ValueError(f"unknown modulator kind {kind!r}; expected one of {sorted(MODULATORS)}")
    return kind


def _value(kind: str, value: npt.ArrayLike) -> npt.NDArray[np.float64]:
    return checks.positive_array(f"{kind}: {SWEPT_PARAMETER[kind][0]}", value)


def modulator_settings(
    kind: str, value: npt.ArrayLike, params: ValveParams | None = None
) -> dict[str, Any]:
    """Settings of a modulator for a value of its swept parameter.

    Parameters
    ----------
    kind : {"pwm", "ipfm", "iipfm", "dsm"}
        Modulator type.
    value : array_like of float
        ``f_w`` in Hz (PWM) or ``t_h``, ``t_l``, ``period`` in s.
    params : ValveParams, optional
        Valve parameters (IIPFM's gain uses ``t_on``); nominal when omitted.

    Returns
    -------
    dict
        Keyword settings for :mod:`spa.model.averaging` and
        :func:`spa.model.modulators.modulate`: IPFM uses ``gain = 1`` (the paper's choice),
        IIPFM ``gain = 1 + t_on/t_l`` (Eq. 17).
        Scalars in give floats out.

    Raises
    ------
    ValueError
        For an unknown ``kind`` or a non-positive value.

    Examples
    --------
    >>> modulator_settings("iipfm", 0.02)
    {'t_l': 0.02, 'gain': 1.15}
    >>> modulator_settings("pwm", 20.0)
    {'f_w': 20.0}
    """
    p = checks.valve_params(params)
    v = _value(_kind(kind), value)
    out: dict[str, Any] = {SWEPT_PARAMETER[kind][0]: v}
    if kind == "ipfm":
        out["gain"] = np.ones_like(v)
    elif kind == "iipfm":
        out["gain"] = 1.0 + p.t_on / v
    if v.ndim == 0:
        out = {k: float(x) for k, x in out.items()}
    return out


def constraint(kind: str, params: ValveParams | None = None) -> str:
    """The optimisation constraint of a modulator as text (paper Section 5.1, Table 2).

    Examples
    --------
    >>> constraint("dsm")
    'period > t_off = 10 ms and period > t_on = 3 ms'
    """
    p = checks.valve_params(params)
    on, off = f"{p.t_on * 1e3:g} ms", f"{p.t_off * 1e3:g} ms"
    return {
        "pwm": "f_w > 0 Hz",
        "ipfm": f"t_h > t_on = {on} (gain = 1)",
        "iipfm": f"t_l > t_off = {off} and gain = 1 + t_on/t_l",
        "dsm": f"period > t_off = {off} and period > t_on = {on}",
    }[_kind(kind)]


def feasible(
    kind: str, value: npt.ArrayLike, params: ValveParams | None = None
) -> npt.NDArray[np.bool_] | np.bool_:
    """Whether a parameter value satisfies the modulator's constraint (Section 5.1).

    Parameters
    ----------
    kind : {"pwm", "ipfm", "iipfm", "dsm"}
        Modulator type.
    value : array_like of float
        Swept parameter value(s), as in :func:`modulator_settings`.
    params : ValveParams, optional
        Valve parameters; nominal when omitted.

    Returns
    -------
    numpy.ndarray of bool or numpy.bool_
        PWM: always; IPFM: ``t_h > t_on``; IIPFM: ``t_l > t_off``; ΔΣM: ``period > t_off``
        and ``period > t_on``.

    Raises
    ------
    ValueError
        For an unknown ``kind`` or a non-positive value.

    Examples
    --------
    >>> feasible("ipfm", [0.002, 0.004]).tolist()
    [False, True]
    """
    p = checks.valve_params(params)
    v = _value(_kind(kind), value)
    if kind == "pwm":
        ok = np.ones(v.shape, dtype=bool)
    elif kind == "ipfm":
        ok = v > p.t_on
    elif kind == "iipfm":
        ok = v > p.t_off
    else:
        ok = (v > p.t_off) & (v > p.t_on)
    return np.asarray(ok)[()]


def linearity_cost(
    kind: str, value: npt.ArrayLike, params: ValveParams | None = None, n_xi: int = 100
) -> Floats:
    """Linearity cost ``J`` of a modulator setting (Eq. 25).

    Parameters
    ----------
    kind : {"pwm", "ipfm", "iipfm", "dsm"}
        Modulator type.
    value : array_like of float
        Swept parameter value(s) (:func:`modulator_settings`); an array gives one ``J`` each.
    params : ValveParams, optional
        Valve parameters; nominal when omitted.
    n_xi : int, default 100
        Number ``N`` of equally spaced input fractions in [0, 1], both ends included.

    Returns
    -------
    numpy.ndarray or numpy.float64
        ``J`` in bar, same shape as ``value``. The constraint is not applied here (see
        :func:`feasible`, :func:`sweep`).

    Raises
    ------
    ValueError
        For an unknown ``kind``, a non-positive value or ``n_xi < 2``.

    Notes
    -----
    ``J = sum_{i=1..N} |P_eq(xi_i) - k2*xi_i|``, ``xi_i = (i - 1)/(N - 1)``, with ``P_eq``
    the averaged equilibrium of Eq. 5. ``J`` grows with ``N``; compare costs at equal ``N``.

    Examples
    --------
    >>> round(float(linearity_cost("iipfm", 0.0195)), 2)
    3.63
    """
    p = checks.valve_params(params)
    n = checks.integer("n_xi", n_xi, minimum=2)
    settings = modulator_settings(kind, value, p)
    v = np.asarray(settings[SWEPT_PARAMETER[kind][0]])
    xi = np.linspace(0.0, 1.0, n)
    grid = {k: np.asarray(x)[..., np.newaxis] for k, x in settings.items()}
    a1, a2 = time_fractions(kind, xi, p, **grid)
    peq = np.asarray(equilibrium_pressure(a1, a2, p))
    cost = np.abs(peq - p.k2 * xi).sum(axis=-1)
    return np.asarray(cost, dtype=np.float64).reshape(v.shape)[()]


def sweep_grid(start: float, stop: float, step: float) -> npt.NDArray[np.float64]:
    """Grid ``start, start + step, ...`` up to ``stop`` inclusive (to 1e-9 of a step).

    Raises
    ------
    ValueError
        Unless ``0 < start <= stop`` and ``step > 0``, all finite.

    Examples
    --------
    >>> sweep_grid(0.0125, 0.0155, 0.001).tolist()
    [0.0125, 0.0135, 0.0145, 0.0155]
    """
    start = checks.positive("start", start)
    stop = checks.positive("stop", stop)
    step = checks.positive("step", step)
    if stop < start:
        raise ValueError(f"stop must be >= start, got start={start!r}, stop={stop!r}")
    n = int(np.floor((stop - start) / step + 1e-9)) + 1
    # Rounding removes the float noise of start + k*step (0.019500000000000003 -> 0.0195).
    return np.round(start + step * np.arange(n), 12)


def sweep(
    kind: str,
    params: ValveParams | None,
    start: float,
    stop: float,
    step: float,
    n_xi: int = 100,
) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
    """Linearity cost over a grid of the modulator's parameter, with the constraints.

    Parameters
    ----------
    kind : {"pwm", "ipfm", "iipfm", "dsm"}
        Modulator type.
    params : ValveParams or None
        Valve parameters; nominal when None.
    start, stop, step : float
        Grid of :func:`sweep_grid`, in the parameter's unit (Hz for PWM, s otherwise).
    n_xi : int, default 100
        Points of ``xi`` in the cost.

    Returns
    -------
    values, J : numpy.ndarray
        Grid values and ``J`` (Eq. 25); ``J`` is NaN where :func:`feasible` is False.

    Raises
    ------
    ValueError
        For an unknown ``kind``, a bad grid or ``n_xi``.

    Notes
    -----
    All grid points are evaluated at once (a ``(len(values), n_xi)`` array).

    Examples
    --------
    >>> v, j = sweep("ipfm", None, 0.001, 0.005, 0.002, n_xi=10)
    >>> v.tolist(), bool(np.isnan(j[0])), bool(np.isfinite(j[1]))
    ([0.001, 0.003, 0.005], True, False)
    """
    p = checks.valve_params(params)
    values = sweep_grid(start, stop, step)
    cost = np.asarray(linearity_cost(kind, values, p, n_xi), dtype=np.float64)
    return values, np.where(feasible(kind, values, p), cost, np.nan)


def optimum(
    kind: str,
    params: ValveParams | None,
    start: float,
    stop: float,
    step: float,
    n_xi: int = 100,
) -> tuple[float, float]:
    """Grid value minimising the linearity cost, and the minimum (Table 2).

    Parameters
    ----------
    kind, params, start, stop, step, n_xi
        As :func:`sweep`.

    Returns
    -------
    value, J_min : float
        The first grid value where the feasible ``J`` is smallest, and that ``J``.

    Raises
    ------
    ValueError
        As :func:`sweep`, or if no grid point is feasible.

    Examples
    --------
    >>> optimum("iipfm", None, 0.0125, 1.0, 0.001)[0]
    0.0195
    """
    values, cost = sweep(kind, params, start, stop, step, n_xi)
    if not np.any(np.isfinite(cost)):
        raise ValueError(f"{kind}: no feasible grid point in [{start}, {stop}]: {constraint(kind)}")
    i = int(np.nanargmin(cost))
    return float(values[i]), float(cost[i])


def iipfm_optimal_t_l(params: ValveParams | None = None) -> float:
    """Analytic IIPFM pulse separation that best linearises the valve (Eq. 29).

    Parameters
    ----------
    params : ValveParams, optional
        Valve parameters; nominal when omitted.

    Returns
    -------
    float
        ``t_l*`` in s.

    Raises
    ------
    ValueError
        If ``r = c1*sqrt(k2/2)/tau2 >= 1`` (then no positive ``t_l`` matches the ideal ratio).

    Notes
    -----
    Matching the IIPFM fraction ratio ``(t_l - t_off)²/(t_l + t_on)² * (1 - xi)²/xi²`` to the
    ideal ``c1²*k2/tau2² * (1 - xi)²/xi`` (Eq. 20) with ``(1 - xi)²/xi² ≈ 2*(1 - xi)²/xi``
    gives ``(t_l - t_off)/(t_l + t_on) = r`` with ``r = c1*sqrt(k2/2)/tau2``, so
    ``t_l* = (t_off + r*t_on)/(1 - r)``.

    Examples
    --------
    >>> round(iipfm_optimal_t_l() * 1e3, 1)  # ms; the paper prints 19 ms
    19.3
    """
    p = checks.valve_params(params)
    r = p.c1 * np.sqrt(p.k2 / 2.0) / p.tau2
    if r >= 1.0:
        raise ValueError(f"c1*sqrt(k2/2)/tau2 = {r:g} must be < 1 for Eq. 29 to have a solution")
    return float((p.t_off + r * p.t_on) / (1.0 - r))


# --------------------------------------------------------------------------- tidy tables
def _grids(sweeps: Mapping[str, Mapping[str, float]]) -> dict[str, Mapping[str, float]]:
    missing = [k for k in _LABELS if k not in sweeps]
    if missing:
        raise ValueError(f"sweeps: missing modulator(s) {missing}")
    return {k: sweeps[k] for k in _LABELS}


def sweep_frame(
    sweeps: Mapping[str, Mapping[str, float]],
    params: ValveParams | None = None,
    n_xi: int = 100,
) -> pd.DataFrame:
    """The four sweeps of Fig. 4 as one tidy table.

    Parameters
    ----------
    sweeps : mapping
        ``kind -> {"start", "stop", "step"}`` for all four kinds (``analytic.sweeps``).
    params : ValveParams, optional
        Valve parameters; nominal when omitted.
    n_xi : int, default 100
        Points of ``xi`` in the cost.

    Returns
    -------
    pandas.DataFrame
        Columns ``modulator``, ``parameter``, ``value`` (in ``unit``), ``unit``, ``x_ms`` (the
        common axis of Fig. 4: PWM period ``1000/f_w``, otherwise ``1000*value``), ``J``
        (NaN where infeasible).

    Raises
    ------
    ValueError
        If a kind is missing or a grid is bad.
    """
    p = checks.valve_params(params)
    parts = []
    for kind, g in _grids(sweeps).items():
        values, cost = sweep(kind, p, g["start"], g["stop"], g["step"], n_xi)
        name, unit = SWEPT_PARAMETER[kind]
        x_ms = 1e3 / values if kind == "pwm" else 1e3 * values
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
    p = checks.valve_params(params)
    rows = []
    for kind, g in _grids(sweeps).items():
        value, j_min = optimum(kind, p, g["start"], g["stop"], g["step"], n_xi)
        name, unit = SWEPT_PARAMETER[kind]
        scale, shown = (1.0, "Hz") if unit == "Hz" else (1e3, "ms")
        settings = modulator_settings(kind, value, p)
        paper_j, paper_value, _ = PAPER_TABLE2[kind]
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
                "analytic_optimum": iipfm_optimal_t_l(p) * 1e3 if kind == "iipfm" else np.nan,
            }
        )
    return pd.DataFrame(rows)


def equilibrium_frame(
    optima: Mapping[str, float], params: ValveParams | None = None, n_xi: int = 100
) -> pd.DataFrame:
    """Equilibrium pressure and time constant against ``xi`` at given settings (Fig. 5).

    Parameters
    ----------
    optima : mapping
        ``kind -> value`` of the swept parameter (Hz for PWM, s otherwise); settings from
        :func:`modulator_settings`.
    params : ValveParams, optional
        Valve parameters; nominal when omitted.
    n_xi : int, default 100
        Points of ``xi`` in [0, 1].

    Returns
    -------
    pandas.DataFrame
        Columns ``modulator``, ``parameter``, ``value``, ``gain``, ``xi``, ``p_eq`` (Eq. 5),
        ``p_target`` (``k2*xi``), ``tau_m`` (Eq. 9; NaN in the dead-zone and past saturation).
    """
    p = checks.valve_params(params)
    xi = np.linspace(0.0, 1.0, checks.integer("n_xi", n_xi, minimum=2))
    parts = []
    for kind in _LABELS:
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
    if not parts:
        raise ValueError(f"optima: expected some of {list(_LABELS)}, got {sorted(optima)}")
    return pd.DataFrame(pd.concat(parts, ignore_index=True))
