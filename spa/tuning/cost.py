"""The linearity cost of Eq. 25 over each modulator's parameter (paper Section 5).

Each modulator has one principal parameter: ``f_w`` (Hz) for PWM, the pulse width ``t_h``
(s) for IPFM, the pulse separation ``t_l`` (s) for IIPFM (with the dead-zone-free gain
``G = 1 + t_on/t_l``, Eq. 17) and the clock period (s) for ΔΣM. The cost of Eq. 25 measures
how far the averaged equilibrium curve ``P_eq(xi)`` (Eq. 5) is from the line ``k2*xi``; the
sweep evaluates it on a grid of the parameter, all grid points at once. :func:`optimum`
takes the grid minimum and :func:`iipfm_optimal_t_l` the analytic IIPFM optimum (Eq. 29).
"""

from __future__ import annotations

from collections.abc import Callable, Iterator, Mapping
from typing import Any

import numpy as np
import numpy.typing as npt

from spa import _checks as checks
from spa._checks import MAX_SWEEP_POINTS
from spa._docs import fill_doc
from spa.model.averaging import Floats, equilibrium_pressure, time_fractions
from spa.model.modulators import MODULATOR_ORDER, MODULATORS, PARAMETER, Modulator, get_kind
from spa.model.modulators.iipfm import iipfm_optimal_t_l
from spa.model.params import ValveParams, valve_params
from spa.openloop.paper import PAPER_SETTING, PAPER_TABLE2

__all__ = [
    "DEFAULT_SWEEPS",
    "PAPER_SETTING",
    "PAPER_TABLE2",
    "SWEPT_PARAMETER",
    "CostFunction",
    "check_sweeps",
    "constraint",
    "deviation_cost",
    "feasible",
    "iipfm_optimal_t_l",
    "linearity_cost",
    "mean_pressure",
    "modulator_settings",
    "optimum",
    "paper_setting",
    "setting",
    "sweep",
    "sweep_grid",
]

#: The swept parameter of each modulator: ``kind -> (setting name, unit)``.
SWEPT_PARAMETER: Mapping[str, tuple[str, str]] = PARAMETER


class _Grids(Mapping[str, Mapping[str, float]]):
    """``kind -> {start, stop, step}``: each registered kind's default grid."""

    def __getitem__(self, kind: str) -> Mapping[str, float]:
        return get_kind(kind).default_grid if kind in MODULATORS else {}[kind]

    def __iter__(self) -> Iterator[str]:
        return iter(MODULATOR_ORDER)

    def __len__(self) -> int:
        return len(MODULATOR_ORDER)


#: The grids of Section 5.1 and each further kind's own: ``kind -> {start, stop, step}``
#: (Hz for PWM and LPWM, s otherwise).
DEFAULT_SWEEPS: Mapping[str, Mapping[str, float]] = _Grids()

#: The kinds every sweep holds: those of the paper's Table 2.
_REQUIRED: tuple[str, ...] = tuple(PAPER_TABLE2)

#: A cost ``(kind, values, params, n_xi) -> J`` such as :func:`linearity_cost`.
CostFunction = Callable[[str, npt.NDArray[np.float64], ValveParams, int], Floats]


def _kind(kind: str) -> str:
    get_kind(kind)
    return kind


def _value(kind: str, value: npt.ArrayLike) -> npt.NDArray[np.float64]:
    return checks.positive_array(f"{kind}: {SWEPT_PARAMETER[kind][0]}", value)


@fill_doc
def modulator_settings(
    kind: str,
    value: npt.ArrayLike,
    params: ValveParams | None = None,
    gain: npt.ArrayLike | None = None,
) -> dict[str, Any]:
    """Settings of a modulator for a value of its swept parameter.

    Parameters
    ----------
    %(kind)s
    value : array_like of float
        ``f_w`` in Hz (PWM) or ``t_h``, ``t_l``, ``period`` in s.
    params : ValveParams, optional
        Valve parameters (IIPFM's gain uses ``t_on``); nominal when omitted.
    gain : array_like of float, optional
        IPFM/IIPFM gain instead of the default (broadcasts with ``value``); for a gain sweep.

    Returns
    -------
    dict
        Keyword settings for :mod:`spa.model.averaging` and
        :func:`spa.model.modulators.modulate`: IPFM uses ``gain = 1`` (the paper's choice),
        IIPFM ``gain = 1 + t_on/t_l`` (Eq. 17), unless ``gain`` is given.
        Scalars in give floats out.

    Raises
    ------
    ValueError
        For an unknown ``kind``, a non-positive value or gain, or a gain for PWM or ΔΣM.

    Examples
    --------
    >>> modulator_settings("iipfm", 0.02)
    {'t_l': 0.02, 'gain': 1.15}
    >>> modulator_settings("pwm", 20.0)
    {'f_w': 20.0}
    """
    p = valve_params(params)
    v = _value(_kind(kind), value)
    spec = get_kind(kind)
    if gain is not None:
        if not spec.has_gain:
            takes = [k for k in MODULATOR_ORDER if get_kind(k).has_gain]
            raise ValueError(f"{kind}: has no gain; only {' and '.join(takes)} take one")
        gain = checks.positive_array(f"{kind}: gain", gain)
    out: dict[str, Any] = spec.sweep_settings(v, p, gain)
    if all(np.ndim(x) == 0 for x in out.values()):
        out = {k: float(x) for k, x in out.items()}
    return out


