"""What ``params.yaml`` says about the identified model beyond its parameters: the whiteness of
the closed forms' residuals, the agreement of the repeats, and the sensor's own noise
(:mod:`spa.identification.diagnostics` holds the tests themselves)."""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np
import pandas as pd

from spa.identification.history import HistoryTest
from spa.identification.results import _Z95, IdentificationResult

__all__ = ["closed_form_residuals", "model_checks", "noise_record", "repeat_checks", "rms"]


def rms(residuals: Mapping[str, np.ndarray]) -> float:
    """RMS of every run's residuals together (NaN for none)."""
    if not residuals:
        return math.nan
    return float(np.sqrt(np.mean(np.concatenate([e * e for e in residuals.values()]))))


def repeat_checks(
    result: IdentificationResult, runs: Mapping[str, pd.DataFrame], kinds: Mapping[str, str]
) -> dict[str, Any]:
    """The repeats of the charge and of the discharge, each fitted alone and compared."""
    from spa.identification.diagnostics import repeats_agree
    from spa.identification.rate_fits import DerivativeFit, fit_charge, fit_discharge
    from spa.identification.results import IdentificationError

    s = result.settings
    derivative = DerivativeFit(
        s.get("window", 0.1), s.get("polyorder", 3), s.get("skip", 0.03),
        s.get("onset_fraction", 0.02),
    )  # fmt: skip
    out: dict[str, Any] = {}
    plan = (
        ("charge", ("k2", "tau2"), fit_charge, {"supply_fraction": s.get("supply_fraction", 0.9)}),
        ("discharge", ("c1",), fit_discharge, {"tail_fraction": s.get("tail_fraction", 0.05)}),
    )
    for kind, names, fit, kw in plan:
        ids = sorted(r for r, k in kinds.items() if k == kind and r in runs)
        if len(ids) < 2:
            continue
        per: dict[str, dict[str, float]] = {n: {} for n in names}
        ses: dict[str, dict[str, float]] = {n: {} for n in names}
        failed: dict[str, str] = {}
        for rid in ids:
            try:
                one = fit({rid: runs[rid]}, settings=derivative, **kw)
            except (IdentificationError, ValueError, np.linalg.LinAlgError) as err:
                failed[rid] = str(err)
                continue
            for n in names:
                est = getattr(one, n)
                if est.lo is not None and est.hi is not None and math.isfinite(est.hi):
                    per[n][rid] = est.value
                    ses[n][rid] = (est.hi - est.lo) / (2 * _Z95)
        for n in names:
            check = repeats_agree(n, per[n], ses[n], floor=0.01)
            if check is not None:
                out[n] = check
        if failed and len(failed) < len(ids):
            # the others fit alone and this one does not: it is unlike its repeats
            out[f"{kind}_alone"] = failed
    return out


def closed_form_residuals(result: IdentificationResult) -> dict[str, np.ndarray]:
    """Residuals of the charge and discharge closed forms per run (their fit spans)."""
    out: dict[str, np.ndarray] = {}
    for fit in (result.charge, result.discharge):
        resid = getattr(fit, "residuals", None)
        if resid:
            out.update(resid)
    return out


def noise_record(
    result: IdentificationResult,
    runs: Mapping[str, pd.DataFrame],
    kinds: Mapping[str, str],
    model_residual: float,
) -> dict[str, Any]:
    """``params.yaml``'s ``noise:``: the sensor's noise where nothing moves, and the model's
    residual under its own name."""
    from spa.identification.diagnostics import sensor_noise

    plateaus, moving = [], []
    k2, tau2 = result.k2.value, result.tau2.value
    for rid, table in sorted(runs.items()):
        p = table["p"].to_numpy(dtype=np.float64)
        t = table["t"].to_numpy(dtype=np.float64)
        moving.append(p)
        if kinds.get(rid) != "charge":
            continue
        # The settled tail: at least 6 tau2 after the first sample above half the supply,
        # where the charge is within 0.25 % of k2 (never the zero tail of a discharge).
        half = np.flatnonzero(p > 0.5 * k2)
        if half.size:
            settled = t >= t[half[0]] + 6.0 * tau2
            plateaus.append(p[settled])
    sd, method, bound = sensor_noise(plateaus, moving)
    out: dict[str, Any] = {
        "sensor": None if not math.isfinite(sd) else float(sd),
        "method": method,
        "upper_bound": bool(bound),
    }
    out["model_residual"] = float(model_residual) if math.isfinite(model_residual) else None
    return out


