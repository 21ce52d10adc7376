"""A recorded closed-loop run against the model: its metrics, and the same loop replayed.

A bench run under PI control records the set-point ``r``, the pressure ``p`` and, often, the
valve command. :func:`replay_closed_loop` measures the step metrics of the recording
(:func:`spa.closedloop.metrics.step_metrics`), runs the same controller and modulator on the
identified model with the recorded set-point (:func:`spa.closedloop.loop.simulate_closed_loop`
on the controller's own step), and scores the prediction against the measurement with the
FIT of system identification, ``100*(1 - ||p - p_model|| / ||p - mean(p)||)``.

In closed loop the controller hides much of a model's error (both the bench and the model
track the set-point), so the FIT is high for any model that tracks: on a staircase
0.1-0.7 bar with 5 mbar sensor noise, the true valve replays to FIT 97.6 % and a valve with
k2 = 0.7 bar and tau2 = 0.5 s still to 93.9 %. Compare the RMS error with the sensor's noise
(2.5 times larger for the wrong valve there) rather than the FIT alone.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
import pandas as pd

from spa import _checks as checks
from spa.closedloop.controller import PIController
from spa.closedloop.experiments import step_periods
from spa.closedloop.loop import simulate_closed_loop
from spa.closedloop.metrics import step_metrics
from spa.model.modulators import Modulator
from spa.model.params import ValveParams

__all__ = ["RUN_COLUMNS", "ClosedLoopReplay", "recorded_runs", "replay_closed_loop"]


@dataclass(frozen=True)
class ClosedLoopReplay:
    """What :func:`replay_closed_loop` returns.

    Attributes
    ----------
    fit : float
        FIT % of the replayed pressure against the recorded one.
    rmse, max_error : float
        Root-mean-square and largest absolute error, bar.
    measured, predicted : pandas.DataFrame
        Step metrics of the recording and of the replay (one row per set-point step).
    model : pandas.DataFrame
        The replay on the recording's time stamps: ``t``, ``r``, ``p`` (recorded),
        ``p_model``.
    """

    fit: float
    rmse: float
    max_error: float
    measured: pd.DataFrame
    predicted: pd.DataFrame
    model: pd.DataFrame


def replay_closed_loop(
    run: pd.DataFrame,
    modulator: Modulator | dict[str, Any],
    controller: PIController,
    params: ValveParams,
    dt: float,
    *,
    integral0: float = 0.0,
) -> ClosedLoopReplay:
    """Measure a recorded closed-loop run and replay its controller on the model.

    Parameters
    ----------
    run : pandas.DataFrame
        Columns ``t`` (s), ``p`` and ``r`` (bar); ``valve`` (0/1) when recorded, for the
        switching rate (NaN without it).
    modulator : Modulator or mapping
        The setting the bench used.
    controller : PIController
        The controller the bench used.
    params : ValveParams
        The identified valve.
    dt : float
        The controller's step, s. The recorded set-point is held between samples (zero-order
        hold) onto this step.
    integral0 : float, optional
        The controller's integrator at the start of the recording.

    Returns
    -------
    ClosedLoopReplay

    Raises
    ------
    ValueError
        For a missing column, fewer than two samples or non-finite values.
    """
    for col in ("t", "p", "r"):
        if col not in run:
            raise ValueError(f"closed-loop run has no column {col!r} (the set-point is 'r')")
    t = checks.finite_array("t", run["t"], ndim=1)
    p = checks.finite_array("p", run["p"], ndim=1)
    r = checks.finite_array("r", run["r"], ndim=1)
    if t.size < 2:
        raise ValueError("closed-loop run needs at least two samples")
    dt = checks.positive("dt", dt, "s")
    mod = Modulator.from_mapping(modulator)
    n = math.floor((t[-1] - t[0]) / dt + 1e-9) + 1
    grid = t[0] + np.arange(n) * dt
    held = r[np.maximum(np.searchsorted(t, grid + 1e-12, side="right") - 1, 0)]
    sim = simulate_closed_loop(
        held, dt, mod, controller, params, max(float(p[0]), 0.0), integral0=integral0
    )
    p_model = np.interp(t, grid, sim["p"].to_numpy())
    err = p - p_model
    spread = float(np.linalg.norm(p - p.mean()))
    fit = 100.0 * (1.0 - float(np.linalg.norm(err)) / spread) if spread > 0 else math.nan
    period = step_periods(mod, params, np.unique(r), dt)
    valve = run["valve"].to_numpy() if "valve" in run else np.zeros(t.size, dtype=np.int8)
    recording = pd.DataFrame({"t": t, "r": r, "p": p, "valve": valve})
    measured = step_metrics(recording, period, r_initial=float(r[0]))
    if "valve" not in run:
        measured["switching_rate"] = math.nan
    sim_on_grid = sim.assign(t=grid)
    predicted = step_metrics(sim_on_grid, period, r_initial=float(r[0]))
    return ClosedLoopReplay(
        fit=fit,
        rmse=float(np.sqrt(np.mean(err**2))),
        max_error=float(np.max(np.abs(err))),
        measured=measured,
        predicted=predicted,
        model=pd.DataFrame({"t": t, "r": r, "p": p, "p_model": p_model}),
    )


#: Columns of ``runs.csv`` (recorded closed-loop runs against their replay).
RUN_COLUMNS = (
    "run",
    "origin",
    "modulator",
    "kp",
    "ki",
    "dt",
    "n_steps",
    "fit",
    "rmse",
    "max_error",
    "rise_time_max",
    "rise_time_max_model",
    "overshoot_max",
    "overshoot_max_model",
    "steady_state_error_max",
    "steady_state_error_max_model",
)


def recorded_runs(
    runs: Mapping[str, pd.DataFrame], metas: Mapping[str, Mapping[str, Any]], params: ValveParams
) -> pd.DataFrame:
    """The dataset's ``closed_loop`` runs: measured metrics and the replay on the model.

    Parameters
    ----------
    runs, metas : mapping
        Run id -> run table and metadata (:func:`spa.datasets.read_runs`); runs of other kinds
        are ignored.
    params : ValveParams
        The identified valve.

    Returns
    -------
    pandas.DataFrame
        One row per run, :data:`RUN_COLUMNS`: the recording's worst rise time, overshoot and
        steady-state error over its set-point steps beside the replay's (``*_model``), and
        the replay's FIT %, RMSE and largest error (bar). The replay starts from the recorded
        first pressure with the integrator at 0 (a run that starts from rest).
    """
    rows = []
    for rid, meta in metas.items():
        if meta.get("kind") != "closed_loop":
            continue
        spec = dict(meta["controller"])
        ctrl = PIController.from_mapping(spec)
        res = replay_closed_loop(runs[rid], meta["modulator"], ctrl, params, float(spec["dt"]))
        worst = {}
        for metric in ("rise_time", "overshoot", "steady_state_error"):
            for suffix, frame in (("", res.measured), ("_model", res.predicted)):
                v = frame[metric].abs().to_numpy(np.float64)
                worst[f"{metric}_max{suffix}"] = (
                    float(np.nanmax(v)) if np.isfinite(v).any() else math.nan
                )
        rows.append(
            {
                "run": rid,
                "origin": meta.get("origin", ""),
                "modulator": Modulator.from_mapping(meta["modulator"]).label,
                "kp": fmt_gain(spec["kp"]),
                "ki": fmt_gain(spec.get("ki", 0.0)),
                "dt": float(spec["dt"]),
                "n_steps": len(res.measured),
                "fit": res.fit,
                "rmse": res.rmse,
                "max_error": res.max_error,
                **worst,
            }
        )
    return pd.DataFrame(rows, columns=list(RUN_COLUMNS))


def fmt_gain(value: Any) -> str:
    """A gain or a schedule of gains as text (``4.1`` or ``3.9-4.5``)."""
    if isinstance(value, list | tuple):
        return f"{min(value):.4g}-{max(value):.4g}"
    return f"{float(value):.4g}"