def _on_xi_grid(
    kind: str,
    value: npt.ArrayLike,
    params: ValveParams,
    n_xi: int,
    gain: npt.ArrayLike | None,
) -> tuple[dict[str, Any], npt.NDArray[np.float64], dict[str, npt.NDArray[Any]]]:
    """The settings of ``value`` against the grid of ``n_xi`` input fractions.

    Parameters
    ----------
    kind, value, params, gain
        As :func:`modulator_settings`.
    n_xi : int
        Points ``xi_i = i/(n_xi - 1)`` (>= 2).

    Returns
    -------
    settings : dict
        :func:`modulator_settings`.
    xi : numpy.ndarray
        The ``n_xi`` fractions.
    grid : dict of str to numpy.ndarray
        The settings with a new last axis, to broadcast against ``xi``.
    """
    n = checks.integer("n_xi", n_xi, minimum=2)
    settings = modulator_settings(kind, value, params, gain)
    xi = np.linspace(0.0, 1.0, n)
    grid = {k: np.asarray(x)[..., np.newaxis] for k, x in settings.items()}
    return settings, xi, grid


def setting(
    kind: str, value: float, params: ValveParams | None = None, gain: float | None = None
) -> Modulator:
    """The :class:`~spa.model.modulators.Modulator` of one value of the swept parameter.

    Examples
    --------
    >>> setting("iipfm", 0.02).label
    'iipfm-20ms-G1.15'
    """
    return Modulator(kind, modulator_settings(kind, value, params, gain))


def paper_setting(kind: str, params: ValveParams | None = None) -> Modulator:
    """The paper's selected setting (20 Hz, 20 ms; IIPFM with ``G = 1 + t_on/t_l``).

    Examples
    --------
    >>> paper_setting("pwm").label, paper_setting("iipfm").label
    ('pwm-20Hz', 'iipfm-20ms-G1.15')
    """
    return setting(kind, PAPER_SETTING.get(kind, get_kind(kind).reference), params)


def constraint(kind: str, params: ValveParams | None = None) -> str:
    """The optimisation constraint of a modulator as text (paper Section 5.1, Table 2).

    Examples
    --------
    >>> constraint("dsm")
    'period > t_off = 10 ms and period > t_on = 3 ms'
    """
    return get_kind(kind).constraint(valve_params(params))


