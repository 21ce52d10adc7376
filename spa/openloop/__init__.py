"""Open-loop characterisation of one run: staircase, sine and chirp (paper Section 6).

Each function takes one canonical run table (``t`` s, ``p`` bar, ``valve`` 0/1, ``u`` input
fraction) and the run's modulator setting, calls the array functions of
:mod:`spa.openloop.linearity`, :mod:`spa.openloop.spectra` and
:mod:`spa.model.averaging`, and returns tables ready to be written:

* `staircase_analysis`: per level the measured equilibrium, chattering and switching rate
  beside the averaged model's predictions (Eqs. 5–10, Appendix B); per step the time
  constant (Fig. 7b); and one summary row of Table 3 (line fit, MSE, MD, FIT), with the
  measured dead-zone and saturation against Table 1.
* `sine_analysis`: the lag-compensated input against the normalised pressure (Fig. 8) and
  its RMS deviation from the line from (0, 0) to (1, 1).
* `chirp_analysis`: the bicoherence map of the pressure (Fig. 9) and its mean over the
  principal domain.

`PAPER_TABLE3` holds the paper's printed Table 3 for the five selected cases; it is only
ever shown beside the measured values, never used to compute anything.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
import numpy.typing as npt
import pandas as pd
from scipy import signal

from spa.model.averaging import (
    chattering_estimate,
    equilibrium,
    pseudo_steady_state,
    pulse_times,
    thresholds,
)
from spa.model.modulators import MODULATOR_ORDER, Modulator
from spa.model.params import ValveParams
from spa.openloop.linearity import (
    compensate_lag,
    linear_fit_metrics,
    sine_linearity,
    staircase_levels,
    step_time_constants,
)
from spa.openloop.spectra import bicoherence, mean_bicoherence, principal_domain_mask, segment_count

__all__ = [
    "MODULATOR_ORDER",
    "PAPER_TABLE3",
    "PAPER_TIME_CONSTANTS",
    "best_settings",
    "chirp_analysis",
    "measured_thresholds",
    "paper_case",
    "predicted_levels",
    "run_tags",
    "runs_of_kind",
    "sine_analysis",
    "staircase_analysis",
]

#: The paper's Table 3 (bench data): setting -> (MSE in bar², MD in bar, FIT in %).
PAPER_TABLE3: Mapping[str, tuple[dict[str, Any], float, float, float]] = {
    "PWM": ({"type": "pwm", "f_w": 20.0}, 7.3e-3, 7.56e-2, 75.23),
    "IPFM": ({"type": "ipfm", "t_h": 0.020}, 13.0e-3, 10.02e-2, 68.23),
    "IIPFM (G = 1.00)": ({"type": "iipfm", "t_l": 0.020, "gain": 1.0}, 2.5e-3, 4.07e-2, 84.20),
    "IIPFM (G = 1.15)": ({"type": "iipfm", "t_l": 0.020, "gain": 1.15}, 1.3e-3, 3.13e-2, 87.89),
    "ΔΣM": ({"type": "dsm", "period": 0.020}, 4.5e-3, 5.55e-2, 78.82),
}

#: The paper's measured step time constants (Fig. 7b): modulator -> (mean, sd) in s.
PAPER_TIME_CONSTANTS: Mapping[str, tuple[float, float]] = {
    "iipfm": (1.139, 0.207),
    "pwm": (0.847, 0.388),
}

_RUN_COLUMNS = ("t", "p", "valve", "u")


def _columns(run: pd.DataFrame, what: str) -> tuple[np.ndarray, ...]:
    missing = [c for c in _RUN_COLUMNS if c not in run.columns]
    if missing:
        raise ValueError(f"{what}: run table lacks column(s) {missing}; has {list(run.columns)}")
    return tuple(run[c].to_numpy(dtype=np.float64) for c in _RUN_COLUMNS)


def paper_case(mod: Mapping[str, Any]) -> str | None:
    """Name of the `PAPER_TABLE3` case a modulator setting is, or None.

    Examples
    --------
    >>> paper_case({"type": "iipfm", "t_l": 0.02, "gain": 1.15})
    'IIPFM (G = 1.15)'
    >>> paper_case({"type": "pwm", "f_w": 10}) is None
    True
    """
    setting = Modulator.from_mapping(mod)
    for name, (case, *_) in PAPER_TABLE3.items():
        if Modulator.from_mapping(case) == setting:
            return name
    return None


def predicted_levels(
    mod: Mapping[str, Any], xi: npt.ArrayLike, params: ValveParams
) -> pd.DataFrame:
    """What the averaged model predicts for constant input fractions.

    Parameters
    ----------
    mod : mapping
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
    t_h, t_l = (np.asarray(a, dtype=np.float64) for a in pulse_times(kind, x, **settings))
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
    mod: Mapping[str, Any],
    params: ValveParams,
    *,
    settle: float = 0.4,
    zone_fraction: float = 0.02,
    min_change: float = 0.01,
    smooth: float = 0.1,
) -> tuple[pd.DataFrame, pd.DataFrame, dict[str, Any]]:
    """Static and dynamic linearity of one staircase run (Table 3, Figs. 6–7).

    Parameters
    ----------
    run : pandas.DataFrame
        Canonical run table of a staircase (``u`` piece-wise constant).
    mod : mapping
        The run's modulator setting.
    params : ValveParams
        Valve parameters for the predictions (the dataset's identified ones).
    settle : float, default 0.4
        Settled window of each level, as the fraction of its duration at its end
        (`spa.openloop.linearity.staircase_levels`).
    zone_fraction : float, default 0.02
        Dead-zone/saturation tolerance (`measured_thresholds`).
    min_change : float, default 0.01
        Steps changing the pressure by at most this (bar) get no time constant.
    smooth : float, default 0.1
        Moving-average width (s) applied before timing the steps (removes chattering).

    Returns
    -------
    levels : pandas.DataFrame
        `spa.openloop.linearity.staircase_levels` joined with `predicted_levels` at each level's
        ``xi``, plus ``p_fit`` (the fitted line) and ``residual`` (``p_eq - p_fit``).
    steps : pandas.DataFrame
        `spa.openloop.linearity.step_time_constants`.
    summary : dict
        One row of Table 3: the line ``m``, ``n``, ``mse``, ``md`` (largest residual),
        ``mad`` (mean absolute residual), ``fit`` (%); the paper's values
        ``paper_mse``, ``paper_md``, ``paper_fit`` when the setting is one of its five cases
        (else NaN); ``eq_rmse_model`` (RMS of measured minus averaged-model equilibrium,
        bar); the measured thresholds (`measured_thresholds`) beside ``dead_zone_table1`` and
        ``saturation_table1`` (Table 1 with ``params``) and beside the same brackets taken on
        the averaged model's equilibria at the run's levels (``dead_zone_model_last``,
        ``saturation_model_first``), with ``dead_zone_agrees`` / ``saturation_agrees`` true
        when measurement and model put the threshold between the same two levels (a
        threshold itself cannot be compared: just above it the pressure rises too slowly to
        be told from the sensor's floor); ``tau_mean``, ``tau_sd`` (sample sd), ``n_tau``;
        ``switching_rate_mean`` (edges/s over all levels) and ``noise_pp`` (``p_pp`` of the
        first level, the sensor's floor when that level is a dead-zone).
    """
    setting = Modulator.from_mapping(mod)
    kind, settings = setting.kind, dict(setting.settings)
    t, p, valve, u = _columns(run, "staircase_analysis")
    lv = staircase_levels(t, p, u, valve, settle=settle)
    steps = step_time_constants(t, p, u, settle=settle, min_change=min_change, smooth=smooth)
    fit = linear_fit_metrics(lv["xi"], lv["p_eq"])
    pred = predicted_levels(mod, lv["xi"].to_numpy(), params).drop(columns="xi")
    levels = pd.concat([lv, pred], axis=1)
    levels["p_fit"] = fit["m"] * levels["xi"] + fit["n"]
    levels["residual"] = levels["p_eq"] - levels["p_fit"]

    meas = measured_thresholds(lv["xi"], lv["p_eq"], zone_fraction)
    model = measured_thresholds(lv["xi"], levels["p_eq_model"], zone_fraction)
    dz, sat = (float(v) for v in thresholds(kind, params, **settings))
    case = paper_case(mod)
    paper = PAPER_TABLE3[case][1:] if case else (math.nan,) * 3
    tau = steps["tau"].dropna()
    summary: dict[str, Any] = {
        "modulator": kind,
        "setting": setting.label,
        "paper_case": case or "",
        **fit,
        "paper_mse": paper[0],
        "paper_md": paper[1],
        "paper_fit": paper[2],
        "eq_rmse_model": float(np.sqrt(np.mean((levels["p_eq"] - levels["p_eq_model"]) ** 2))),
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
        "noise_pp": float(levels["p_pp"].iloc[0]),
    }
    return levels, steps, summary


