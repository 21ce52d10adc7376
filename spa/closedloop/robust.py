"""The designed controller over the identification's 95 % box, and the robust ``tau_c``.

The PI is designed at the point estimate (:func:`spa.closedloop.design.design_pi`); the
plant it meets may be any valve of the box. :func:`box_worst_case` runs the set-point
staircase with the plant at the estimate and at every corner of the box
(:func:`spa.identification.identified.corners`: ``2**k`` valves for ``k`` parameters with an
interval) and keeps the worst value of each metric: the largest rise time, overshoot,
``|steady-state error|`` and ripple over the steps and the valves. :func:`lengthen_tau_c`
lengthens SIMC's closed-loop time constant by a factor (1.5) while the worst-case overshoot
exceeds the limit (:data:`spa.closedloop.choice.MAX_OVERSHOOT`, 10 %), up to a bound; the
first ``tau_c`` that holds is the robust one, and none may hold (docs/model.md section 8).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from spa import _checks as checks
from spa.closedloop.controller import PIController
from spa.closedloop.design import design_pi
from spa.closedloop.experiments import _settled, staircase_reference, step_periods
from spa.closedloop.loop import closed_loop_many
from spa.closedloop.metrics import step_rows
from spa.identification.identified import corners
from spa.model.modulators import Modulator
from spa.model.params import ValveParams

__all__ = [
    "WORST_METRICS",
    "RobustDesign",
    "box_worst_case",
    "lengthen_tau_c",
    "robust_design",
    "worst_of_steps",
]

#: The metrics kept at their worst over the box, and how: largest value (``abs``: of the
#: magnitude).
WORST_METRICS: dict[str, bool] = {
    "rise_time": False,
    "overshoot": False,
    "settling_time": False,
    "end_error": False,
    "steady_state_error": True,
    "ripple_pp": False,
    "ripple_rms": False,
}

#: A step ends settled within this share of its size, % (``end_error``).
SETTLED = 2.0

#: Factor by which :func:`robust_tau_c` lengthens ``tau_c`` per try, and the longest it tries
#: as a multiple of the nominal one.
FACTOR = 1.5
MAX_FACTOR = 8.0


def worst_of_steps(frames: Sequence[Mapping[str, Sequence[float]]]) -> dict[str, float]:
    """The worst value of each of :data:`WORST_METRICS` over several step-metric tables.

    Parameters
    ----------
    frames : sequence of mappings
        Step metrics (:func:`spa.closedloop.metrics.step_metrics`), one per valve.

    Returns
    -------
    dict
        Metric -> largest value (of ``|value|`` for the steady-state error) over every step
        of every frame; NaN where no step has a value, and for the rise and settling times as
        soon as one step never rises or settles (a valve that does not reach or hold a
        set-point is the worst case).

    Examples
    --------
    >>> worst_of_steps([{"rise_time": [0.2, 0.3], "overshoot": [1.0, 4.0],
    ...   "settling_time": [0.5, 0.6], "end_error": [1.0, 0.5],
    ...   "steady_state_error": [-0.01, 0.002],
    ...   "ripple_pp": [0.0, 0.0],
    ...   "ripple_rms": [0.0, 0.0]}])["steady_state_error"]
    0.01
    """
    out: dict[str, float] = {}
    for metric, magnitude in WORST_METRICS.items():
        values = np.concatenate([np.asarray(f[metric], dtype=np.float64) for f in frames])
        if magnitude:
            values = np.abs(values)
        if metric in ("rise_time", "settling_time") and np.isnan(values).any():
            out[metric] = math.nan
            continue
        finite = values[np.isfinite(values)]
        out[metric] = float(finite.max()) if finite.size else math.nan
    return out


def box_worst_case(
    modulator: Modulator,
    controller: PIController,
    params: ValveParams,
    intervals: Mapping[str, tuple[float, float]] | None,
    levels: Sequence[float],
    hold: float,
    dt: float,
    gains: Sequence[float] = (1.0,),
) -> tuple[dict[str, float], int]:
    """The staircase's worst metrics with the plant at the estimate and the box's corners.

    Parameters
    ----------
    modulator : Modulator
        The setting.
    controller : PIController
        Designed at ``params``.
    params : ValveParams
        The point estimate.
    intervals : mapping or None
        ``name -> (lo, hi)``, the 95 % intervals
        (:func:`~spa.identification.identified.read_intervals`).
    levels, hold, dt : as :class:`spa.closedloop.experiments.Staircase`
    gains : sequence of float, default (1.0,)
        Factors on the loop gain (the measured model error's ``gain``,
        :func:`spa.closedloop.model_error.error_intervals`): the estimate is also run with
        the controller's gains times each factor (:meth:`PIController.scaled`). The factor
        is the measured plant's slope against the estimate's, whatever its cause (a
        parameter's error included), so it scales the estimate's loop, not every corner's:
        the corners are the parameters' own uncertainty, at the model's gain.

    Returns
    -------
    worst : dict
        :func:`worst_of_steps` over the estimate and every corner, at every gain factor.
    n_corners : int
        Corners evaluated (0 without intervals: the estimate alone).

    Notes
    -----
    Every valve's run starts settled at the first level on that valve (pressure and
    integrator at its averaged equilibrium, as
    :func:`spa.closedloop.experiments.run_staircase`), so that the steps, not the start, are
    measured; every run is measured with the estimate's cycle-mean window (the modulator's
    period at the middle level): one measurement for all valves, computed once. The valves
    run in one compiled call (:func:`spa.closedloop.loop.closed_loop_many`).
    """
    valves = [params, *corners(params, intervals)]
    r = staircase_reference(levels, hold, dt)
    t = np.arange(r.size) * dt
    r0 = float(levels[0])
    period = step_periods(modulator, params, levels, dt)
    frames = []
    # the settled integrator depends on the feed-forward, which a gain factor leaves alone
    i0 = [_settled(modulator, controller, valve, r0) for valve in valves]
    for factor in dict.fromkeys(float(g) for g in gains):
        ctrl = controller if factor == 1.0 else controller.scaled(factor)
        # The measured gain error is the plant's against the estimate (whatever its cause,
        # a parameter's error included): it scales the estimate's loop; the corners are the
        # parameters' own uncertainty, at the model's gain.
        run = valves if factor == 1.0 else valves[:1]
        ps, _, us = closed_loop_many(r, dt, modulator, ctrl, run, [r0] * len(run), i0[: len(run)])
        for p, u in zip(ps, us, strict=True):
            rows = step_rows(t, r, p, u, period, r_initial=r0)
            for row in rows:
                size = abs(row["r1"] - row["r0"])
                error = abs(row["steady_state_error"])
                row["end_error"] = 100.0 * error / size if size else math.nan
            frames.append({m: [row[m] for row in rows] for m in WORST_METRICS})
    return worst_of_steps(frames), len(valves) - 1


def lengthen_tau_c(
    worst_overshoot: Callable[[float], float],
    tau_c: float,
    limit: float,
    *,
    factor: float = FACTOR,
    max_tau_c: float | None = None,
) -> tuple[float | None, list[tuple[float, float]]]:
    """The shortest ``tau_c * factor**j`` whose worst-case overshoot is at most ``limit``.

    Parameters
    ----------
    worst_overshoot : callable
        ``tau_c -> worst-case overshoot`` (%) of the loop designed with that ``tau_c``.
    tau_c : float
        The nominal closed-loop time constant, s (tried first).
    limit : float
        The largest overshoot allowed, %.
    factor : float, optional
        Lengthening per try (> 1).
    max_tau_c : float, optional
        The longest ``tau_c`` tried; ``MAX_FACTOR * tau_c`` by default.

    Returns
    -------
    tau_c : float or None
        The first that holds, or None when none up to ``max_tau_c`` does (a NaN overshoot,
        a loop that never rises, does not hold).
    tried : list of (tau_c, overshoot)
        Every evaluation, in order.

    Examples
    --------
    >>> lengthen_tau_c(lambda t: 20.0 / t, 1.0, 10.0)
    (2.25, [(1.0, 20.0), (1.5, 13.333333333333334), (2.25, 8.88888888888889)])
    >>> lengthen_tau_c(lambda t: 20.0, 1.0, 10.0, max_tau_c=2.0)[0] is None
    True
    """
    tau = checks.positive("tau_c", tau_c, "s")
    if not factor > 1.0:
        raise ValueError(f"factor must be > 1, got {factor}")
    bound = MAX_FACTOR * tau if max_tau_c is None else float(max_tau_c)
    tried: list[tuple[float, float]] = []
    while tau <= bound * (1.0 + 1e-12):
        over = float(worst_overshoot(tau))
        tried.append((tau, over))
        if over <= limit:
            return tau, tried
        tau *= factor
    return None, tried


@dataclass(frozen=True)
class RobustDesign:
    """The chosen loop over the box: worst case at the nominal ``tau_c`` and the robust one.

    Attributes
    ----------
    tau_c : float
        The nominal closed-loop time constant, s.
    worst : dict
        Worst metrics over the box at ``tau_c`` (:func:`box_worst_case`).
    n_corners : int
        Corners of the box (0: no intervals).
    tau_c_robust : float or None
        The shortest ``tau_c`` (``tau_c * 1.5**j``) whose worst-case overshoot holds the limit;
        ``tau_c`` itself when it holds; None when none up to the bound does.
    worst_robust : dict
        Worst metrics at ``tau_c_robust`` (empty when None).
    tried : list of (tau_c, overshoot)
        Every ``tau_c`` evaluated.
    """

    tau_c: float
    worst: dict[str, float]
    n_corners: int
    tau_c_robust: float | None
    worst_robust: dict[str, float] = field(default_factory=dict)
    tried: list[tuple[float, float]] = field(default_factory=list)


def robust_design(
    modulator: Modulator,
    controller: str,
    params: ValveParams,
    intervals: Mapping[str, tuple[float, float]] | None,
    *,
    levels: Sequence[float],
    hold: float,
    dt: float,
    tau_c: float,
    limit: float,
    max_tau_c: float | None = None,
    hold_of: Callable[[float], float] | None = None,
    gains: Sequence[float] = (1.0,),
    schedule: Sequence[float] | None = None,
) -> RobustDesign:
    """Worst case over the box of the PI ``controller`` designed at the estimate,
    and the robust ``tau_c`` (:func:`lengthen_tau_c`).

    Parameters
    ----------
    modulator : Modulator
        The setting.
    controller : {"fixed", "scheduled", "scheduled_ff"}
        Which of :func:`spa.closedloop.design.design_pi`'s controllers.
    params, intervals : as :func:`box_worst_case`
    levels, hold, dt : the staircase (:class:`spa.closedloop.experiments.Staircase`)
    tau_c : float
        SIMC's nominal closed-loop time constant, s.
    limit : float
        Largest worst-case overshoot allowed, %.
    max_tau_c : float, optional
        As :func:`lengthen_tau_c`.
    hold_of : callable, optional
        ``tau_c -> hold`` (s): the staircase's hold for a lengthened ``tau_c`` (each level
        held for several closed-loop time constants); ``hold`` for every ``tau_c`` when
        omitted.
    gains : sequence of float, default (1.0,)
        Factors on the loop gain, as :func:`box_worst_case`.
    schedule : sequence of float, optional
        The set-points the controller is designed on (its gain schedule's grid); ``levels``
        when omitted. The staircase ``levels`` may be a subset (the promise's larger steps).

    Returns
    -------
    RobustDesign

    Notes
    -----
    A ``tau_c`` holds when the worst-case overshoot is within ``limit`` AND every step of
    every corner ends within 2 % of its size (``end_error``: the mean over the last quarter
    of the step, as a bench measures it): a loop whose overshoot is bought with a loop that
    never settles does not hold (its overshoot counts as infinite).
    """
    results: dict[float, tuple[dict[str, float], int]] = {}

    def evaluate(tau: float) -> float:
        grid = levels if schedule is None else schedule
        ctrl = design_pi(modulator, params, levels=grid, tau_c=tau)[controller]
        h = hold if hold_of is None else float(hold_of(tau))
        results[tau] = box_worst_case(modulator, ctrl, params, intervals, levels, h, dt, gains)
        worst = results[tau][0]
        settled = math.isfinite(worst["end_error"]) and worst["end_error"] <= SETTLED
        return worst["overshoot"] if settled else math.inf

    robust, tried = lengthen_tau_c(evaluate, tau_c, limit, max_tau_c=max_tau_c)
    worst, n = results[tried[0][0]]
    return RobustDesign(
        tau_c=float(tau_c),
        worst=worst,
        n_corners=n,
        tau_c_robust=robust,
        worst_robust=results[robust][0] if robust is not None else {},
        tried=tried,
    )
