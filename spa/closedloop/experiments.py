"""The closed-loop experiments: set-point staircase up and down, a set of steps, a sine.

Each builds its set-point sequence, runs :func:`spa.closedloop.loop.simulate_closed_loop`
and measures it with :mod:`spa.closedloop.metrics`.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt
import pandas as pd

from spa import _checks as checks
from spa.closedloop.controller import PIController
from spa.closedloop.design import MAX_PERIOD, _feedforward
from spa.closedloop.loop import closed_loop_arrays, simulate_closed_loop
from spa.closedloop.metrics import STEP_METRICS, sine_metrics, step_metrics, step_rows
from spa.model.modulators import Modulator, get_kind
from spa.model.modulators.core import settings_arrays
from spa.model.params import ValveParams

__all__ = [
    "LoopUnderTest",
    "Staircase",
    "cycle_period",
    "run_sine",
    "run_staircase",
    "run_steps",
    "sine_reference",
    "spread",
    "staircase_reference",
    "step_periods",
]


def staircase_reference(levels: Sequence[float], hold: float, dt: float) -> np.ndarray:
    """Set-points ``levels`` up, then back down, each held ``hold`` s, sampled every ``dt``.

    Examples
    --------
    >>> staircase_reference([0.1, 0.2, 0.3], 0.002, 0.001).tolist()
    [0.1, 0.1, 0.2, 0.2, 0.3, 0.3, 0.2, 0.2, 0.1, 0.1]
    """
    up = list(levels)
    seq = up + up[-2::-1]
    return np.repeat(np.asarray(seq, dtype=np.float64), round(hold / dt))


def sine_reference(
    offset: float, amplitude: float, frequency: float, duration: float, dt: float
) -> np.ndarray:
    """``offset + amplitude*sin(2*pi*frequency*t)`` for ``duration`` s."""
    t = np.arange(round(duration / dt)) * dt
    return offset + amplitude * np.sin(2.0 * np.pi * frequency * t)


def cycle_period(modulator: Modulator, params: ValveParams, level: float, dt: float) -> float:
    """The modulator's pulse period at the feed-forward of ``level`` (capped), s.

    The window of the cycle-mean pressure (:func:`spa.closedloop.metrics.cycle_mean`).
    """
    xi = np.float64(_feedforward([level], modulator, params)[0])
    settings = settings_arrays(modulator.kind, dict(modulator.settings))
    # the kind's own cycle (ΔΣ: the time between its minority pulses)
    period = float(np.asarray(get_kind(modulator.kind).cycle(xi, settings, params)))
    return float(np.clip(period, 2.0 * dt, MAX_PERIOD))


def step_periods(
    modulator: Modulator, params: ValveParams, levels: Sequence[float], dt: float
) -> dict[float, float]:
    """Each level's cycle-mean window (:func:`cycle_period`), for measuring the steps that go
    to it (:func:`spa.closedloop.metrics.step_metrics`): a modulator whose period changes
    with the level (IPFM, IIPFM, ΔΣ) is averaged over its own cycle at every level.

    Examples
    --------
    >>> from spa.model.params import ValveParams
    >>> w = step_periods(Modulator.from_mapping({"type": "pwm", "f_w": 20.0}),
    ...                  ValveParams(), [0.2, 0.4], 1e-3)
    >>> w
    {0.2: 0.05, 0.4: 0.05}
    """
    return {float(v): cycle_period(modulator, params, float(v), dt) for v in levels}


def _settled(
    modulator: Modulator, controller: PIController, params: ValveParams, level: float
) -> float:
    """The integrator's state that holds ``level`` in the averaged model: ``xi_ff(level)``
    for a PI without feed-forward, 0 with it (the feed-forward supplies it)."""
    if controller.feedforward is not None:
        return 0.0
    return float(_feedforward([level], modulator, params)[0])


@dataclass(frozen=True)
class LoopUnderTest:
    """The loop an experiment runs: a modulator setting, its PI and the valve it closes on.

    Attributes
    ----------
    modulator, controller, params : Modulator, PIController, ValveParams
        The setting, its PI (fixed, scheduled or with feed-forward) and the plant.
    """

    modulator: Modulator
    controller: PIController
    params: ValveParams


@dataclass(frozen=True)
class Staircase:
    """The set-points of an experiment: ``levels`` (bar), each held ``hold`` s, sampled every
    ``dt`` s (the controller step); checked once, here.

    Attributes
    ----------
    levels : tuple of float
        The set-points, bar (at least one; any sequence is stored as a tuple of floats).
    hold : float
        How long each is held, s (> 0).
    dt : float
        The controller step, s (> 0).

    Examples
    --------
    >>> s = Staircase([0.1, 0.2], 0.002, 0.001)
    >>> s.levels, s.n_hold, s.reference.tolist()
    ((0.1, 0.2), 2, [0.1, 0.1, 0.2, 0.2, 0.1, 0.1])
    """

    levels: tuple[float, ...]
    hold: float
    dt: float

    def __post_init__(self) -> None:
        levels = tuple(float(v) for v in self.levels)
        if not levels:
            raise ValueError("levels: need at least one set-point")
        object.__setattr__(self, "levels", levels)
        object.__setattr__(self, "hold", checks.positive("hold", self.hold, "s"))
        object.__setattr__(self, "dt", checks.positive("dt", self.dt, "s"))

    @property
    def n_hold(self) -> int:
        """Controller steps each level is held."""
        return round(self.hold / self.dt)

    @property
    def reference(self) -> np.ndarray:
        """The staircase up and back down (:func:`staircase_reference`), bar."""
        return staircase_reference(self.levels, self.hold, self.dt)

    def periods(self, loop: LoopUnderTest) -> dict[float, float]:
        """Each level's cycle-mean window with ``loop``'s modulator (:func:`step_periods`)."""
        return step_periods(loop.modulator, loop.params, self.levels, self.dt)


def _settled_run(
    loop: LoopUnderTest, reference: np.ndarray, dt: float, level: float
) -> pd.DataFrame:
    """:func:`~spa.closedloop.loop.simulate_closed_loop` over ``reference``, started settled
    at ``level``: the pressure at ``level``, the integrator at :func:`_settled`'s state.

    Parameters
    ----------
    loop : LoopUnderTest
        The loop to run.
    reference : numpy.ndarray
        The set-points, bar.
    dt : float
        The controller step, s.
    level : float
        The set-point the loop starts settled at, bar.

    Returns
    -------
    pandas.DataFrame
        :func:`~spa.closedloop.loop.simulate_closed_loop`'s run.
    """
    return simulate_closed_loop(
        reference,
        dt,
        loop.modulator,
        loop.controller,
        loop.params,
        p0=level,
        integral0=_settled(loop.modulator, loop.controller, loop.params, level),
    )


def run_staircase(loop: LoopUnderTest, stairs: Staircase) -> tuple[pd.DataFrame, pd.DataFrame]:
    """The staircase up and down, settled at the first level (pressure and integrator at
    its averaged equilibrium).

    Parameters
    ----------
    loop : LoopUnderTest
        The loop to run.
    stairs : Staircase
        The set-points and their hold.

    Returns
    -------
    run : pandas.DataFrame
        :func:`~spa.closedloop.loop.simulate_closed_loop`'s run.
    steps : pandas.DataFrame
        :func:`~spa.closedloop.metrics.step_metrics` of its steps, each measured over the
        cycle of its level (:func:`step_periods`).
    """
    r = stairs.reference
    run = _settled_run(loop, r, stairs.dt, stairs.levels[0])
    return run, step_metrics(run, stairs.periods(loop), r_initial=stairs.levels[0])


def run_steps(loop: LoopUnderTest, stairs: Staircase) -> pd.DataFrame:
    """One step from rest (0 bar, integrator at 0) to each of the staircase's levels, held
    its ``hold``: one metrics row per level.

    Each step is measured with the cycle-mean window of its level, as the staircase.
    """
    period = stairs.periods(loop)
    dt = stairs.dt
    t = np.arange(stairs.n_hold, dtype=np.float64) * dt
    rows = []
    for level in stairs.levels:
        r = np.full(stairs.n_hold, level)
        p, _, u = closed_loop_arrays(r, dt, loop.modulator, loop.controller, loop.params, 0.0)
        rows += step_rows(t, r, p, u, period, r_initial=0.0)
    return pd.DataFrame(rows, columns=["r0", "r1", "t0", *STEP_METRICS])


def run_sine(
    loop: LoopUnderTest, sine: Mapping[str, Any], dt: float
) -> tuple[pd.DataFrame, dict[str, float]]:
    """The sine reference (``offset``, ``amplitude``, ``frequency``, ``duration``, ``skip``)."""
    r = sine_reference(sine["offset"], sine["amplitude"], sine["frequency"], sine["duration"], dt)
    run = _settled_run(loop, r, dt, float(r[0]))
    return run, sine_metrics(run, sine["frequency"], skip=float(sine.get("skip", 0.0)))


def sine_within(sine: Mapping[str, Any], lo: float, hi: float) -> dict[str, Any]:
    """The sine reference moved and shrunk, if need be, to stay within ``[lo, hi]`` bar.

    Parameters
    ----------
    sine : mapping
        ``offset`` and ``amplitude`` (bar) and the rest of the sine's settings.
    lo, hi : float
        The set-points the setting holds (its lowest and highest operating level), bar.

    Returns
    -------
    dict
        ``sine`` unchanged when ``offset ± amplitude`` lies within ``[lo, hi]``; else with
        the offset moved into the range and the amplitude cut to what fits around it.

    Examples
    --------
    >>> sine_within({"offset": 0.4, "amplitude": 0.2}, 0.05, 0.25)
    {'offset': 0.15, 'amplitude': 0.1}
    """
    out = dict(sine)
    offset, amplitude = float(out["offset"]), float(out["amplitude"])
    if lo <= offset - amplitude and offset + amplitude <= hi:
        return out
    offset = min(max(offset, lo), hi)
    if not lo < offset < hi:
        offset = 0.5 * (lo + hi)
    out["offset"] = round(offset, 12)
    out["amplitude"] = round(min(amplitude, offset - lo, hi - offset), 12)
    return out


def spread(values: npt.ArrayLike) -> float:
    """Largest minus smallest finite value (NaN when none)."""
    v = np.asarray(values, dtype=np.float64)
    v = v[np.isfinite(v)]
    return float(v.max() - v.min()) if v.size else float("nan")
