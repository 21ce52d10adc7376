"""One staircase run: Table 3, the levels of Fig. 7a and the steps of Fig. 7b (Section 6.2).

`staircase_analysis` measures, per level, the equilibrium, the chattering (peak-to-peak and
corrected for the sensor's noise, `spa.openloop.noise`) and the switching rate beside the
averaged model's predictions (`predicted_levels`: Eqs. 5, 9, 10 and Appendix B); per step
the time constant (Fig. 7b); and one summary row of Table 3 with the dead-zone and
saturation brackets (`measured_thresholds`) against Table 1.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np
import numpy.typing as npt
import pandas as pd

from spa.model.averaging import (
    chattering_estimate,
    equilibrium,
    pseudo_steady_state,
    pulse_times,
    thresholds,
)
from spa.model.modulators import Modulator
from spa.model.params import ValveParams
from spa.openloop._arrays import _array, run_columns
from spa.openloop.levels import linear_fit_metrics, staircase_levels
from spa.openloop.noise import corrected_ripple, sensor_noise
from spa.openloop.paper import PAPER_TABLE3, paper_case
from spa.openloop.steps import step_time_constants

__all__ = ["measured_thresholds", "predicted_levels", "staircase_analysis"]


def predicted_levels(
    mod: Mapping[str, Any] | Modulator, xi: npt.ArrayLike, params: ValveParams
) -> pd.DataFrame:
    """What the averaged model predicts for constant input fractions.

    Parameters
    ----------
    mod : mapping or Modulator
        Modulator setting, e.g. ``{"type": "pwm", "f_w": 20}``.
    xi : array_like of float, shape (k,)
        Input fractions.
    params : ValveParams
        Valve parameters (e.g. the dataset's identified ones).

    Returns
    -------
    pandas.DataFrame
        One row per ``xi`` with ``p_eq_model`` (Eq. 5, bar), ``p_pp_eq10`` (Eq. 10: rise
        during one high pulse at equilibrium, bar), ``p_pp_appb`` (Appendix B: exact
        ``P+ - P-`` of the periodic train, bar) and ``switching_rate_model`` (command edges
        per second, ``2/(t_h + t_l)``). Where the command is constant (a duration is 0 or
        infinite) there is no pulse train: chattering and switching rate are 0.

    Examples
    --------
    >>> df = predicted_levels({"type": "pwm", "f_w": 20}, [0.0, 0.5, 1.0], ValveParams())
    >>> df["switching_rate_model"].tolist()
    [0.0, 40.0, 0.0]
    """
    setting = Modulator.from_mapping(mod)
    kind, settings = setting.kind, dict(setting.settings)
    x = np.asarray(xi, dtype=np.float64)
    p_eq = np.asarray(equilibrium(kind, x, params, **settings), dtype=np.float64)
    t_h, t_l = (np.asarray(a, dtype=np.float64) for a in pulse_times(kind, x, params, **settings))
    pulsing = np.isfinite(t_h) & np.isfinite(t_l) & (t_h > 0.0) & (t_l > 0.0)
    th = np.where(pulsing, t_h, 1.0)
    tl = np.where(pulsing, t_l, 1.0)
    p_plus, p_minus = pseudo_steady_state(th, tl, params)
    eq10 = np.asarray(chattering_estimate(th, p_eq, params), dtype=np.float64)
    return pd.DataFrame(
        {
            "xi": x,
            "p_eq_model": p_eq,
            "p_pp_eq10": np.where(pulsing, eq10, 0.0),
            "p_pp_appb": np.where(pulsing, np.asarray(p_plus) - np.asarray(p_minus), 0.0),
            "switching_rate_model": np.where(pulsing, 2.0 / (th + tl), 0.0),
        }
    )


def measured_thresholds(
    xi: npt.ArrayLike, p_eq: npt.ArrayLike, zone_fraction: float = 0.02
) -> dict[str, float]:
    """Dead-zone and saturation seen in a staircase, bracketed by its levels.

    Parameters
    ----------
    xi : array_like of float, shape (k,)
        Input fractions of the levels, increasing.
    p_eq : array_like of float, shape (k,)
        Their equilibrium pressures (bar).
    zone_fraction : float, default 0.02
        A level is in the dead-zone while its pressure is within this fraction of the span
        ``max(p_eq) - min(p_eq)`` of the lowest level's, and saturated while within it of the
        highest pressure; in (0, 1).

    Returns
    -------
    dict
        ``dead_zone_last``: the largest ``xi`` of the run of dead levels starting at the
        lowest level; ``dead_zone_next``: the level after it (NaN if none). The true
        threshold lies in ``[dead_zone_last, dead_zone_next)``. Likewise ``saturation_first``
        (smallest ``xi`` of the run of saturated levels ending at the highest) and
        ``saturation_prev`` (the level before it): the threshold lies in
        ``(saturation_prev, saturation_first]``.

    Examples
    --------
    >>> r = measured_thresholds([0, .25, .5, .75, 1], [0, 0, .3, .8, .8])
    >>> r["dead_zone_last"], r["dead_zone_next"], r["saturation_prev"], r["saturation_first"]
    (0.25, 0.5, 0.5, 0.75)
    """
    x = np.asarray(xi, dtype=np.float64)
    p = np.asarray(p_eq, dtype=np.float64)
    if x.ndim != 1 or x.shape != p.shape or x.size < 2:
        raise ValueError("xi and p_eq must be one-dimensional, of one length >= 2")
    if np.any(np.diff(x) <= 0.0):
        raise ValueError("xi must be strictly increasing")
    if not 0.0 < zone_fraction < 1.0:
        raise ValueError(f"zone_fraction must be in (0, 1), got {zone_fraction!r}")
    tol = zone_fraction * float(np.ptp(p))
    dead = np.abs(p - p[0]) <= tol
    sat = np.abs(p - p.max()) <= tol
    n_dead = int(np.argmin(dead)) if not dead.all() else x.size  # leading run
    n_sat = int(np.argmin(sat[::-1])) if not sat.all() else x.size  # trailing run
    return {
        "dead_zone_last": float(x[n_dead - 1]),
        "dead_zone_next": float(x[n_dead]) if n_dead < x.size else math.nan,
        "saturation_first": float(x[x.size - n_sat]),
        "saturation_prev": float(x[x.size - n_sat - 1]) if n_sat < x.size else math.nan,
    }


def staircase_analysis(
    run: pd.DataFrame,
    mod: Mapping[str, Any] | Modulator,
    params: ValveParams,
    *,
    settle: float = 0.4,
    zone_fraction: float = 0.02,
    min_change: float = 0.01,
    smooth: float = 0.1,
    max_drift: float = 0.005,
    clean: Mapping[str, npt.ArrayLike] | None = None,
) -> tuple[pd.DataFrame, pd.DataFrame, dict[str, Any]]:
    """Static and dynamic linearity of one staircase run (Table 3, Figs. 6–7).

    Parameters
    ----------
    run : pandas.DataFrame
        Canonical run table of a staircase (``u`` piece-wise constant).
    mod : mapping or Modulator
        The run's modulator setting.
    params : ValveParams
        Valve parameters for the predictions (the dataset's identified ones).
    settle : float, default 0.4
        Settled window of each level, as the fraction of its duration at its end
        (`spa.openloop.levels.staircase_levels`).
    zone_fraction : float, default 0.02
        Dead-zone/saturation tolerance (`measured_thresholds`).
    min_change : float, default 0.01
        Steps changing the pressure by at most this (bar) get no time constant.
    smooth : float, default 0.1
        Moving-average width (s) applied before timing the steps (removes chattering).
    max_drift : float, default 0.005
        A level whose pressure still drifts by more than this (bar) across its window is
        not used to measure the sensor's noise (`spa.openloop.noise.sensor_noise`).
    clean : mapping of str to array_like of float, shape (n,), optional
        Noise-free versions of the run's pressure (a simulated run's,
        `spa.openloop.replicas.noise_free_pressure`), e.g. ``{"noise_free": ...}``: the
        ripple of each is reported beside the measured and the corrected one.

    Returns
    -------
    levels : pandas.DataFrame
        `spa.openloop.levels.staircase_levels` joined with `predicted_levels` at each level's
        ``xi``, plus ``p_fit`` (the fitted line), ``residual`` (``p_eq - p_fit``),
        ``still`` (no valve edge in the window), ``p_ripple_corrected`` (peak-to-peak
        chattering with the sensor's noise variance subtracted,
        `spa.openloop.noise.corrected_ripple`) and, for each ``name`` of ``clean``,
        ``p_ripple_<name>`` (that pressure's ``p_ripple`` over the same window).
    steps : pandas.DataFrame
        `spa.openloop.steps.step_time_constants`.
    summary : dict
        One row of Table 3: the line ``m``, ``n``; ``mse`` beside the paper's
        ``paper_mse``; ``mad`` (mean absolute residual) beside ``paper_md`` (the paper's MD
        is a mean absolute deviation: `spa.openloop.levels.linear_fit_metrics`);
        ``max_dev`` (largest residual); ``fit`` (%) beside ``paper_fit``; the paper's values
        are NaN unless the setting is one of its five cases. Then ``eq_rmse_model`` (RMS of
        measured minus averaged-model equilibrium, bar); ``drift_max`` (the largest
        ``|p_drift|`` of a level, bar: how far the levels are from settled); the measured
        thresholds (`measured_thresholds`) beside ``dead_zone_table1`` and
        ``saturation_table1`` (Table 1 with ``params``) and beside the same brackets taken
        on the averaged model's equilibria at the run's levels (``dead_zone_model_last``,
        ``saturation_model_first``), with ``dead_zone_agrees`` / ``saturation_agrees`` true
        when measurement and model put the threshold between the same two levels;
        ``tau_mean``, ``tau_sd`` (sample sd), ``n_tau``; ``switching_rate_mean`` (edges/s
        over all levels); ``noise_pp`` (``p_pp`` of the lowest level); the sensor's noise
        ``noise_sd`` (bar) pooled over ``n_still_levels`` still, settled levels; and the
        chattering averaged over the levels where the valve switches: ``ripple_mean``
        (measured peak-to-peak), ``ripple_corrected_mean``, ``ripple_<name>_mean`` for each
        of ``clean``, and Appendix B's ``ripple_model_mean``.
    """
    setting = Modulator.from_mapping(mod)
    kind, settings = setting.kind, dict(setting.settings)
    t, p, valve, u = run_columns(run, ("t", "p", "valve", "u"), "staircase_analysis")
    lv = staircase_levels(t, p, u, valve, settle=settle)
    steps = step_time_constants(t, p, u, settle=settle, min_change=min_change, smooth=smooth)
    fit = linear_fit_metrics(lv["xi"], lv["p_eq"])
    pred = predicted_levels(setting, lv["xi"].to_numpy(), params).drop(columns="xi")
    levels = pd.concat([lv, pred], axis=1)
    levels["p_fit"] = fit["m"] * levels["xi"] + fit["n"]
    levels["residual"] = levels["p_eq"] - levels["p_fit"]
    levels["still"] = levels["switching_rate"] == 0.0
    noise_sd, n_still = sensor_noise(
        levels["p_ripple_sd"], levels["n_window"], levels["still"], levels["p_drift"], max_drift
    )
    levels["p_ripple_corrected"] = corrected_ripple(levels["p_ripple_sd"], noise_sd)[1]
    for name, pressure in (clean or {}).items():
        p_clean = _array(f"clean[{name!r}]", pressure, size=t.size)
        levels[f"p_ripple_{name}"] = staircase_levels(t, p_clean, u, settle=settle)["p_ripple"]
    pulsing = ~levels["still"]

    up = np.argsort(lv["xi"].to_numpy(), kind="stable")  # a staircase stepping down, reversed
    xi_up = lv["xi"].to_numpy()[up]
    meas = measured_thresholds(xi_up, lv["p_eq"].to_numpy()[up], zone_fraction)
    model = measured_thresholds(xi_up, levels["p_eq_model"].to_numpy()[up], zone_fraction)
    dz, sat = (float(v) for v in thresholds(kind, params, **settings))
    case = paper_case(setting)
    paper = PAPER_TABLE3[case][1:] if case else (math.nan,) * 3
    tau = steps["tau"].dropna()
    summary: dict[str, Any] = {
        "modulator": kind,
        "setting": setting.label,
        "paper_case": case or "",
        "m": fit["m"],
        "n": fit["n"],
        "mse": fit["mse"],
        "paper_mse": paper[0],
        "mad": fit["mad"],
        "paper_md": paper[1],
        "max_dev": fit["max_dev"],
        "fit": fit["fit"],
        "paper_fit": paper[2],
        "eq_rmse_model": float(np.sqrt(np.mean((levels["p_eq"] - levels["p_eq_model"]) ** 2))),
        "drift_max": float(levels["p_drift"].abs().max()),
        **meas,
        "dead_zone_table1": dz,
        "dead_zone_model_last": model["dead_zone_last"],
        "dead_zone_agrees": meas["dead_zone_last"] == model["dead_zone_last"],
        "saturation_table1": sat,
        "saturation_model_first": model["saturation_first"],
        "saturation_agrees": meas["saturation_first"] == model["saturation_first"],
        "tau_mean": float(tau.mean()) if tau.size else math.nan,
        "tau_sd": float(tau.std()) if tau.size > 1 else math.nan,
        "n_tau": int(tau.size),
        "switching_rate_mean": float(levels["switching_rate"].mean()),
        "noise_pp": float(levels["p_pp"].iloc[up[0]]),
        "noise_sd": noise_sd,
        "n_still_levels": n_still,
        "ripple_mean": _mean(levels["p_ripple"], pulsing),
        "ripple_corrected_mean": _mean(levels["p_ripple_corrected"], pulsing),
        **{
            f"ripple_{name}_mean": _mean(levels[f"p_ripple_{name}"], pulsing)
            for name in clean or {}
        },
        "ripple_model_mean": _mean(levels["p_pp_appb"], pulsing),
    }
    return levels, steps, summary


def _mean(values: pd.Series, where: pd.Series) -> float:
    """Mean of ``values`` over the rows ``where`` is true; NaN if there is none."""
    if not where.any():
        return math.nan
    return float(values[where].mean())