@fill_doc
def feasible(
    kind: str, value: npt.ArrayLike, params: ValveParams | None = None
) -> npt.NDArray[np.bool_] | np.bool_:
    """Whether a parameter value satisfies the modulator's constraint (Section 5.1).

    Parameters
    ----------
    %(kind)s
    value : array_like of float
        Swept parameter value(s), as in :func:`modulator_settings`.
    %(params)s

    Returns
    -------
    numpy.ndarray of bool, or a NumPy bool for a scalar ``value``
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
    p = valve_params(params)
    v = _value(_kind(kind), value)
    return np.asarray(get_kind(kind).feasible(v, p))[()]


@fill_doc
def linearity_cost(
    kind: str,
    value: npt.ArrayLike,
    params: ValveParams | None = None,
    n_xi: int = 100,
    *,
    gain: npt.ArrayLike | None = None,
    exact: bool = False,
) -> Floats:
    """Linearity cost ``J`` of a modulator setting (Eq. 25), or ``J_exact``.

    Parameters
    ----------
    %(kind)s
    value : array_like of float
        Swept parameter value(s) (:func:`modulator_settings`); an array gives one ``J`` each.
    %(params)s
    n_xi : int, default 100
        Number ``N`` of equally spaced input fractions in [0, 1], both ends included.
    gain : array_like of float, optional
        IPFM/IIPFM gain instead of the default (:func:`modulator_settings`).
    exact : bool, default False
        ``J_exact``: the exact time mean of the periodic steady state in place of the
        averaged ``P_eq`` (:func:`mean_pressure`).

    Returns
    -------
    numpy.ndarray or numpy.float64
        ``J`` (or ``J_exact``) in bar, of the shape of ``value`` (broadcast with ``gain``).
        The constraint is not applied here (see :func:`feasible`, :func:`sweep`).

    Raises
    ------
    ValueError
        For an unknown ``kind``, a non-positive value or ``n_xi < 2``.

    Notes
    -----
    ``J = sum_{i=1..N} |P_eq(xi_i) - k2*xi_i|``, ``xi_i = (i - 1)/(N - 1)``, with ``P_eq``
    the averaged equilibrium of Eq. 5. ``J`` grows with ``N``; compare costs at equal ``N``.

    ``J_exact`` puts the exact time mean over one cycle of the periodic orbit in place of
    ``P_eq`` (:mod:`spa.tuning.exact`). Under fast switching (periods far below ``tau2`` and
    ``c1*sqrt(P)``) the orbit is close to its average and ``J_exact`` to ``J``. The holds
    make the orbit linger at ``P+`` for ``t_off`` and at ``P-`` for ``t_on``, which Eq. 5
    does not see.

    Examples
    --------
    >>> round(float(linearity_cost("iipfm", 0.0195)), 2)
    3.63
    >>> round(float(linearity_cost("iipfm", 0.0195, exact=True)), 2)
    3.62
    """
    p = valve_params(params)
    settings, xi, grid = _on_xi_grid(kind, value, p, n_xi, gain)
    shape = np.broadcast_shapes(*(np.shape(x) for x in settings.values()))
    pressure = mean_pressure(kind, xi, p, grid, exact=exact)
    return np.asarray(deviation_cost(pressure, xi, p.k2), dtype=np.float64).reshape(shape)[()]


def mean_pressure(
    kind: str,
    xi: npt.NDArray[np.float64],
    params: ValveParams,
    settings: Mapping[str, npt.ArrayLike],
    exact: bool = False,
) -> npt.NDArray[np.float64]:
    """Mean pressure against the input fractions: ``P_eq`` of Eq. 5, or the exact cycle mean.

    Parameters
    ----------
    kind : str
        Modulator type (checked by the caller).
    xi : numpy.ndarray
        The ``n`` fractions ``i/(n - 1)``, ``i = 0..n-1``.
    params : ValveParams
        Valve parameters.
    settings : mapping
        Modulator settings (:func:`modulator_settings`), broadcasting against ``xi``.
    exact : bool, default False
        The exact time mean of the periodic steady state
        (:meth:`spa.model.modulators.ModulatorKind.periodic_mean`: Appendix B's ``P+``/``P-``
        for PWM, IPFM and IIPFM, the true first-order pattern for ΔΣM, whose ``xi_i`` is then
        the fraction ``i/(n - 1)`` exactly) instead of the averaged equilibrium.

    Returns
    -------
    numpy.ndarray
        The pressure at each ``xi`` (broadcast with ``settings``), bar.

    Examples
    --------
    >>> xi = np.linspace(0.0, 1.0, 3)
    >>> mean_pressure("pwm", xi, ValveParams(), {"f_w": 20.0}).round(3).tolist()
    [0.0, 0.279, 0.837]
    """
    if exact:
        mean = get_kind(kind).periodic_mean(xi, settings, params, max_denominator=xi.size - 1)
    else:
        mean = equilibrium_pressure(*time_fractions(kind, xi, params, **settings), params)
    return np.asarray(mean, dtype=np.float64)


def deviation_cost(
    pressure: npt.ArrayLike, xi: npt.ArrayLike, k2: float
) -> npt.NDArray[np.float64]:
    """``sum_i |P(xi_i) - k2*xi_i|`` over the last axis: the sum of Eq. 25.

    Examples
    --------
    >>> float(deviation_cost([0.0, 0.5, 0.75], [0.0, 0.5, 1.0], 1.0))
    0.25
    """
    diff = np.asarray(pressure, np.float64) - k2 * np.asarray(xi, np.float64)
    return np.asarray(np.abs(diff).sum(axis=-1), dtype=np.float64)


def sweep_grid(start: float, stop: float, step: float) -> npt.NDArray[np.float64]:
    """Grid ``start, start + step, ...`` up to ``stop`` inclusive (to 1e-9 of a step).

    Raises
    ------
    ValueError
        Unless ``0 < start <= stop`` and ``step > 0``, all finite, and the grid has at most
        :data:`spa._checks.MAX_SWEEP_POINTS` points.

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
    if n > MAX_SWEEP_POINTS:
        raise ValueError(
            f"sweep from {start!r} to {stop!r} by step {step!r} has {n:,} points; at most "
            f"{MAX_SWEEP_POINTS:,} (a coarser step or a shorter range)"
        )
    # Rounding removes the float noise of start + k*step (0.019500000000000003 -> 0.0195).
    return np.round(start + step * np.arange(n), 12)