def best_settings(table: pd.DataFrame, score: str = "fit", higher: bool = True) -> pd.DataFrame:
    """The best row of each modulator, with the settings of gain other than 1 apart.

    Parameters
    ----------
    table : pandas.DataFrame
        Rows with columns ``modulator``, ``setting``, ``gain`` and ``score``.
    score : str, default "fit"
        Column ranking the settings of one modulator.
    higher : bool, default True
        Whether a higher score is better.

    Returns
    -------
    pandas.DataFrame
        The chosen rows, in the paper's order PWM, IPFM, IIPFM, IIPFM with gain, ΔΣM
        (a modulator's settings with ``gain != 1`` compete only among themselves, so that
        Fig. 7a shows IIPFM with G = 1 and with G = 1.15, as the paper does).
    """
    for c in ("modulator", "setting", "gain", score):
        if c not in table.columns:
            raise ValueError(f"table lacks column {c!r}; has {list(table.columns)}")
    if table.empty:
        return table.copy()
    group = table["modulator"] + np.where(table["gain"] != 1.0, "+G", "")
    order = {"pwm": 0, "ipfm": 1, "ipfm+G": 1.5, "iipfm": 2, "iipfm+G": 3, "dsm": 4}
    keyed = table.assign(_group=group, _score=table[score] if higher else -table[score])
    keyed = keyed[keyed["_score"].notna()]
    best = keyed.sort_values(["_score", "setting"], ascending=[False, True]).drop_duplicates(
        "_group"
    )
    best = best.assign(_order=best["_group"].map(order).fillna(9)).sort_values(
        ["_order", "setting"]
    )
    return best.drop(columns=["_group", "_score", "_order"])


