"""The three experiments chained: a dataset's runs in, an :class:`IdentificationResult` out."""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import replace
from typing import Any

import numpy as np
import pandas as pd

from spa.identification.delays import _FALLBACK_PRIOR_REL_SD, fit_delays
from spa.identification.rate_fits import DerivativeFit, fit_charge, fit_discharge
from spa.identification.results import (
    _Z95,
    UNITS,
    Estimate,
    IdentificationError,
    IdentificationResult,
    Runs,
)
from spa.model.params import DELAY_CONVENTIONS, ValveParams

__all__ = [
    "identify",
    "identify_runs",
    "identify_with_config",
    "run_context",
]

# --------------------------------------------------------------------------------------------
# The whole identification
# --------------------------------------------------------------------------------------------


def identify(
    charge: Runs | None,
    discharge: Runs | None,
    pulse: Runs | None,
    *,
    window: float = 0.1,
    polyorder: int = 3,
    skip: float = 0.03,
    onset_fraction: float = 0.02,
    tail_fraction: float = 0.05,
    supply_fraction: float = 0.9,
    max_delay: float = 0.05,
    min_edges: int = 3,
    guard: float = 0.03,
    n_boot: int = 200,
    seed: int = 0,
    fallback: ValveParams | None = None,
) -> IdentificationResult:
    """Identify ``c1``, ``k2``, ``tau2``, ``t_on``, ``t_off`` from the three experiments.

    Parameters
    ----------
    charge, discharge, pulse : mapping of run id to table, sequence of tables, or None
        The runs of experiments 1, 2 and 3 (see :func:`fit_charge`, :func:`fit_discharge`,
        :func:`fit_delays`).
    window, polyorder : float, int, optional
        Savitzky–Golay window (s) and order for the derivatives.
    skip, onset_fraction, tail_fraction, supply_fraction : float, optional
        Window choices of the derivative fits (see :func:`fit_charge`, :func:`fit_discharge`).
    max_delay : float, optional
        Largest ``t_on``/``t_off`` searched, s.
    min_edges : int, optional
        Responding rising/falling edges needed for ``t_on``/``t_off``.
    guard : float, optional
        Time after every command edge of the pulse runs left out of the delay fit, s
        (sensor ringing; see :func:`fit_delays`).
    n_boot, seed : int, optional
        Not used: every interval now comes from a fit covariance and the result is
        deterministic; kept (``n_boot`` checked >= 20, both recorded in ``settings``) so
        that configurations written for the earlier bootstrap stay valid.
    fallback : ValveParams, optional
        Nominal parameters. Without it any experiment that cannot support its fit raises
        :class:`IdentificationError`. With it, the parameters of that experiment take the
        nominal values instead, and ``result.fallback`` records which and why.

    Returns
    -------
    IdentificationResult

    Raises
    ------
    IdentificationError
        When data are missing or insufficient and no ``fallback`` is given; the message names
        the experiment and what is missing.
    ValueError
        For an invalid setting (the message names it).

    Notes
    -----
    ``t_on``/``t_off`` come last: their fit re-fits ``c1``, ``k2``, ``tau2`` as nuisance
    parameters tied to the experiment 1–2 values by their standard errors (20 %
    for a fallback value).
    """
    settings: dict[str, Any] = {
        "window": float(window),
        "polyorder": int(polyorder),
        "skip": float(skip),
        "onset_fraction": float(onset_fraction),
        "tail_fraction": float(tail_fraction),
        "supply_fraction": float(supply_fraction),
        "max_delay": float(max_delay),
        "min_edges": int(min_edges),
        "guard": float(guard),
        "n_boot": int(n_boot),
        "seed": int(seed),
    }
    derivative = DerivativeFit(window, polyorder, skip, onset_fraction)
    if not (isinstance(n_boot, int | np.integer) and n_boot >= 20):
        raise ValueError(f"n_boot must be an integer >= 20, got {n_boot!r}")
    reasons: dict[str, str] = {}

    def nominal(name: str, reason: str) -> Estimate:
        assert fallback is not None
        reasons[name] = reason
        return Estimate(
            getattr(fallback, name), None, None, UNITS[name], (), "fallback", fallback=reason
        )

    def attempt(fit: Callable[..., Any], names: tuple[str, ...], *args: Any, **kw: Any) -> Any:
        """``fit(*args, **kw)`` and its estimates ``names``; the fallback's when it fails."""
        try:
            result = fit(*args, **kw)
        except IdentificationError as err:
            if fallback is None:
                raise
            return None, [nominal(name, str(err)) for name in names]
        return result, [getattr(result, name) for name in names]

    cf, (k2, tau2) = attempt(
        fit_charge, ("k2", "tau2"), charge or {},
        settings=derivative, supply_fraction=supply_fraction,
    )  # fmt: skip
    df, (c1,) = attempt(
        fit_discharge, ("c1",), discharge or {},
        settings=derivative, tail_fraction=tail_fraction,
    )  # fmt: skip

    prior_sd = {}
    for name, est in (("c1", c1), ("k2", k2), ("tau2", tau2)):
        if est.lo is not None and est.hi is not None and est.hi > est.lo:
            prior_sd[name] = (est.hi - est.lo) / (2 * _Z95)
        else:
            prior_sd[name] = _FALLBACK_PRIOR_REL_SD * est.value
    start = ValveParams(c1.value, k2.value, tau2.value)  # t_on, t_off: found by grid search
    dfit, (t_on, t_off) = attempt(
        fit_delays, ("t_on", "t_off"), pulse or {}, start,
        prior_sd=prior_sd, max_delay=max_delay, min_edges=min_edges, guard=guard,
    )  # fmt: skip
    return IdentificationResult(
        c1=c1,
        k2=k2,
        tau2=tau2,
        t_on=t_on,
        t_off=t_off,
        charge=cf,
        discharge=df,
        delays=dfit,
        fallback=reasons,
        settings=settings,
    )


