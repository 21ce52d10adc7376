"""Which modulator and setting to use for a valve: the constrained minimum of the cost.

Every setting of the four sweeps is a candidate (IIPFM with ``G = 1 + t_on/t_l``, and with
every gain of an optional gain sweep). Each gets its cost (``J`` of Eq. 25 and ``J_exact`` of
the exact periodic steady state) and what a user must live with, as a maximum over the
input fractions of the cost's grid: the valve's switching rate (command edges per second,
``2/(t_h + t_l)``), the chattering (Appendix B's ``P+ - P-``) and the shortest pulse the
controller must produce. The constraints of :class:`TuningOptions` keep the candidates a
user accepts; :func:`recommend` picks the one with the smallest score (``J`` or
``J_exact``), predicts what it will do (:func:`predict`, including a simulated staircase)
and names the constraint that ruled everything out when nothing is left.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt
import pandas as pd

from spa import _checks as checks
from spa._docs import fill_doc
from spa._progress import progress
from spa.model.averaging import pulse_times, time_constant, time_fractions
from spa.model.chattering import pseudo_steady_state
from spa.model.modulators import MODULATOR_ORDER, Modulator, get_kind
from spa.model.params import ValveParams
from spa.model.plant import simulate
from spa.model.thresholds import thresholds
from spa.model.usable import usable
from spa.openloop import staircase_analysis
from spa.synthetic import staircase_input
from spa.tuning.cost import _on_xi_grid, feasible, linearity_cost, modulator_settings, sweep_grid
from spa.tuning.exact import best_first, exact_cost

__all__ = [
    "CONSTRAINTS",
    "DEFAULT_CHATTERING_RELATIVE",
    "UNITS",
    "TuningOptions",
    "candidate_frame",
    "predict",
    "recommend",
    "setting_metrics",
    "violation",
]

#: Chattering limit as a fraction of the valve's ``k2`` (0.050 bar on the paper's valve).
DEFAULT_CHATTERING_RELATIVE = 0.06

#: The user's constraints, in the order they are reported.
CONSTRAINTS: tuple[str, ...] = (
    "setting_range",
    "max_switching_rate",
    "max_chattering",
    "min_pulse_width",
    "max_time_constant",
)

#: Units of the numbers in a recommendation.
UNITS: Mapping[str, str] = {
    "J": "bar",
    "J_exact": "bar",
    "dead_zone": "1 (input fraction)",
    "saturation": "1 (input fraction)",
    "chattering": "bar",
    "switching_rate": "valve command edges per second",
    "min_pulse": "s",
    "tau_max": "s",
    "tau_m": "s",
    "fit": "%",
    "mse": "bar^2",
    "max_dev": "bar",
    "mad": "bar",
}

_SCORES = ("J", "J_exact")


def _limit(name: str, value: Any, unit: str) -> float | None:
    return None if value is None else checks.positive(f"tuning.{name}", value, unit)


@dataclass(frozen=True)
class TuningOptions:
    """What the recommendation minimises and which settings it may choose.

    Parameters
    ----------
    score : {"J", "J_exact"}
        The cost minimised: the paper's averaged ``J`` (Eq. 25) or ``J_exact``.
    max_switching_rate : float or None
        Largest switching rate allowed, valve command edges per second, max over ``xi``
        (valve life); None: no limit.
    max_chattering : float or None
        Largest chattering allowed, bar (Appendix B's ``P+ - P-``, max over ``xi``). None
        (the default): ``max_chattering_relative`` of the valve's ``k2`` decides.
    max_chattering_relative : float or None
        Largest chattering allowed as a fraction of the identified ``k2`` when
        ``max_chattering`` is None: 0.06 by default (0.050 bar on the paper's 0.837 bar
        valve, 0.24 bar on a 4 bar one). None with ``max_chattering`` None: no limit.
    min_pulse_width : float or None
        Shortest pulse the controller can produce, s. A setting needs every pulse that moves
        the pressure (high longer than ``t_on``, low longer than ``t_off``; ΔΣM: its clock
        period) to be at least this long.
    max_time_constant : float or None
        Slowest response allowed, as a multiple of the valve's own ``tau2``: a setting whose
        equivalent time constant (Eq. 9) exceeds ``max_time_constant * tau2`` at some ``xi``
        is left out (response speed; 3 by default). None: no limit.
    max_fit_shortfall : float or None
        Percentage points: the recommendation never goes to a setting whose predicted
        staircase FIT is more than this below the best predicted FIT among the candidates
        of every kind (10 by default); such a setting is passed over, and says why.
        None: FIT does not decide.
    ranges : mapping
        ``kind -> (lo, hi)``: the settings a user accepts, in the sweep's unit (Hz for PWM,
        s otherwise); kinds not listed keep their whole sweep.
    gain_sweep : mapping or None
        ``{start, stop, step}``: IIPFM gains tried at every ``t_l`` besides
        ``1 + t_on/t_l``.
    staircase : mapping
        ``step``, ``hold`` (s) and ``dt`` (controller step, s) of the staircase simulated
        for the predicted ``fit``, ``mse``, ``max_dev``, ``mad`` (the paper's: 0.1, 5 s).
        A valve slower than the paper's gets holds of at least ``5 * tau2``
        (:func:`staircase_hold`), so that a level can settle.

    Examples
    --------
    >>> TuningOptions.from_mapping({"max_chattering": None, "score": "J_exact"}).score
    'J_exact'
    """

    score: str = "J"
    max_switching_rate: float | None = 100.0
    max_chattering: float | None = None
    max_chattering_relative: float | None = DEFAULT_CHATTERING_RELATIVE
    min_pulse_width: float | None = 0.001
    max_time_constant: float | None = 3.0
    max_fit_shortfall: float | None = 10.0
    ranges: Mapping[str, tuple[float, float]] = field(default_factory=dict)
    gain_sweep: Mapping[str, float] | None = None
    staircase: Mapping[str, float] = field(
        default_factory=lambda: {"step": 0.1, "hold": 5.0, "dt": 0.001}
    )

    def __post_init__(self) -> None:
        if self.score not in _SCORES:
            raise ValueError(f"tuning.score must be one of {list(_SCORES)}, got {self.score!r}")
        object.__setattr__(
            self,
            "max_switching_rate",
            _limit("max_switching_rate", self.max_switching_rate, "edges/s"),
        )
        object.__setattr__(
            self, "max_chattering", _limit("max_chattering", self.max_chattering, "bar")
        )
        object.__setattr__(
            self,
            "max_chattering_relative",
            _limit("max_chattering_relative", self.max_chattering_relative, "of k2"),
        )
        object.__setattr__(
            self, "min_pulse_width", _limit("min_pulse_width", self.min_pulse_width, "s")
        )
        object.__setattr__(
            self, "max_time_constant", _limit("max_time_constant", self.max_time_constant, "tau2")
        )
        if self.max_fit_shortfall is not None:
            object.__setattr__(
                self,
                "max_fit_shortfall",
                checks.nonnegative("tuning.max_fit_shortfall", self.max_fit_shortfall, "%"),
            )
        ranges = {}
        for kind, pair in dict(self.ranges).items():
            if kind not in MODULATOR_ORDER:
                raise ValueError(f"tuning.ranges: unknown modulator {kind!r}")
            if not isinstance(pair, list | tuple) or len(pair) != 2:
                raise ValueError(f"tuning.ranges.{kind} must be [lo, hi], got {pair!r}")
            lo = checks.positive(f"tuning.ranges.{kind}[0]", pair[0])
            hi = checks.positive(f"tuning.ranges.{kind}[1]", pair[1])
            if hi < lo:
                raise ValueError(f"tuning.ranges.{kind} must have lo <= hi, got {list(pair)}")
            ranges[kind] = (lo, hi)
        object.__setattr__(self, "ranges", ranges)
        stair = {"step": 0.1, "hold": 5.0, "dt": 0.001, **dict(self.staircase)}
        object.__setattr__(
            self,
            "staircase",
            {
                "step": checks.fraction("tuning.staircase.step", stair["step"], low_open=True),
                "hold": checks.positive("tuning.staircase.hold", stair["hold"], "s"),
                "dt": checks.positive("tuning.staircase.dt", stair["dt"], "s"),
            },
        )

    def chattering_limit(self, params: ValveParams) -> float | None:
        """The chattering limit on this valve, bar: ``max_chattering`` when set, else
        ``max_chattering_relative * k2``; None: no limit.

        Examples
        --------
        >>> round(TuningOptions().chattering_limit(ValveParams()), 4)  # the paper's valve
        0.0502
        >>> TuningOptions().chattering_limit(ValveParams(k2=4.0))
        0.24
        >>> TuningOptions(max_chattering=0.03).chattering_limit(ValveParams(k2=4.0))
        0.03
        """
        if self.max_chattering is not None:
            return self.max_chattering
        if self.max_chattering_relative is None:
            return None
        return self.max_chattering_relative * float(params.k2)

    def limits(self, params: ValveParams) -> dict[str, float | None]:
        """Each constraint of :data:`CONSTRAINTS` but the setting range as a number on this
        valve, in the unit of the metric it bounds (``max_time_constant`` in s)."""
        return {
            "max_switching_rate": self.max_switching_rate,
            "max_chattering": self.chattering_limit(params),
            "min_pulse_width": self.min_pulse_width,
            "max_time_constant": None
            if self.max_time_constant is None
            else self.max_time_constant * float(params.tau2),
        }

    @classmethod
    def from_mapping(cls, cfg: Mapping[str, Any] | None) -> TuningOptions:
        """Options from the config's ``tuning:`` section (missing keys take the defaults)."""
        cfg = dict(cfg or {})
        known = {f for f in cls.__dataclass_fields__}
        unknown = sorted(set(cfg) - known)
        if unknown:
            raise ValueError(f"tuning: unknown key(s) {unknown}; allowed: {sorted(known)}")
        return cls(**cfg)

    def to_mapping(self) -> dict[str, Any]:
        """Plain, YAML-ready form."""
        return {
            "score": self.score,
            "max_switching_rate": self.max_switching_rate,
            "max_chattering": self.max_chattering,
            "max_chattering_relative": self.max_chattering_relative,
            "min_pulse_width": self.min_pulse_width,
            "max_time_constant": self.max_time_constant,
            "max_fit_shortfall": self.max_fit_shortfall,
            "ranges": {k: list(v) for k, v in self.ranges.items()},
            "gain_sweep": None if self.gain_sweep is None else dict(self.gain_sweep),
            "staircase": dict(self.staircase),
        }


@fill_doc
def setting_metrics(
    kind: str,
    value: npt.ArrayLike,
    params: ValveParams,
    n_xi: int = 100,
    gain: npt.ArrayLike | None = None,
) -> dict[str, npt.NDArray[np.float64]]:
    """Switching rate, chattering and shortest pulse of settings, each a maximum over ``xi``.

    Parameters
    ----------
    %(cost_args)s

    Returns
    -------
    dict
        Arrays of the shape of ``value``: ``switching_rate`` (largest ``2/(t_h + t_l)`` over
        the grid of ``xi``, edges/s), ``chattering`` (largest ``P+ - P-`` of Appendix B, bar)
        and ``min_pulse`` (shortest pulse that moves the pressure, s; ΔΣM: the clock period;
        ``inf`` when nothing pulses) and ``tau_max`` (largest equivalent time constant of
        Eq. 9 over the ``xi`` where it is defined, s; NaN where it is defined nowhere). Where
        the command is constant there is no pulse train: rate and chattering 0. Durations
        are those of :func:`spa.model.averaging.pulse_times`, as in
        :func:`spa.openloop.predicted_levels`.

    Examples
    --------
    >>> m = setting_metrics("pwm", 20.0, ValveParams())
    >>> float(m["switching_rate"])
    40.0
    """
    _, xi, grid = _on_xi_grid(kind, value, params, n_xi, gain)
    t_h, t_l = (np.asarray(a, dtype=np.float64) for a in pulse_times(kind, xi, params, **grid))
    pulsing = np.isfinite(t_h) & np.isfinite(t_l) & (t_h > 0.0) & (t_l > 0.0)
    th = np.where(pulsing, t_h, 1.0)
    tl = np.where(pulsing, t_l, 1.0)
    hi, lo = (np.asarray(a) for a in pseudo_steady_state(th, tl, params))
    # A pulse within rounding of its hold (IIPFM's t_on-long high at xi = 0 with the gain of
    # Eq. 17) does not move the pressure.
    moving = np.minimum(
        np.where(pulsing & (th > params.t_on * (1 + 1e-9)), th, np.inf),
        np.where(pulsing & (tl > params.t_off * (1 + 1e-9)), tl, np.inf),
    ).min(axis=-1)
    moving = get_kind(kind).min_pulse(moving, grid)
    with np.errstate(all="ignore"):
        tau = np.asarray(
            time_constant(*time_fractions(kind, xi, params, **grid), params), dtype=np.float64
        )
    tau = np.where(np.isfinite(tau), tau, -np.inf).max(axis=-1)
    return {
        "switching_rate": np.where(pulsing, 2.0 / (th + tl), 0.0).max(axis=-1),
        "chattering": np.where(pulsing, hi - lo, 0.0).max(axis=-1),
        "min_pulse": moving,
        "tau_max": np.where(np.isfinite(tau), tau, np.nan),
    }


def candidate_frame(
    grids: Mapping[str, Mapping[str, float]],
    params: ValveParams,
    n_xi: int = 100,
    options: TuningOptions | None = None,
    data: pd.DataFrame | None = None,
) -> pd.DataFrame:
    """Every setting of the sweeps with its costs, metrics and constraint checks.

    Parameters
    ----------
    grids : mapping
        ``kind -> {start, stop, step}`` (:func:`spa.tuning.cost.check_sweeps`).
    params : ValveParams
        Valve parameters.
    n_xi : int, default 100
        Points of ``xi`` in the costs and metrics.
    options : TuningOptions, optional
        Constraints and gain sweep; defaults when omitted.
    data : pandas.DataFrame, optional
        ``sweep_frame(grids, params, n_xi, exact=True)`` when already computed: its ``J``
        and ``J_exact`` are used for the settings with the default gain.

    Returns
    -------
    pandas.DataFrame
        One row per candidate: ``modulator``, ``value`` (Hz for PWM, s otherwise), ``gain``
        (NaN for PWM, ΔΣM), ``J``, ``J_exact``, ``switching_rate``, ``chattering``,
        ``min_pulse`` (:func:`setting_metrics`), one boolean column per entry of
        :data:`CONSTRAINTS` (True: the candidate meets it) and ``feasible`` (all of them).
        Settings outside Section 5's constraints (:func:`spa.tuning.cost.feasible`) or with
        no input range that moves the pressure (:func:`spa.model.usable.usable`) are left
        out.
    """
    opts = options or TuningOptions()
    parts = []
    for kind, g in progress(grids.items(), "sweeps", total=len(grids), unit="modulator"):
        values = sweep_grid(g["start"], g["stop"], g["step"])
        keep = np.asarray(feasible(kind, values, params), dtype=bool)
        keep &= usable(kind, values, params)
        values = values[keep]
        sets: list[tuple[npt.NDArray[np.float64], npt.NDArray[np.float64] | None]] = [
            (values, None)
        ]
        if get_kind(kind).gain_swept and opts.gain_sweep is not None:
            gains = sweep_grid(**opts.gain_sweep)
            sets.append((np.repeat(values, gains.size), np.tile(gains, values.size)))
        for v, gain in sets:
            settings = modulator_settings(kind, v, params, gain)
            if gain is None and data is not None:
                known = data[data["modulator"] == kind]
                if len(known) != keep.size:
                    raise ValueError(f"data: {kind} rows do not match the grid {dict(g)}")
                costs = {
                    "J": known["J"].to_numpy()[keep],
                    "J_exact": known["J_exact"].to_numpy()[keep],
                }
            else:
                costs = {
                    "J": linearity_cost(kind, v, params, n_xi, gain=gain),
                    "J_exact": exact_cost(kind, v, params, n_xi, gain=gain),
                }
            frame = pd.DataFrame(
                {
                    "modulator": kind,
                    "value": v,
                    "gain": settings.get("gain", np.full(v.shape, np.nan)),
                    **costs,
                    **setting_metrics(kind, v, params, n_xi, gain),
                }
            )
            lo, hi = opts.ranges.get(kind, (-np.inf, np.inf))
            frame["setting_range"] = (v >= lo * (1 - 1e-12)) & (v <= hi * (1 + 1e-12))
            parts.append(frame)
    out = pd.concat(parts, ignore_index=True)
    on_valve = opts.limits(params)
    for name, (column, sign) in _METRIC.items():
        limit = on_valve[name]
        if limit is None:
            out[name] = True
        elif sign > 0:
            out[name] = out[column] <= limit
        else:
            out[name] = out[column] >= limit * (1 - 1e-9)
    out["feasible"] = out[list(CONSTRAINTS)].all(axis=1)
    out["violation"] = violation(out, opts, params)
    return out


#: The metric each numeric constraint bounds, and its sense (1: at most, -1: at least).
_METRIC: Mapping[str, tuple[str, int]] = {
    "max_switching_rate": ("switching_rate", 1),
    "max_chattering": ("chattering", 1),
    "min_pulse_width": ("min_pulse", -1),
    "max_time_constant": ("tau_max", 1),
}


def _excess(value: np.ndarray, limit: float, sign: int) -> np.ndarray:
    """How far ``value`` is beyond ``limit``, relative to it (0 where it meets it)."""
    with np.errstate(invalid="ignore", divide="ignore"):
        over = sign * (value - limit) / limit
    return np.where(np.isfinite(over), np.maximum(over, 0.0), np.inf)


def violation(
    candidates: pd.DataFrame, options: TuningOptions, params: ValveParams
) -> npt.NDArray[np.float64]:
    """How far each candidate is from meeting the user's constraints: 0 when it meets them.

    The sum over the violated constraints of the excess over the limit relative to the
    limit: ``(metric - limit)/limit`` for an upper limit (switching rate, chattering, time
    constant), ``(limit - metric)/limit`` for the shortest pulse, and the distance outside
    ``tuning.ranges`` relative to the bound it passes. A candidate whose metric is not
    finite where a limit applies violates it without bound (``inf``).

    Examples
    --------
    >>> frame = pd.DataFrame({"modulator": ["pwm", "pwm"], "value": [20.0, 60.0],
    ...     "switching_rate": [40.0, 120.0], "chattering": [0.06, 0.02],
    ...     "min_pulse": [0.01, 0.004], "tau_max": [1.0, 1.0]})
    >>> violation(frame, TuningOptions(max_chattering=0.05), ValveParams()).round(3).tolist()
    [0.2, 0.2]
    """
    total = np.zeros(len(candidates))
    for name, limit in options.limits(params).items():
        if limit is None:
            continue
        column, sign = _METRIC[name]
        total += _excess(candidates[column].to_numpy(dtype=float), limit, sign)
    kinds = candidates["modulator"].to_numpy()
    values = candidates["value"].to_numpy(dtype=float)
    for kind, (lo, hi) in options.ranges.items():
        mine = kinds == kind
        total[mine] += _excess(values[mine], hi, 1) + _excess(values[mine], lo, -1)
    return total


def _violated(row: pd.Series, options: TuningOptions, params: ValveParams) -> dict[str, Any]:
    """Each constraint ``row`` breaks: the metric, the limit and the relative excess."""
    out: dict[str, Any] = {}
    for name, limit in options.limits(params).items():
        column, sign = _METRIC[name]
        if limit is None or bool(row[name]):
            continue
        value = float(row[column])
        excess = float(_excess(np.array([value]), limit, sign)[0])
        out[name] = {"value": value, "limit": float(limit), "excess": excess}
    if not bool(row["setting_range"]):
        lo, hi = options.ranges[row["modulator"]]
        value = float(row["value"])
        excess = float(_excess(np.array([value]), hi, 1)[0] + _excess(np.array([value]), lo, -1)[0])
        out["setting_range"] = {"value": value, "limit": [lo, hi], "excess": excess}
    return out


def _excluded_by(rows: pd.DataFrame) -> list[str]:
    """The constraint(s) that no row meets, else the smallest set no row meets together."""
    single = [c for c in CONSTRAINTS if not rows[c].any()]
    if single:
        return single
    for r in range(2, len(CONSTRAINTS) + 1):
        for combo in itertools.combinations(CONSTRAINTS, r):
            if not rows[list(combo)].all(axis=1).any():
                return list(combo)
    return []


def staircase_hold(options: TuningOptions, params: ValveParams) -> float:
    """Hold of each level of the predicted staircase: the option's, at least ``5 * tau2``.

    Examples
    --------
    >>> staircase_hold(TuningOptions(), ValveParams(tau2=2.5))
    12.5
    >>> staircase_hold(TuningOptions(), ValveParams())
    5.0
    """
    return max(float(options.staircase["hold"]), 5.0 * params.tau2)


def _staircase(mod: Modulator, params: ValveParams, options: TuningOptions, **analysis: Any):
    """Fit, MSE, max_dev and MAD of a noise-free simulated staircase (Table 3's metrics)."""
    step, dt = (options.staircase[k] for k in ("step", "dt"))
    hold = staircase_hold(options, params)
    levels = math.floor(1.0 / step + 1e-9) + 1
    t = np.arange(round(levels * hold / dt)) * dt
    xi = staircase_input(t, step, hold)
    u = mod.bind(params).modulate(xi, dt)
    run = pd.DataFrame({"t": t, "p": simulate(u, dt, params), "valve": u, "u": xi})
    _, _, summary = staircase_analysis(run, mod.to_mapping(), params, **analysis)
    out = {k: float(summary[k]) for k in ("fit", "mse", "max_dev", "mad")}
    if hold != float(options.staircase["hold"]):
        out["staircase_hold"] = hold
    return out


def predict(
    mod: Modulator,
    params: ValveParams,
    n_xi: int = 100,
    options: TuningOptions | None = None,
    linearity: Mapping[str, float] | None = None,
) -> dict[str, Any]:
    """What a setting will do on the valve: the ``predicted:`` block of a recommendation.

    Parameters
    ----------
    mod : Modulator
        The setting.
    params : ValveParams
        Valve parameters.
    n_xi : int, default 100
        Points of ``xi`` for the maxima and the ``tau_m`` range.
    options : TuningOptions, optional
        Its ``staircase`` is simulated; defaults when omitted.
    linearity : mapping, optional
        Keyword arguments of :func:`spa.openloop.staircase_analysis` (``settle``, ...).

    Returns
    -------
    dict
        ``dead_zone``, ``saturation`` (Table 1), ``chattering``, ``switching_rate``,
        ``min_pulse`` (:func:`setting_metrics`), ``tau_m`` (``{min, max}`` of Eq. 9 over the
        ``xi`` where it is defined, s), and ``fit``, ``mse``, ``max_dev``, ``mad`` of the paper's
        staircase simulated with the exact plant, noise-free, analysed like a measured one
        (with ``staircase_hold``, s, where :func:`staircase_hold` lengthened its levels).
    """
    opts = options or TuningOptions()
    settings = dict(mod.settings)
    dead, sat = (float(v) for v in thresholds(mod.kind, params, **settings))
    gain = settings.get("gain")
    metrics = setting_metrics(mod.kind, mod.value, params, n_xi, gain)
    xi = np.linspace(0.0, 1.0, n_xi)
    tau = np.asarray(time_constant(*time_fractions(mod.kind, xi, params, **settings), params))
    tau = tau[np.isfinite(tau)]
    return {
        "dead_zone": dead,
        "saturation": sat,
        "chattering": float(metrics["chattering"]),
        "switching_rate": float(metrics["switching_rate"]),
        "min_pulse": float(metrics["min_pulse"]),
        "tau_m": {
            "min": float(tau.min()) if tau.size else None,
            "max": float(tau.max()) if tau.size else None,
        },
        **_staircase(mod, params, opts, **dict(linearity or {})),
    }


def _edge(row: pd.Series, candidates: pd.DataFrame) -> dict[str, Any] | None:
    """Whether a setting sits at an edge of its kind's feasible range, and what bounds it.

    The neighbours of ``row`` are the candidates of its kind with the same gain rule, in
    the order of the swept value. At an edge the next value beyond either is not a candidate
    at all (the end of the grid, or of the settings that work on the valve) or breaks the
    constraints it names.
    """
    same = candidates[candidates["modulator"] == row["modulator"]]
    same = same[same["gain"].isna()] if np.isnan(row["gain"]) else same[same["gain"] == row["gain"]]
    same = same.sort_values("value", kind="stable")
    values = same["value"].to_numpy()
    ok = same["feasible"].to_numpy()
    i = int(np.searchsorted(values, row["value"]))
    for step, side in ((-1, "lowest"), (1, "highest")):
        j = i + step
        if 0 <= j < len(values) and ok[j]:
            continue
        if j < 0 or j >= len(values):
            bound = ["end of the sweep or of the settings that work on this valve"]
        else:
            bound = [c for c in CONSTRAINTS if not bool(same[c].iloc[j])]
        return {"side": side, "bounded_by": bound}
    return None


def _entry(
    row: pd.Series,
    params: ValveParams,
    n_xi: int,
    options: TuningOptions,
    linearity: Mapping[str, float] | None,
    candidates: pd.DataFrame | None = None,
) -> dict[str, Any]:
    gain = None if np.isnan(row["gain"]) else float(row["gain"])
    mod = Modulator(
        row["modulator"], modulator_settings(row["modulator"], row["value"], params, gain)
    ).bind(params)
    entry = {
        "modulator": mod.kind,
        "label": mod.label,
        "description": mod.description,
        "setting": mod.to_mapping(),
        "J": float(row["J"]),
        "J_exact": float(row["J_exact"]),
        "predicted": predict(mod, params, n_xi, options, linearity),
    }
    edge = None if candidates is None else _edge(row, candidates)
    entry["at_feasible_edge"] = edge
    return entry


def _pass_over(entries: list[dict[str, Any]], shortfall: float | None) -> list[dict[str, Any]]:
    """Entries (best score first), those far below the best predicted FIT passed over.

    The first entry whose predicted staircase FIT is within ``shortfall`` percentage points
    of the best predicted FIT of the entries comes first; the entries of better score before
    it get ``passed_over`` (why) and follow it; the order is otherwise kept.
    """
    if shortfall is None or not entries:
        return entries
    fits = [e["predicted"]["fit"] for e in entries]
    finite = [f for f in fits if math.isfinite(f)]
    if not finite:
        return entries
    best = max(finite)
    leader = entries[fits.index(best)]["label"]
    first = next(i for i, f in enumerate(fits) if math.isfinite(f) and f >= best - shortfall)
    for entry, fit in zip(entries[:first], fits[:first], strict=True):
        entry["passed_over"] = (
            f"predicted staircase FIT {fit:.1f} % is more than {shortfall:g} points "
            f"below {leader}'s {best:.1f} % (tuning.max_fit_shortfall)"
        )
    return [entries[first], *entries[:first], *entries[first + 1 :]]


def recommend(
    candidates: pd.DataFrame,
    params: ValveParams,
    n_xi: int = 100,
    options: TuningOptions | None = None,
    linearity: Mapping[str, float] | None = None,
) -> dict[str, Any]:
    """The recommended setting, the runner-up of each other modulator, or why there is none.

    Parameters
    ----------
    candidates : pandas.DataFrame
        :func:`candidate_frame`.
    params : ValveParams
        Valve parameters.
    n_xi : int, default 100
        As :func:`candidate_frame`.
    options : TuningOptions, optional
        Score and constraints; defaults when omitted.
    linearity : mapping, optional
        Passed to :func:`predict`.

    Returns
    -------
    dict
        YAML-ready: ``score``, ``constraints`` (the options, and per constraint how many
        candidates it excludes, and ``max_chattering_bar``, the chattering limit on this
        valve), ``n_candidates``, ``n_feasible``, ``recommended`` (None only when no
        candidate works on the valve; else ``modulator``, ``label``, ``description``,
        ``setting`` in the form of a ``dataset.yaml`` modulator, ``J``, ``J_exact``,
        ``predicted``, ``at_feasible_edge``; when no candidate meets every constraint, the
        least-violating one, with ``violates``, constraint -> ``{value, limit, excess}``,
        and ``violation``, :func:`violation`), ``runners_up`` (the best feasible setting of
        every other modulator, or the constraints that exclude all of its settings),
        ``excluded_by`` (the constraints that together exclude every setting; empty when one
        is feasible) and ``units``.

    Notes
    -----
    The rule: among the settings meeting every constraint (:data:`CONSTRAINTS`, response
    speed included), each modulator's best by ``score`` (ties within
    :data:`spa.tuning.exact.COST_TIE` go to the other cost); of these, the best by ``score``
    whose predicted staircase FIT is within ``max_fit_shortfall`` points of the best
    predicted FIT. Better-scored ones further below are passed over (``passed_over`` says
    why) and follow it among the runners-up. ``at_feasible_edge`` flags a setting that is
    the lowest or highest of its kind's feasible settings, with what bounds it there.
    When no setting meets every constraint, the one of smallest :func:`violation` (ties by
    ``score``) is recommended: usable on the valve, and as near the user's limits as any.
    """
    opts = options or TuningOptions()
    feasible_rows = candidates[candidates["feasible"]]
    best = best_first(feasible_rows, opts.score).drop_duplicates("modulator")
    entries = [_entry(row, params, n_xi, opts, linearity, candidates) for _, row in best.iterrows()]
    entries = _pass_over(entries, opts.max_fit_shortfall)
    if not entries and not candidates.empty:  # the least-violating usable setting
        scores = candidates["violation"] if "violation" in candidates else None
        scores = violation(candidates, opts, params) if scores is None else scores
        finite = candidates[np.isfinite(scores.to_numpy(dtype=float))]
        if not finite.empty:
            least = float(scores[finite.index].min())
            tied = finite[scores[finite.index] <= least * (1 + 1e-9) + 1e-15]
            row = best_first(tied, opts.score).iloc[0]
            entry = _entry(row, params, n_xi, opts, linearity)
            entry["violates"] = _violated(row, opts, params)
            entry["violation"] = least
            entries = [entry]
    runners_up: list[dict[str, Any]] = entries[1:]
    for kind in MODULATOR_ORDER:
        rows = candidates[candidates["modulator"] == kind]
        if not rows.empty and kind not in set(best["modulator"]):
            runners_up.append({"modulator": kind, "excluded_by": _excluded_by(rows)})
    excludes = {c: int((~candidates[c]).sum()) for c in CONSTRAINTS}
    chattering = opts.chattering_limit(params)
    return {
        "score": opts.score,
        "constraints": {
            **opts.to_mapping(),
            "max_chattering_bar": None if chattering is None else float(chattering),
            "excludes": excludes,
        },
        "n_candidates": len(candidates),
        "n_feasible": len(feasible_rows),
        "recommended": entries[0] if entries else None,
        "runners_up": runners_up,
        "excluded_by": _excluded_by(candidates) if feasible_rows.empty and len(candidates) else [],
        "units": dict(UNITS),
    }