def sine_analysis(
    run: pd.DataFrame, *, settle: float = 0.0, max_lag: float | None = 2.0
) -> tuple[pd.DataFrame, dict[str, float]]:
    """Linearity of the response to a sine of piece-wise decreasing amplitude (Fig. 8).

    Parameters
    ----------
    run : pandas.DataFrame
        Canonical run table.
    settle : float, default 0.0
        Seconds dropped at the start (a hold at the offset before the sine starts).
    max_lag : float or None, default 2.0
        Largest lag searched by the cross-correlation, s (None: the whole record).

    Returns
    -------
    aligned : pandas.DataFrame
        ``t``, ``xi`` (input) and ``p_norm`` (pressure shifted back by the lag, divided by
        its maximum) over the overlapping part.
    summary : dict
        ``lag`` (s), ``rms`` and ``md`` (RMS and largest ``|p_norm - xi|``), ``p_max`` (bar).
    """
    t, p, _, u = _columns(run, "sine_analysis")
    keep = t >= t[0] + settle
    if keep.sum() < 2:
        raise ValueError(f"sine_analysis: settle = {settle} s leaves no samples")
    lag, ta, xa, pa = compensate_lag(t[keep], u[keep], p[keep], max_lag=max_lag)
    lin = sine_linearity(xa, pa)
    aligned = pd.DataFrame({"t": ta, "xi": xa, "p_norm": pa / lin["p_max"]})
    return aligned, {"lag": lag, **lin}


