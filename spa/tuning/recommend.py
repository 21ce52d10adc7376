"""Which modulator and setting to use for a valve: the constrained minimum of the cost.

Every setting of the four sweeps is a candidate (:func:`~spa.tuning.candidates.candidate_frame`:
its costs ``J`` and ``J_exact``, its switching rate, chattering, shortest pulse and slowest
response, each a maximum over the input fractions). The constraints of
:class:`~spa.tuning.constraints.TuningOptions` keep the candidates a user accepts;
:func:`recommend` picks the one with the smallest score (``J`` or ``J_exact``), predicts what
it will do (:func:`predict`, including a simulated staircase) and names the constraint that
ruled everything out when nothing is left, recommending then the least-violating setting.

The options, constraints and candidates are defined in :mod:`spa.tuning.constraints` and
:mod:`spa.tuning.candidates` and stay importable from here.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pandas as pd

from spa import _checks as checks
from spa._memo import memoised
from spa.model.averaging import time_constant, time_fractions
from spa.model.modulators import MODULATOR_ORDER, Modulator
from spa.model.params import ValveParams
from spa.model.plant import simulate
from spa.model.thresholds import thresholds
from spa.openloop import staircase_analysis
from spa.synthetic import staircase_input

# Defined with the options and the candidates; importable from here as before.
from spa.tuning.candidates import candidate_frame as candidate_frame
from spa.tuning.candidates import setting_metrics as setting_metrics
from spa.tuning.constraints import CONSTRAINTS as CONSTRAINTS
from spa.tuning.constraints import DEFAULT_CHATTERING_RELATIVE as DEFAULT_CHATTERING_RELATIVE
from spa.tuning.constraints import TuningOptions as TuningOptions
from spa.tuning.constraints import _excluded_by, _least_violating, _violated
from spa.tuning.constraints import violation as violation
from spa.tuning.cost import modulator_settings
from spa.tuning.exact import best_first

__all__ = ["UNITS", "TuningSetup", "predict", "recommend"]

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


@dataclass(frozen=True)
class TuningSetup:
    """The valve and what a recommendation and its predictions are made with.

    Checked once here; :func:`recommend` and :func:`predict` take it as it is.

    Parameters
    ----------
    params : ValveParams
        Valve parameters.
    n_xi : int, default 100
        Points of ``xi`` for the maxima and the ``tau_m`` range (as :func:`candidate_frame`).
    options : TuningOptions, optional
        Score and constraints, and the ``staircase`` simulated; defaults when omitted.
    linearity : mapping, optional
        Keyword arguments of :func:`spa.openloop.staircase_analysis` (``settle``, ...) for
        the predicted staircase metrics; its defaults when empty.

    Raises
    ------
    ValueError
        If ``n_xi`` is not an integer >= 2.

    Examples
    --------
    >>> TuningSetup(ValveParams(), 20).linearity
    {}
    """

    params: ValveParams
    n_xi: int = 100
    options: TuningOptions = field(default_factory=TuningOptions)
    linearity: Mapping[str, float] = field(default_factory=dict)

    def __post_init__(self) -> None:
        object.__setattr__(self, "n_xi", checks.integer("n_xi", self.n_xi, minimum=2))
        object.__setattr__(self, "linearity", dict(self.linearity))


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


_STAIRCASE_METRICS = ("fit", "mse", "max_dev", "mad")


def _staircase(mod: Modulator, params: ValveParams, options: TuningOptions, **analysis: Any):
    """Fit, MSE, max_dev and MAD of a noise-free simulated staircase (Table 3's metrics).

    They depend on the setting, the valve, the staircase and the analysis' settings alone,
    not on the constraints: kept between runs of the pipeline (:mod:`spa._memo`).
    """
    step, dt = (options.staircase[k] for k in ("step", "dt"))
    hold = staircase_hold(options, params)

    def simulated() -> list[float]:
        levels = math.floor(1.0 / step + 1e-9) + 1
        t = np.arange(round(levels * hold / dt)) * dt
        xi = staircase_input(t, step, hold)
        u = mod.bind(params).modulate(xi, dt)
        run = pd.DataFrame({"t": t, "p": simulate(u, dt, params), "valve": u, "u": xi})
        _, _, summary = staircase_analysis(run, mod.to_mapping(), params, **analysis)
        return [float(summary[k]) for k in _STAIRCASE_METRICS]

    key = {"setting": mod.to_mapping(), "params": params, "step": step, "dt": dt,
           "hold": hold, "analysis": analysis}  # fmt: skip
    values = memoised("tuning-staircase", key, simulated)
    out = {k: float(v) for k, v in zip(_STAIRCASE_METRICS, values, strict=True)}
    if hold != float(options.staircase["hold"]):
        out["staircase_hold"] = hold
    return out


def predict(mod: Modulator, setup: TuningSetup) -> dict[str, Any]:
    """What a setting will do on the valve: the ``predicted:`` block of a recommendation.

    Parameters
    ----------
    mod : Modulator
        The setting.
    setup : TuningSetup
        The valve, ``n_xi``, the options (whose ``staircase`` is simulated) and the
        staircase analysis' settings.

    Returns
    -------
    dict
        ``dead_zone``, ``saturation`` (Table 1), ``chattering``, ``switching_rate``,
        ``min_pulse`` (:func:`setting_metrics`), ``tau_m`` (``{min, max}`` of Eq. 9 over the
        ``xi`` where it is defined, s), and ``fit``, ``mse``, ``max_dev``, ``mad`` of the paper's
        staircase simulated with the exact plant, noise-free, analysed like a measured one
        (with ``staircase_hold``, s, where :func:`staircase_hold` lengthened its levels).
    """
    params, n_xi = setup.params, setup.n_xi
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
        **_staircase(mod, params, setup.options, **setup.linearity),
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
    row: pd.Series, setup: TuningSetup, candidates: pd.DataFrame | None = None
) -> dict[str, Any]:
    gain = None if np.isnan(row["gain"]) else float(row["gain"])
    mod = Modulator(
        row["modulator"], modulator_settings(row["modulator"], row["value"], setup.params, gain)
    ).bind(setup.params)
    entry = {
        "modulator": mod.kind,
        "label": mod.label,
        "description": mod.description,
        "setting": mod.to_mapping(),
        "J": float(row["J"]),
        "J_exact": float(row["J_exact"]),
        "predicted": predict(mod, setup),
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


def recommend(candidates: pd.DataFrame, setup: TuningSetup) -> dict[str, Any]:
    """The recommended setting, the runner-up of each other modulator, or why there is none.

    Parameters
    ----------
    candidates : pandas.DataFrame
        :func:`candidate_frame`.
    setup : TuningSetup
        The valve, ``n_xi`` (as :func:`candidate_frame`), the options (score and
        constraints) and what :func:`predict` analyses the staircase with.

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
    params, opts = setup.params, setup.options
    feasible_rows = candidates[candidates["feasible"]]
    best = best_first(feasible_rows, opts.score).drop_duplicates("modulator")
    entries = [_entry(row, setup, candidates) for _, row in best.iterrows()]
    entries = _pass_over(entries, opts.max_fit_shortfall)
    if not entries and not candidates.empty:  # the least-violating usable setting
        found = _least_violating(candidates, opts, params)
        if found is not None:
            row, least = found
            entry = _entry(row, setup)
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