def identify_runs(
    runs: Mapping[str, pd.DataFrame], kinds: Mapping[str, str], **kwargs: Any
) -> IdentificationResult:
    """:func:`identify` on a collection of runs of mixed kinds.

    Parameters
    ----------
    runs : mapping of run id to table
        All runs; those whose kind is not ``charge``, ``discharge`` or ``pulse`` are ignored.
    kinds : mapping of run id to kind
        Kind of every run.
    **kwargs
        Passed on to :func:`identify`.

    Returns
    -------
    IdentificationResult

    Raises
    ------
    ValueError
        If a run has no kind.
    """
    missing = sorted(set(runs) - set(kinds))
    if missing:
        raise ValueError(f"kinds has no entry for run(s) {missing}")
    groups: dict[str, dict[str, pd.DataFrame]] = {"charge": {}, "discharge": {}, "pulse": {}}
    for rid, table in runs.items():
        if kinds[rid] in groups:
            groups[kinds[rid]][rid] = table
    return identify(groups["charge"], groups["discharge"], groups["pulse"], **kwargs)


def identify_with_config(
    runs: Mapping[str, pd.DataFrame],
    kinds: Mapping[str, str],
    config: Mapping[str, Any] | None = None,
    seed: int | None = None,
    *,
    modulators: Mapping[str, str] | None = None,
    command_dt: Mapping[str, float] | None = None,
    metas: Mapping[str, Mapping[str, Any]] | None = None,
) -> IdentificationResult:
    """:func:`identify_runs` with the sections of a pipeline configuration, as the workflow's
    identify rule runs it (and ``spa identify``).

    Parameters
    ----------
    runs, kinds
        As :func:`identify_runs`.
    config : mapping, optional
        A configuration (``config/config.yaml``): its ``identification`` section (``savgol``,
        ``use_fallback`` and the keyword arguments of :func:`identify`), ``nominal`` (the
        fallback's values) and ``seed``; :func:`identify`'s defaults where absent.
    seed : int, optional
        Recorded in ``settings`` (not used by the fits); default the configuration's
        ``seed``, else 0.
    modulators, command_dt : mapping, optional
        Run id → modulator type and → the command's own step (s), for
        :func:`~spa.identification.refined.refine_result`, which runs after the three fits
        unless ``identification.refine`` is false (``identification.adequacy_threshold``: its
        threshold).
    metas : mapping, optional
        Run id → the run's metadata (:func:`spa.datasets.read_runs`): the modulators, command
        steps and declared ``valve_edges`` are read from it (``modulators`` and
        ``command_dt`` then default to :func:`run_context`'s), and each run's edge-timing
        rule is decided (:func:`spa.identification.edges.dataset_edge_timing`).

    Returns
    -------
    IdentificationResult

    Raises
    ------
    IdentificationError, ValueError
        As :func:`identify`; ``use_fallback`` without ``nominal`` is a ValueError.
    """
    config = config or {}
    cfg = dict(config.get("identification") or {})
    threshold = float(cfg.pop("adequacy_threshold", 80.0))
    if not (math.isfinite(threshold) and 0.0 < threshold <= 100.0):
        raise ValueError(
            f"identification.adequacy_threshold must be in (0, 100] %, got {threshold!r}"
        )
    do_refine = bool(cfg.pop("refine", True))
    convention = str(cfg.pop("delay_convention", "auto"))
    laws = str(cfg.pop("laws", "auto"))
    if laws not in ("auto", "paper"):
        raise ValueError(f"identification.laws must be auto or paper, got {laws!r}")
    if convention not in ("auto", *DELAY_CONVENTIONS):
        raise ValueError(
            f"identification.delay_convention must be auto, hold or transport, got {convention!r}"
        )
    use_fallback = bool(cfg.pop("use_fallback", False))
    savgol = dict(cfg.pop("savgol", None) or {})
    fallback = None
    if use_fallback:
        if "nominal" not in config:
            raise ValueError("identification.use_fallback needs the config's nominal: section")
        fallback = ValveParams(**config["nominal"])
    seed = int(config.get("seed", 0) if seed is None else seed)
    search = False
    try:
        result = identify_runs(runs, kinds, **savgol, **cfg, seed=seed, fallback=fallback)
    except IdentificationError as err:
        # Without a usable pulse run the refinement can still find the delays from the other
        # runs' edges: it then searches them itself (no nominal value is kept).
        if not do_refine or fallback is not None or not str(err).startswith(_DELAY_ERRORS):
            raise
        result = identify_runs(runs, kinds, **savgol, **cfg, seed=seed, fallback=ValveParams())
        if set(result.fallback) - {"t_on", "t_off"}:
            raise
        search = True
    if not do_refine:
        return result
    from spa.identification.edges import dataset_edge_timing
    from spa.identification.refined import refine_result

    edges = None
    if metas is not None:
        context = run_context(metas)
        modulators = context[0] if modulators is None else modulators
        command_dt = context[1] if command_dt is None else command_dt
        edges = dataset_edge_timing(runs, metas)
    try:
        return refine_result(
            result,
            runs,
            kinds,
            modulators=modulators,
            command_dt=command_dt,
            threshold=threshold,
            max_delay=float(cfg.get("max_delay", 0.05)),
            search_delays=search,
            convention=convention,
            edges=edges,
            laws=laws,
        )
    except (ValueError, FloatingPointError, np.linalg.LinAlgError) as err:
        if search:  # no estimate of the delays at all: nothing to fall back on
            raise IdentificationError(f"the refinement failed ({err}) and no pulse fit") from err
        note = f"the refinement failed ({err}): the charge, discharge and pulse fits are kept"
        return replace(result, warnings=(*result.warnings, note))


def run_context(
    metas: Mapping[str, Mapping[str, Any]],
) -> tuple[dict[str, str], dict[str, float]]:
    """Each run's modulator type and command step, from :func:`spa.datasets.read_runs`' metadata.

    Returns
    -------
    modulators : dict
        Run id → modulator type (``""`` for none).
    command_dt : dict
        Run id → ``controller_dt`` (s), for the runs whose metadata give it.

    Examples
    --------
    >>> run_context({"a": {"modulator": {"type": "pwm", "f_w": 20}, "controller_dt": 0.001},
    ...              "b": {}})
    ({'a': 'pwm', 'b': ''}, {'a': 0.001})
    """
    modulators = {}
    for rid, meta in metas.items():
        mod = meta.get("modulator")
        kind = getattr(mod, "kind", None) or (mod.get("type") if isinstance(mod, Mapping) else "")
        modulators[rid] = str(kind or "")
    command_dt = {
        rid: float(meta["controller_dt"])
        for rid, meta in metas.items()
        if meta.get("controller_dt")
    }
    return modulators, command_dt


# How the pulse fit's errors start (spa.identification.delays): the delays alone are missing.
_DELAY_ERRORS = ("no pulse run", "pulse run")