def model_checks(
    result: IdentificationResult,
    runs: Mapping[str, pd.DataFrame],
    kinds: Mapping[str, str],
    residuals: Mapping[str, np.ndarray],
    history: HistoryTest | None = None,
    suggest_laws: bool = False,
) -> dict[str, Any]:
    """The whiteness of the charge and discharge closed forms' residuals, whether the rates
    depend on history (a second state), and the agreement of the repeats.

    The whiteness is tested where one law alone is fitted to one experiment (the charge's
    exponential, the discharge's square root), so that a second state shows as it is (a
    charge that wants two time constants), not the modulated runs' residuals, which also
    carry the jitter of edges logged off the log's ticks and the compromise of one parameter
    set over every run.

    Ljung's test cannot tell a second state from laws other than the plant's: only
    ``history`` (:func:`spa.identification.history.history_test` on the runs with the valve
    command, under the chosen laws) names a second state. ``suggest_laws``: the paper's
    laws were kept without trying the actuator's own (``identification.laws: paper``), so
    rates that depend on the pressure otherwise are pointed to ``laws: auto``.
    """
    from spa.identification.diagnostics import whiteness

    tests = [whiteness(rid, e) for rid, e in sorted(residuals.items()) if e.size]
    # Several runs are tested: each at 1 %/runs, so that a white dataset passes at 1 %.
    level = 0.01 / max(len(tests), 1)
    tests = [whiteness(t.run, residuals[t.run], alpha=level) for t in tests]
    failed = [t.run for t in tests if not t.white]
    repeats = repeat_checks(result, runs, kinds)
    alone = {k: repeats.pop(k) for k in list(repeats) if k.endswith("_alone")}
    disagree = [c for c in repeats.values() if not c.agree]
    sentences = []
    if failed:
        if history is None:
            why = "runs with the valve command would tell a missing state from other laws"
        elif history.second_state:
            why = "not laws alone: the rates depend on history, below"
        else:
            why = (
                "not a missing state: what the time since the last valve edge adds to a law "
                f"of the pressure is {100 * history.history_share:.1f} % of the rate "
                f"(p = {history.p_history:.2g}), under the {100 * history.min_share:.0f} % "
                "that would name one"
            )
        sentences.append(
            f"the model's residuals are not white on run(s) {', '.join(failed)} (Ljung's "
            f"test at 1 %): they carry structure the model misses ({why})"
        )
    said = history.sentence(suggest_laws) if history is not None else ""
    if said:
        sentences.append(said)
    sentences += [c.sentence() for c in disagree]
    for key, runs_failed in alone.items():
        kind = key.removesuffix("_alone")
        for rid, why in sorted(runs_failed.items()):
            sentences.append(
                f"the {kind} run {rid} cannot be fitted alone while its repeats can ({why}): "
                "check that run (a throttled or kinked line, another supply)"
            )
    return {
        "whiteness": {t.run: t.to_dict() for t in tests},
        "white": not failed,
        "history": None if history is None else history.to_dict(),
        "second_state": bool(history is not None and history.second_state),
        "repeats": {n: c.to_dict() for n, c in repeats.items()},
        "repeats_unfitted": {k: dict(v) for k, v in alone.items()},
        "repeats_agree": not disagree and not alone,
        "sentences": sentences,
    }