@fill_doc
def sweep(
    kind: str,
    params: ValveParams | None,
    start: float,
    stop: float,
    step: float,
    n_xi: int = 100,
    cost: CostFunction | None = None,
) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
    """Linearity cost over a grid of the modulator's parameter, with the constraints.

    Parameters
    ----------
    %(kind)s
    params : ValveParams or None
        Valve parameters; nominal when None.
    start, stop, step : float
        Grid of :func:`sweep_grid`, in the parameter's unit (Hz for PWM, s otherwise).
    n_xi : int, default 100
        Points of ``xi`` in the cost.
    cost : callable, optional
        ``(kind, values, params, n_xi) -> J``; :func:`linearity_cost` (Eq. 25) by default,
        ``functools.partial(linearity_cost, exact=True)`` for the exact periodic steady
        state.

    Returns
    -------
    values, J : numpy.ndarray
        Grid values and ``J``; ``J`` is NaN where :func:`feasible` is False.

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
    p = valve_params(params)
    values = sweep_grid(start, stop, step)
    ok = feasible(kind, values, p)
    if not np.any(ok):  # nothing to cost (e.g. LPWM on laws it cannot invert)
        return values, np.full(values.shape, np.nan)
    j = np.asarray((cost or linearity_cost)(kind, values, p, n_xi), dtype=np.float64)
    return values, np.where(ok, j, np.nan)


def optimum(
    kind: str,
    params: ValveParams | None,
    start: float,
    stop: float,
    step: float,
    n_xi: int = 100,
    cost: CostFunction | None = None,
) -> tuple[float, float]:
    """Grid value minimising the linearity cost, and the minimum (Table 2).

    Parameters
    ----------
    kind, params, start, stop, step, n_xi, cost
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
    values, j = sweep(kind, params, start, stop, step, n_xi, cost)
    if not np.any(np.isfinite(j)):
        raise ValueError(
            f"{kind}: no feasible grid point in [{start}, {stop}]: {constraint(kind, params)}"
        )
    i = int(np.nanargmin(j))
    return float(values[i]), float(j[i])


@fill_doc
def check_sweeps(
    sweeps: Mapping[str, Mapping[str, float]], params: ValveParams | None = None
) -> dict[str, Mapping[str, float]]:
    """The grids in table order, checked against the valve's delays.

    Parameters
    ----------
    sweeps : mapping
        ``kind -> {"start", "stop", "step"}`` (``analytic.sweeps``): the paper's four kinds
        and any further registered kind to tune (LPWM).
    %(params)s

    Returns
    -------
    dict
        The grids, in the order PWM, IPFM, IIPFM, ΔΣM, then the further kinds given that
        have a feasible setting on the valve (LPWM has none on laws whose averaged
        equilibrium it cannot invert: it is left out, not refused).

    Raises
    ------
    ValueError
        If a kind is unknown, one of the paper's four or a grid key is missing, or a delay
        is longer than a whole sweep, so that no setting of it is feasible: ``t_on + t_off``
        at least the longest PWM period (``1/start``; every setting is then all dead-zone or
        saturation), ``t_on`` at least the longest IPFM pulse, ``t_off`` at least the
        longest IIPFM separation or ΔΣM period (or ``t_on`` at least the longest period).
        The message names the delay.

    Examples
    --------
    >>> check_sweeps(DEFAULT_SWEEPS, ValveParams(t_off=2.0))  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    ValueError: t_off = 2 s is not shorter than the longest IIPFM t_l of the sweep (0.9995 s): ...
    """
    p = valve_params(params)
    unknown = [k for k in sweeps if k not in MODULATORS]
    if unknown:
        known = list(MODULATOR_ORDER)
        raise ValueError(f"sweeps: unknown modulator(s) {unknown}; expected some of {known}")
    missing = [k for k in _REQUIRED if k not in sweeps]
    if missing:
        raise ValueError(f"sweeps: missing modulator(s) {missing}")
    grids = {k: sweeps[k] for k in MODULATOR_ORDER if k in sweeps}
    limits = []
    for kind, g in grids.items():
        absent = [key for key in ("start", "stop", "step") if key not in g]
        if absent:
            raise ValueError(f"sweeps.{kind}: missing {absent}; expected start, stop, step")
        limits += get_kind(kind).sweep_limits(sweep_grid(g["start"], g["stop"], g["step"]), p)
    # One delay before a sum of delays: the message names the simplest cause.
    for name, delay, limit, what, rule in sorted(limits, key=lambda x: "+" in x[0]):
        if delay >= limit:
            raise ValueError(
                f"{name} = {delay:g} s is not shorter than the longest {what} of the sweep "
                f"({limit:g} s): no setting is feasible ({rule}); check {name} or widen the sweep"
            )
    # a further kind none of whose settings works on this valve is not tuned (LPWM on laws
    # it cannot invert): the paper's four are always, or the valve is refused above
    return {
        k: g
        for k, g in grids.items()
        if k in _REQUIRED or np.any(feasible(k, sweep_grid(g["start"], g["stop"], g["step"]), p))
    }