def chirp_analysis(
    run: pd.DataFrame, *, nfft: int = 256, overlap: float = 0.5, decimate: int = 1
) -> tuple[np.ndarray, np.ndarray, dict[str, float]]:
    """Bicoherence of the pressure response to a chirp input (Fig. 9).

    Parameters
    ----------
    run : pandas.DataFrame
        Canonical run table, uniformly sampled.
    nfft : int, default 256
        Segment and FFT length (`spa.openloop.spectra.bicoherence`).
    overlap : float, default 0.5
        Segment overlap fraction.
    decimate : int, default 1
        Downsampling factor applied first (anti-aliasing FIR filter, zero phase,
        ``scipy.signal.decimate``), so that the map covers the band of the chirp rather than
        the sensor's noise up to half its logging rate: a 0.1–100 Hz chirp logged at 1 kHz
        is analysed at 250 Hz with ``decimate = 4``.

    Returns
    -------
    f : numpy.ndarray, shape (nfft,)
        Frequency axis in Hz.
    bic : numpy.ndarray, shape (nfft, nfft)
        Bicoherence map.
    summary : dict
        ``fs`` (Hz, after decimation), ``nfft``, ``n_segments``, ``mean_bicoherence`` over
        the principal domain without the DC row (one bin and up), and ``median_bicoherence``
        and ``max_bicoherence`` over it. The estimator is not bounded by 1 where a
        frequency carries little power, so a handful of bins can move the mean; the median
        tells whether the whole map moved.
    """
    t, p, _, _ = _columns(run, "chirp_analysis")
    steps = np.diff(t)
    dt = float(np.mean(steps))
    if np.max(np.abs(steps - dt)) > 1e-3 * dt:
        raise ValueError("chirp_analysis: t must be uniformly sampled for a bicoherence")
    q = int(decimate)
    if q != decimate or q < 1:
        raise ValueError(f"chirp_analysis: decimate must be an integer >= 1, got {decimate!r}")
    if q > 1:
        p = signal.decimate(p, q, ftype="fir", zero_phase=True)
    fs = 1.0 / (dt * q)
    f, bic = bicoherence(p, fs, nfft=nfft, overlap=overlap)
    fmin = fs / nfft
    mask = principal_domain_mask(f, fmin=fmin)
    return (
        f,
        bic,
        {
            "fs": fs,
            "nfft": int(nfft),
            "n_segments": segment_count(p.size, nfft, overlap),
            "mean_bicoherence": mean_bicoherence(f, bic, fmin=fmin),
            "median_bicoherence": float(np.median(bic[mask])),
            "max_bicoherence": float(bic[mask].max()),
        },
    )


def runs_of_kind(metas: Mapping[str, Mapping[str, Any]], kind: str) -> list[str]:
    """Run ids of one kind whose metadata names a modulator, in the order of their settings.

    The order is :attr:`spa.model.modulators.Modulator.sort_key`: the paper's modulator order
    (PWM, IPFM, IIPFM, ΔΣM), then the setting's value as a number (10 ms before 100 ms),
    then the gain; runs of the same setting by id.

    Examples
    --------
    >>> runs_of_kind({"b": {"kind": "sine", "modulator": {"type": "pwm", "f_w": 20}},
    ...               "a": {"kind": "charge"}}, "sine")
    ['b']
    """
    ids = [r for r, m in metas.items() if m.get("kind") == kind and m.get("modulator")]
    return sorted(ids, key=lambda r: (Modulator.from_mapping(metas[r]["modulator"]).sort_key, r))


def run_tags(metas: Mapping[str, Mapping[str, Any]], ids: Sequence[str]) -> pd.DataFrame:
    """What tells runs apart in tables and legends: modulator, setting label and gain.

    Parameters
    ----------
    metas : mapping
        Run id -> run metadata with a ``modulator`` mapping.
    ids : sequence of str
        The runs, in the order wanted.

    Returns
    -------
    pandas.DataFrame
        Indexed by run id, with ``modulator`` (type), ``setting`` (its label, or the run id
        when two runs share a label) and ``gain`` (the IPFM/IIPFM gain, 1 for the others).

    Examples
    --------
    >>> m = {"a": {"modulator": {"type": "pwm", "f_w": 20}},
    ...      "b": {"modulator": {"type": "pwm", "f_w": 20}},
    ...      "c": {"modulator": {"type": "iipfm", "t_l": 0.02, "gain": 1.15}}}
    >>> run_tags(m, ["a", "b", "c"])
      modulator           setting  gain
    a       pwm                 a  1.00
    b       pwm                 b  1.00
    c     iipfm  iipfm-20ms-G1.15  1.15
    """
    rows = {}
    for r in ids:
        setting = Modulator.from_mapping(metas[r]["modulator"])
        rows[r] = (setting.kind, setting.label, setting.gain)
    tags = pd.DataFrame.from_dict(rows, orient="index", columns=["modulator", "setting", "gain"])
    shared = tags["setting"].duplicated(keep=False)
    tags.loc[shared, "setting"] = tags.index[shared]
    return tags
