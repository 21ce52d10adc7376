"""What a user accepts of a setting: the tuning's options, its constraints and how far a
setting is from meeting them.

:class:`TuningOptions` holds the score minimised and the user's limits (:data:`CONSTRAINTS`):
the settings accepted, the valve's switching rate, the chattering, the shortest pulse and the
slowest response. :func:`violation` measures how far each candidate of
:func:`spa.tuning.candidates.candidate_frame` is from meeting them, so that when no setting
meets every constraint the recommendation (:func:`spa.tuning.recommend.recommend`) can fall back
on the least-violating one and say which limits it breaks, and by how much.
"""

from __future__ import annotations

import itertools
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt
import pandas as pd

from spa import _checks as checks
from spa.model.modulators import MODULATOR_ORDER
from spa.model.params import ValveParams
from spa.tuning.exact import best_first

__all__ = [
    "CONSTRAINTS",
    "DEFAULT_CHATTERING_RELATIVE",
    "TuningOptions",
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

_SCORES = ("J", "J_exact")


#: The optional positive limits of :class:`TuningOptions`, in check order, with their units.
_LIMIT_UNITS = {
    "max_switching_rate": "edges/s",
    "max_chattering": "bar",
    "max_chattering_relative": "of k2",
    "min_pulse_width": "s",
    "max_time_constant": "tau2",
}


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
        (:func:`~spa.tuning.recommend.staircase_hold`), so that a level can settle.

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
        for name, unit in _LIMIT_UNITS.items():
            object.__setattr__(self, name, _limit(name, getattr(self, name), unit))
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


def _least_violating(
    candidates: pd.DataFrame, options: TuningOptions, params: ValveParams
) -> tuple[pd.Series, float] | None:
    """The candidate nearest to meeting the constraints, and its :func:`violation`.

    The smallest finite violation (the ``violation`` column of ``candidates`` when it has
    one), ties within rounding broken by ``options.score``; None when no violation is finite.
    """
    scores = candidates["violation"] if "violation" in candidates else None
    scores = violation(candidates, options, params) if scores is None else scores
    finite = candidates[np.isfinite(scores.to_numpy(dtype=float))]
    if finite.empty:
        return None
    least = float(scores[finite.index].min())
    tied = finite[scores[finite.index] <= least * (1 + 1e-9) + 1e-15]
    return best_first(tied, options.score).iloc[0], least
