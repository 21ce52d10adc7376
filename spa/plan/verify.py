"""A verification session: the runs that test what spa predicted for a dataset, and the
page that puts each prediction beside its measurement.

:func:`design_verification` plans, on the identified valve, the recommended setting's
staircases and sine (with the identification runs at the start and end as a drift check),
and the closed-loop stage's promise: the chosen controller's staircase (``bench.promise``'s
levels and hold), played by the player through the exported ``controller.h``.
:func:`promise_predictions` states the promise as bands and :func:`compare_promise` measures
a recorded closed-loop staircase against them.
:func:`staircase_predictions` predicts each level's pressure and the staircase's FIT with a
95 % band: the planned command (open loop: the same on any plant) simulated on the
identified valve and on valves drawn from the identification's uncertainty, with the
model's held-out error measured on the identification's own recordings
(:mod:`spa.plan.verify_error`) and the sensor's noise on the level's mean, combined as
:mod:`spa.plan.bands` says (a band calibrated to hold 95 % of measurements on an unchanged
plant, not the worst corner of the box).
:func:`compare` measures a recorded staircase the same way and says, for each prediction,
"kept" (inside its band) or "broken by ..." with the amount.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from spa.model.modulators import Modulator
from spa.model.params import ValveParams
from spa.plan.design import SessionDesign, design_session
from spa.plan.limits import Limits
from spa.plan.session import PlannedRun, Segment, run_commands, run_xi
from spa.plan.verdicts import (
    PARTS,
    _fit,
    compare,
    compare_promise,
    compare_sine,
    level_means,
    session_verdict,
    sine_fit,
    verdict,
    verification_frame,
    verification_page,
)

__all__ = [
    "PARTS",
    "closed_loop_runs",
    "compare",
    "compare_promise",
    "compare_sine",
    "corners",
    "design_verification",
    "header_step",
    "level_means",
    "promise_predictions",
    "session_verdict",
    "sine_fit",
    "sine_predictions",
    "staircase_predictions",
    "verdict",
    "verification_frame",
    "verification_page",
]


def design_verification(
    params: ValveParams,
    recommended: Modulator,
    limits: Limits,
    *,
    dt: float = 0.002,
    levels: int = 11,
    replicates: int = 3,
    seed: int = 0,
    promise: Mapping[str, Any] | None = None,
    margin: float = 3.0,
) -> SessionDesign:
    """The verification session: the recommended setting only, on the identified valve;
    with ``promise`` (``controllers.yaml``'s ``bench.promise``), ``replicates`` closed-loop
    staircases of the exported controller (:func:`closed_loop_runs`) before the drift check.

    The drift checks (charge, discharge and pulses at the start and the end) keep a first
    session's margins: sized for valves ``margin`` times slower and faster than the
    identified one, so that the verification's own recordings identify the valve they
    were made on even when it is not the one identified (the case a verification exists
    to catch)."""
    design = design_session(
        params,
        limits,
        dt=dt,
        levels=levels,
        replicates=replicates,
        seed=seed,
        settings=[],
        recommended=recommended.bind(params),
        precondition=1,
        margin=margin,
    )
    if promise is None:
        return design
    loops = closed_loop_runs(promise, dt, replicates)
    runs = list(design.runs)
    end = next((i for i, r in enumerate(runs) if r.block == "end"), len(runs))
    return dataclasses.replace(design, runs=tuple(runs[:end] + loops + runs[end:]))


def closed_loop_runs(promise: Mapping[str, Any], dt: float, replicates: int) -> list[PlannedRun]:
    """The promise's staircase played by the exported controller: one hold at the first
    level (the staircase starts settled, as the closed-loop stage measures it), then the
    levels up and back down, each held the promise's hold.

    Raises
    ------
    ValueError
        When ``promise`` has no levels or hold (``controllers.yaml: bench.promise``).
    """
    try:
        levels = [float(v) for v in promise["levels"]]
        hold = float(promise["hold"])
    except (KeyError, TypeError, ValueError):
        raise ValueError(
            "controllers.yaml: bench.promise has no levels and hold (the closed_loop stage "
            "made no promise to verify)"
        ) from None
    if len(levels) < 2 or not (math.isfinite(hold) and hold >= 2 * dt):
        raise ValueError(f"bench.promise: levels {levels} and hold {hold!r} s make no staircase")
    ticks = max(2, round(hold / dt))
    stairs = [levels[0], *levels, *levels[-2::-1]]
    segs = tuple(Segment(ticks, "loop", v) for v in stairs)
    said = ", ".join(f"{v:.3g}" for v in levels)
    return [
        PlannedRun(
            f"closed-loop_r{r}",
            "closed_loop",
            segs,
            block="closed_loop",
            notes=f"controller.h holds {said} bar up then down, {hold:.3g} s each, after one "
            "hold at the first (not measured)",
            meta={"lead": ticks * dt, "hold": ticks * dt, "levels": levels},
        )
        for r in range(1, replicates + 1)
    ]


def promise_predictions(
    promise: Mapping[str, Any],
    noise: float,
    quantum: float,
    settling_allowance: float = 0.0,
    samples: int = 1000,
) -> dict[str, dict[str, Any]]:
    """The promise as predictions with their 95 % bands.

    The promise is already the worst case over the 95 % box and the model error; the bands
    add what the sensor adds to a log: the overshoot and settling are on the cycle-mean
    pressure (:data:`spa.closedloop.promise.OVERSHOOT_MARGIN` points, one cycle), the
    ripple is the peak-to-peak of the logged pressure over ``samples`` samples (a step's
    last quarter), to which the noise adds at most the 95 % quantile of the range of that
    many normal samples (:func:`spa.plan.settling.noise_range_quantile`: 7.4 standard
    deviations over 1 000 samples, 8.1 over 4 500) and the ADC one step. The settling time
    adds ``settling_allowance`` s, what the sensor's noise in the loop adds to it
    (:func:`spa.plan.settling.settling_allowance`).

    When the stage made no promise (``kept`` false: no ``tau_c`` tried kept the overshoot
    and settling over the box), its worst case over the box is still what it predicts, and
    is what the bands hold; :func:`compare_promise` names such rows "no promise made".

    Returns
    -------
    dict
        ``overshoot`` (%), ``settling_time`` (s, when the worst case settles) and
        ``ripple_pp`` (bar), each ``value``, ``lo``, ``hi`` and ``unit``; only those the
        promise gives a number for.
    """
    from spa.closedloop.promise import OVERSHOOT_MARGIN
    from spa.plan.settling import noise_range_quantile

    def num(key: str) -> float:
        try:
            return float(promise.get(key))  # type: ignore[arg-type]
        except (TypeError, ValueError):
            return math.nan

    over, settle, ripple = num("overshoot"), num("settling_time"), num("ripple_pp")
    out: dict[str, dict[str, Any]] = {}
    if math.isfinite(over):
        out["overshoot"] = {"value": over, "lo": 0.0, "hi": over + OVERSHOOT_MARGIN, "unit": "%"}
    if math.isfinite(ripple):
        hi = ripple + noise_range_quantile(max(int(samples), 2)) * noise + quantum
        out["ripple_pp"] = {"value": ripple, "lo": 0.0, "hi": hi, "unit": "bar"}
    if math.isfinite(settle):
        hi = settle + max(float(settling_allowance), 0.0)
        out["settling_time"] = {"value": settle, "lo": 0.0, "hi": hi, "unit": "s"}
    return out


def header_step(text: str) -> tuple[str, float]:
    """The prefix and step (s) of an exported ``controller.h``.

    Raises
    ------
    ValueError
        When the text is not a spa controller header.

    Examples
    --------
    >>> header_step("#define SPA_CTRL_DT 0.001\\nstatic inline spa_ctrl_output spa_ctrl_step(")
    ('spa_ctrl', 0.001)
    """
    import re

    m = re.search(r"static\s+(?:inline\s+)?(\w+)_output\s+(\w+)_step\s*\(", text)
    if m is None or m.group(1) != m.group(2):
        raise ValueError("not a spa controller header: no '<prefix>_output <prefix>_step(' in it")
    d = re.search(rf"#define\s+{m.group(1).upper()}_DT\s+(\S+)", text)
    if d is None:
        raise ValueError(f"controller header: no {m.group(1).upper()}_DT")
    return m.group(1), float(d.group(1))


def corners(params: ValveParams, intervals: Mapping[str, tuple[float, float]]) -> list[ValveParams]:
    """The valve at every corner of the 95 % box, as the design's box has them
    (:func:`spa.identification.identified.corners`: the valve's own laws kept, the delays
    moved together by their mean and difference); the estimate alone without intervals.

    Before, the corners were rebuilt from the five numbers alone, so a valve with the
    actuator's own laws had paper-law corners around a laws estimate: on phys-choked the
    estimate's level at xi = 0.67 (3.616 bar) lay outside its own band (2.896 to 3.32 bar).
    """
    from spa.identification.identified import corners as box_corners

    return box_corners(params, intervals) or [params]


def _spread(rows: np.ndarray) -> np.ndarray:
    """The standard deviation over the draws (axis 0); 0 with fewer than two."""
    if rows.shape[0] < 2:
        return np.zeros(rows.shape[1:])
    return np.asarray(rows.std(axis=0, ddof=1), dtype=np.float64)


def _error_term(error: Mapping[str, Any] | None, kind: str) -> tuple[float, float]:
    """The model error's standard deviation and degrees of freedom of ``kind``
    (:func:`spa.plan.verify_error.recorded_model_error`); none without it."""
    term = (error or {}).get(kind)
    if not isinstance(term, Mapping):
        return 0.0, math.inf
    return float(term.get("sd", 0.0)), float(term.get("dof", math.inf))


def staircase_predictions(
    run: PlannedRun,
    dt: float,
    params: ValveParams,
    intervals: Mapping[str, tuple[float, float]],
    noise: float,
    quantum: float,
    error: Mapping[str, Any] | None = None,
    seed: int = 0,
    correlation: Mapping[str, Any] | None = None,
) -> dict[str, Any]:
    """Each level's predicted pressure and the staircase's FIT, with 95 % bands
    (:mod:`spa.plan.bands`).

    The planned command is simulated on the identified valve and on
    :data:`spa.plan.bands.DRAWS` valves drawn from the identification's ``intervals``
    (:func:`spa.plan.bands.parameter_draws`, seeded by ``seed``, correlated as the fit's
    ``correlation`` record says): their spread is the identification's term. ``error``
    (:func:`spa.plan.verify_error.recorded_model_error`, its ``level`` and ``fit``) is the
    model's; ``noise`` and ``quantum`` (bar) the sensor's on each level's mean.

    Returns
    -------
    dict
        ``xi`` (levels), ``hold`` (s), ``p`` (predicted on the identified valve),
        ``sd`` and ``dof`` (each level's prediction standard deviation and degrees of
        freedom, :func:`spa.plan.bands.combine`), ``lo``/``hi`` (the 95 % band); ``fit`` (the
        FIT a recording is expected to measure: the noise lowers it), ``fit_sd``,
        ``fit_dof``, ``fit_lo`` and ``fit_hi`` (at most 100).
    """
    from spa import simulate
    from spa.plan.bands import DRAWS, combine, half_width, parameter_draws

    seg = run.segments[0]
    hold_ticks = int(seg.c)
    n = run.ticks // hold_ticks
    xi = run_xi(run)
    assert xi is not None
    levels = xi[::hold_ticks][:n]
    u = run_commands(run, dt)
    t = np.arange(u.size) * dt
    hold = hold_ticks * dt
    nominal, count = level_means(t, simulate(u, dt, params), hold, n)
    draws = parameter_draws(params, intervals, seed=seed, correlation=correlation)
    sims = np.array([level_means(t, simulate(u, dt, d), hold, n)[0] for d in draws])
    sims = sims.reshape(len(draws), n)
    sd_noise = np.sqrt((noise**2 + quantum**2 / 12.0) / np.maximum(count, 1))
    sd_model, dof_model = _error_term(error, "level")
    sd, dof = combine(_spread(sims), sd_model, dof_model, sd_noise)
    half = half_width(sd, dof)
    # the FIT a recording measures: each draw's levels with the noise of their means
    base = sims if len(draws) >= 2 else np.repeat(nominal[None, :], DRAWS, axis=0)
    noisy = base + np.random.default_rng(seed + 1).standard_normal(base.shape) * sd_noise
    fits = np.array([_fit(levels, row) for row in noisy])
    fit_model, fit_dof_model = _error_term(error, "fit")
    fit_sd, fit_dof = combine(float(np.std(fits, ddof=1)), fit_model, fit_dof_model, 0.0)
    fit_half = float(half_width(fit_sd, fit_dof))
    fit = float(np.mean(fits))
    return {
        "xi": levels.tolist(),
        "hold": hold,
        "p": nominal.tolist(),
        "sd": sd.tolist(),
        "dof": dof.tolist(),
        "lo": (nominal - half).tolist(),
        "hi": (nominal + half).tolist(),
        "fit": fit,
        "fit_sd": float(fit_sd),
        "fit_dof": float(fit_dof),
        "fit_lo": fit - fit_half,
        "fit_hi": min(fit + fit_half, 100.0),
    }


def sine_predictions(
    run: PlannedRun,
    dt: float,
    params: ValveParams,
    intervals: Mapping[str, tuple[float, float]],
    noise: float,
    quantum: float,
    error: Mapping[str, Any] | None = None,
    seed: int = 0,
    correlation: Mapping[str, Any] | None = None,
) -> dict[str, Any]:
    """The sine's mean pressure and amplitude over its second half, predicted with 95 %
    bands as :func:`staircase_predictions`'s: the identification's draws, the model error
    (``error``'s ``sine_mean`` and ``sine_amplitude``) and the noise on a least-squares fit
    of ``n`` samples (``noise/sqrt(n)`` on the mean, ``noise sqrt(2/n)`` on the amplitude).

    Returns
    -------
    dict
        ``omega`` (rad/s), ``start`` (s), and for ``mean`` and ``amplitude`` (bar): the
        value, ``_sd``, ``_dof``, ``_lo`` and ``_hi``.
    """
    from spa import simulate
    from spa.plan.bands import combine, half_width, parameter_draws

    seg = run.segments[0]
    omega = float(seg.c) / dt
    u = run_commands(run, dt)
    t = np.arange(u.size) * dt
    start = 0.5 * u.size * dt
    nominal = sine_fit(t, simulate(u, dt, params), omega, start)
    draws = parameter_draws(params, intervals, seed=seed, correlation=correlation)
    sims = np.array([sine_fit(t, simulate(u, dt, d), omega, start)[:2] for d in draws])
    spread = _spread(sims.reshape(len(draws), 2))
    per_sample = (noise**2 + quantum**2 / 12.0) / max(nominal[2], 1)
    out: dict[str, Any] = {"omega": omega, "start": start}
    for i, (key, var) in enumerate((("mean", per_sample), ("amplitude", 2.0 * per_sample))):
        sd_model, dof_model = _error_term(error, f"sine_{key}")
        sd, dof = combine(spread[i], sd_model, dof_model, math.sqrt(var))
        half = float(half_width(sd, dof))
        out |= {
            key: nominal[i],
            f"{key}_sd": float(sd),
            f"{key}_dof": float(dof),
            f"{key}_lo": nominal[i] - half,
            f"{key}_hi": nominal[i] + half,
        }
    return out
