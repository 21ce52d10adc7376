"""The three fits refined on every run with a valve command, and what the data can and cannot say.

:func:`refine_result` runs the output-error refinement (:mod:`spa.identification.refine`) in
both delay conventions, chooses one, and turns its fit into the five estimates of
``params.yaml``: each with the interval it really has (a delay the log cannot resolve is an
interval, never a point; a fallback is marked as one), the edge-timing rule of the logged
valve (:mod:`spa.identification.edges`), the model's adequacy and its statistical checks
(:mod:`spa.identification.diagnostics`), and the sensor's noise.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import replace
from typing import Any

import numpy as np
import pandas as pd

from spa.identification.convention import choose_convention
from spa.identification.edge_local import edge_delays, edge_priors, edges_convention
from spa.identification.edges import EdgeTiming, summary
from spa.identification.history import full_rate_records, history_test
from spa.identification.model_checks import (
    closed_form_residuals,
    model_checks,
    noise_record,
    rms,
)
from spa.identification.results import _Z95, UNITS, Estimate, IdentificationResult

__all__ = ["refine_result", "unresolved_delays"]

#: The delays and the direction of the command edge that shows each.
_DELAY_EDGE = {"t_on": "rising", "t_off": "falling"}


def _hz(x: float) -> str:
    return f"{x:.0f} Hz" if x >= 10 else f"{x:.2g} Hz"


def _record_advice(name: str, dt: float | None) -> str:
    """What to record so that ``name`` is resolved, in terms of the log."""
    what = _DELAY_EDGE[name]
    clock = (
        f" (this log's step is {1e3 * dt:.3g} ms: the delay is found below one step once the "
        "edge is in the log, and the logging rate then sets only its precision)"
        if dt
        else ""
    )
    return (
        f"log the valve command beside the pressure, on the pressure's clock, in runs with "
        f"{what} edges followed by a visible response (a pulse train){clock}"
    )


def unresolved_delays(
    max_delay: float, reason: str, dt: float | None = None
) -> tuple[dict[str, Estimate], list[str]]:
    """Both delays as the whole searched interval ``[0, max_delay]``, unresolved.

    Parameters
    ----------
    max_delay : float
        The identification's ``max_delay``, s.
    reason : str
        Why the data do not show them (e.g. "no run carries the valve command").
    dt : float, optional
        The log's step, s, for the advice.

    Returns
    -------
    estimates : dict
        ``t_on``, ``t_off`` at their design value, the interval's worst case ``max_delay``.
    warnings : list of str
        One per delay, naming what to record.

    Examples
    --------
    >>> ests, notes = unresolved_delays(0.05, "no valve edge in any run")
    >>> ests["t_on"].lo, ests["t_on"].hi, ests["t_on"].resolved
    (0.0, 0.05, False)
    """
    ests, notes = {}, []
    for name in _DELAY_EDGE:
        ests[name] = Estimate(
            max_delay,
            0.0,
            max_delay,
            UNITS[name],
            (),
            f"not resolved ({reason}): the interval [0, max_delay]; designs use its worst "
            "case, the upper end",
            resolved=False,
        )
        notes.append(
            f"{name} is not resolved: {reason}. Designs use the interval "
            f"[0, {1e3 * max_delay:g}] ms (its worst case); to resolve it, "
            f"{_record_advice(name, dt)}."
        )
    return ests, notes


def refine_result(
    result: IdentificationResult,
    runs: Mapping[str, pd.DataFrame],
    kinds: Mapping[str, str],
    *,
    modulators: Mapping[str, str] | None = None,
    command_dt: Mapping[str, float] | None = None,
    threshold: float = 80.0,
    max_delay: float = 0.05,
    search_delays: bool = False,
    convention: str = "auto",
    edges: Mapping[str, EdgeTiming] | None = None,
    laws: str = "auto",
) -> IdentificationResult:
    """Refine ``result`` on every run with a valve command; conventions, laws, adequacy,
    warnings.

    Parameters
    ----------
    result : IdentificationResult
        The charge, discharge and pulse fits' result (the refinement's start).
    runs, kinds : mapping
        All runs of the dataset and their kinds.
    modulators : mapping, optional
        Run id → modulator type (``""`` or absent for none).
    command_dt : mapping, optional
        Run id → the command's own step, s (when known, e.g. a simulated controller's).
    threshold : float, optional
        ``identification.adequacy_threshold``, % of the noise ceiling.
    max_delay : float, optional
        Largest delay, s.
    search_delays : bool, optional
        The pulse fit gave no delays: start from a coarse search of each delay over
        ``[0, max_delay]`` on the runs' cycle means instead of ``result``'s values.
    convention : {"auto", "hold", "transport"}, optional
        ``identification.delay_convention``; ``"auto"`` chooses it (:func:`choose_convention`).
    edges : mapping, optional
        Run id → its edge-timing rule (:func:`spa.identification.edges.dataset_edge_timing`);
        a run without one is decided from ``command_dt`` alone.
    laws : {"auto", "paper"}, optional
        ``identification.laws``: ``"auto"`` fits the actuator's own charge and discharge
        laws and keeps them only where the held-out modulated runs demand them
        (:func:`spa.identification.laws_fit.choose_laws`); ``"paper"`` keeps the paper's.

    Returns
    -------
    IdentificationResult
        The five parameters from the chosen convention's refinement, ``refinement``,
        ``delay_convention``, ``adequacy``, ``checks``, ``noise``, ``valve_edges`` and
        ``warnings`` filled in. When no run carries a valve command, the three fits' values
        with the delays unresolved (``[0, max_delay]``).

    Notes
    -----
    *Delays and the log's clock.* A logged edge is the true edge when the command was issued
    on a logging tick (``valve_edges: on_tick``). When the command ran on its own faster
    clock (``sampled``), the true edge lies uniformly within the step before the logged one:
    the refinement takes it at the middle of that step and adds ``w**2/12`` to the delay's
    variance. When the data cannot tell (``undecided``), the edge is taken on the tick and
    the interval reaches one step ``w`` above the estimate (one-sided).

    A delay the data cannot resolve (no command edge in its direction, an interval wider than
    half of ``[0, max_delay]``, or within a logging step of 0) is reported as an interval with
    ``resolved: false``; every design downstream then uses the interval (its worst case, the
    upper end, and the box's corners), never a point. No estimate lies outside its interval,
    and no interval outside ``[0, max_delay]``.
    """
    from spa.identification.adequacy import assess
    from spa.identification.delay_search import delay_search
    from spa.identification.laws_record import laws_record
    from spa.identification.refine import NAMES, prepare_runs, refine

    prepared = prepare_runs(runs, kinds, modulators, command_dt, edges=edges)
    if not prepared:
        return _without_command(result, runs, kinds, max_delay)
    start = result.to_valve_params()
    if search_delays:
        start = delay_search(prepared, start, max_delay)
        warnings_start = [
            "the pulse fit gave no delays ("
            + "; ".join(sorted({result.fallback[n] for n in _DELAY_EDGE if n in result.fallback}))
            + "): t_on and t_off come from the refinement on the other runs' edges"
        ]
    else:
        warnings_start = []
    at_edges = edge_delays(prepared, runs, start, max_delay=max_delay)
    priors = edge_priors(at_edges)
    fits = {
        d: refine(prepared, start, delay=d, max_delay=max_delay, delay_prior=priors.get(d))
        for d in ("hold", "transport")
    }
    held_median = {d: f.heldout_median() for d, f in fits.items()}
    mods_of = {r.rid: r.modulator for r in prepared}
    verdicts = {
        d: assess(f.fit_heldout, f.fit_after, f.noise_ceiling, mods_of, threshold)
        for d, f in fits.items()
    }
    by_fit = choose_convention(
        {d: a.heldout_median for d, a in verdicts.items()}, held_median, convention
    )
    chosen, chosen_by, note = edges_convention(by_fit, priors, convention, at_edges)
    warnings_start += note
    ref = fits[chosen]
    dt = float(np.median([r.dt for r in prepared]))
    n_edges = {
        "t_on": sum(r.n_on for r in prepared),
        "t_off": sum(r.n_off for r in prepared),
    }
    warnings = [*result.warnings, *warnings_start]
    ests = {}
    runs_all = tuple(r.rid for r in prepared)
    fallback = {}
    for name in NAMES:
        value = float(getattr(ref.params, name))
        se = float(ref.se[name])
        informed = tuple(ref.informed[name])
        method = (
            f"output-error refinement of the exact model ({chosen} convention) on the cycle means "
            f"of {len(prepared)} run(s) with a valve command, from the charge/discharge/pulse "
            "estimates; 95% from the sandwich covariance (Newey-West, bandwidth from the "
            "data), widened to the leave-one-run-out spread"
        )
        if name in result.fallback and name not in _DELAY_EDGE:
            # Started from a nominal value, not an estimate: its distance to the data says
            # nothing about the error. Refined only where runs inform it; else the fallback
            # stays, its value the nominal one (the top-level fallback lists only those).
            if not informed:
                fallback[name] = result.fallback[name]
                old = getattr(result, name)
                ests[name] = replace(old, method=old.method + "; no run informs it")
                continue
            method += f"; started from the fallback ({result.fallback[name]})"
        elif name not in _DELAY_EDGE:
            # Two estimators of one parameter (the experiment's own fit and the refinement on
            # every run) that disagree by more than their errors show model error: it is added.
            gap = value - float(getattr(start, name))
            se = math.sqrt(se * se + gap * gap)
            method += " and by the gap to the start"
        if name in _DELAY_EDGE:
            if chosen in priors:
                used = at_edges.record()["edges_on" if name == "t_on" else "edges_off"]
                method = (
                    f"common delay of {used} command edges ({chosen} form: the old state's "
                    "closed form before the edge, the new state's after the delay; the "
                    "edges' summed squared residuals); 95% from the larger of that fit's "
                    "and the runs' own delays' standard errors"
                )
            est, notes = _delay_estimate(
                name, value, se, method, informed or runs_all, prepared, start,
                n_edges[name], dt, max_delay, chosen,
                (name in result.fallback and not search_delays) or chosen in priors,
            )  # fmt: skip
            fb = result.fallback.get(name)
            if fb is not None and not search_delays and est.resolved:
                est = replace(est, fallback=f"started from the nominal value ({fb}); refined")
            est = replace(est, spread=getattr(result, name).spread)
            warnings += notes
            ests[name] = est
            continue
        lo, hi = max(value - _Z95 * se, 0.0), value + _Z95 * se
        old = getattr(result, name)
        fb = result.fallback.get(name)
        ests[name] = Estimate(
            value, lo, hi, UNITS[name], informed or runs_all, method, spread=old.spread,
            fallback=None if fb is None else f"started from the nominal value ({fb}); refined",
        )  # fmt: skip
    warnings += bound_warnings(ests, max_delay, dt)
    difference = _difference(ests, ref, chosen, n_edges, prepared, chosen in priors)
    law_record, law_valve = laws_record(prepared, ref, chosen, laws, held_delays=priors.get(chosen))
    if result.delays is not None:
        pulse = result.delays.summary()
        for key, name, what in (
            ("n_edges_on", "t_on", "rising"),
            ("n_edges_off", "t_off", "falling"),
        ):
            if int(pulse.get(key, 1)) == 0:
                warnings.append(
                    f"the pulse runs have no {what} edge with a visible response "
                    f"({key}: 0): {name} comes from the other runs' edges only; record a "
                    f"pulse train whose {what} edges move the pressure"
                )
    adequacy = verdicts[chosen]
    if law_valve is not None:
        # Every stage reads the laws valve back (read_identified), so the verdict they
        # consult is the chosen model's: its held-out FITs on the modulated runs (each
        # predicted by the laws refitted without it) and its in-sample FITs.
        paper = adequacy
        adequacy = assess(
            law_record["fit_identified"], law_record["fit_insample"], ref.noise_ceiling,
            mods_of, threshold,
        )  # fmt: skip
        note = (
            f"The actuator's own laws describe the modulated runs better and are the model "
            f"used: held-out FIT {adequacy.heldout_median:.0f} % (median) against "
            f"{paper.heldout_median:.0f} % with the paper's"
        )
        adequacy = replace(adequacy, sentence=f"{adequacy.sentence} {note}.")
        warnings.append(f"{law_record['reason']}. {note}")
    other_name = "transport" if chosen == "hold" else "hold"
    other = verdicts[other_name]
    if not adequacy.adequate and other.adequate:
        what = {
            "transport": "the transport-delay convention (the valve keeps its previous "
            "connection during its dead time)",
            "hold": "the paper's hold convention",
        }
        better = (
            f"{what[other_name]} describes the runs the designs are for: held-out FIT "
            f"{other.heldout_median:.0f} % against {adequacy.heldout_median:.0f} % for "
            f"{what[chosen]}, which identification.delay_convention sets and the tuning and "
            "the closed loop use; their results on this valve are not verified"
        )
        adequacy = replace(adequacy, sentence=f"{adequacy.sentence} But {better}.")
        warnings.append(better)
    resid = {r.rid: r.y - m for r, m in zip(prepared, ref.final_models(), strict=True)}
    model = law_valve if law_valve is not None else ref.params
    history = history_test(full_rate_records(runs, prepared), model)
    checks = model_checks(
        result, runs, kinds, closed_form_residuals(result), history, laws == "paper"
    )
    adequacy = adequacy.with_checks(checks)
    warnings += checks["sentences"]
    model_rms = rms(resid)

    def clean(d: Mapping[str, float]) -> dict[str, float | None]:
        return {k: (round(float(v), 3) if math.isfinite(v) else None) for k, v in d.items()}

    refinement = {
        "start": {n: float(getattr(start, n)) for n in NAMES},
        "informed_by": {n: list(ref.informed[n]) for n in NAMES},
        "fit_before": clean(ref.fit_before),
        "fit_after": clean(ref.fit_after),
        "fit_heldout": clean(ref.fit_heldout),
        "noise_ceiling": clean(ref.noise_ceiling),
        "se": {n: float(ref.se[n]) for n in NAMES if math.isfinite(ref.se.get(n, math.nan))},
        **(
            {"correlation": {"names": list(NAMES), "matrix": [list(r) for r in ref.correlation]}}
            if ref.correlation
            else {}
        ),
        "bandwidth_blocks": {k: int(v) for k, v in ref.bandwidth.items()},
        "block_samples": {r.rid: int(r.block * r.stride) for r in prepared},
        "n_edges_on": int(n_edges["t_on"]),
        "n_edges_off": int(n_edges["t_off"]),
        "simulations": int(sum(f.nfev for f in fits.values())),
        "converged": bool(ref.converged),
    }
    record = {
        "chosen": chosen,
        **{
            d: {"t_on": float(f.params.t_on), "t_off": float(f.params.t_off)}
            for d, f in fits.items()
        },
        "heldout_fit": {
            d: (round(v, 3) if math.isfinite(v) else None) for d, v in held_median.items()
        },
        "heldout_fit_modulated": {
            d: (round(a.heldout_median, 3) if math.isfinite(a.heldout_median) else None)
            for d, a in verdicts.items()
        },
        "setting": convention,
        "chosen_by": chosen_by,
        "edges": at_edges.record(),
    }
    if n_edges["t_on"] == 0 or n_edges["t_off"] == 0:
        record["note"] = "a delay is unresolved; the conventions differ only in it"
    if result.fallback:
        refinement["started_from_fallback"] = dict(result.fallback)
    return replace(
        result,
        **ests,
        fallback=fallback,
        settings={**result.settings, "refine": True, "adequacy_threshold": float(threshold)},
        refinement=refinement,
        delay_convention=record,
        delay_difference=difference,
        adequacy=adequacy.to_dict(),
        checks=checks,
        noise=noise_record(result, runs, kinds, model_rms),
        valve_edges=summary({r.rid: r.timing for r in prepared}),
        laws=law_record,
        warnings=tuple(dict.fromkeys(warnings)),
    )


def _without_command(
    result: IdentificationResult,
    runs: Mapping[str, pd.DataFrame],
    kinds: Mapping[str, str],
    max_delay: float,
) -> IdentificationResult:
    """No run carries the valve command: the three fits stand, the delays are unresolved,
    and the closed forms' residuals are checked."""
    note = "no run carries the valve command: the refinement and the adequacy were skipped"
    warnings = [*result.warnings, note]
    ests: dict[str, Estimate] = {}
    fallback = dict(result.fallback)
    if result.delays is None:
        dts = [float(np.median(np.diff(t["t"].to_numpy()))) for t in runs.values() if len(t) > 1]
        reason = "no run carries the valve command, so no edge shows when the valve switched"
        ests, notes = unresolved_delays(max_delay, reason, float(np.median(dts)) if dts else None)
        warnings += notes
        for name in _DELAY_EDGE:
            fallback.pop(name, None)
    resid = closed_form_residuals(result)
    checks = model_checks(result, runs, kinds, resid)
    warnings += checks["sentences"]
    model_rms = rms(resid)
    from spa.identification.adequacy import Adequacy

    adequacy = Adequacy(
        sentence="Model adequacy not assessed: no run carries the valve command, so no run "
        "can be predicted from the others' parameters; the modulated use is not assessed.",
        modulated_assessed=False,
    ).with_checks(checks)
    return replace(
        result,
        **ests,
        fallback=fallback,
        adequacy=adequacy.to_dict(),
        checks=checks,
        noise=noise_record(result, runs, kinds, model_rms),
        warnings=tuple(dict.fromkeys(warnings)),
    )


def _delay_estimate(
    name: str,
    value: float,
    se: float,
    method: str,
    informed: tuple[str, ...],
    prepared: list[Any],
    start: Any,
    edges: int,
    dt: float,
    max_delay: float,
    chosen: str,
    without_gap: bool,
) -> tuple[Estimate, list[str]]:
    """One delay's estimate and interval under the edge-timing rule; unresolved when the
    log does not show it."""
    rising = name == "t_on"
    what = _DELAY_EDGE[name]
    with_edges = [r for r in prepared if (r.n_on if rising else r.n_off) > 0]
    shifts = [
        float(np.mean(r.edge_shift[1:][r.level[1:] == rising]))
        for r in with_edges
        if np.any(r.level[1:] == rising)
    ]
    shift = float(np.mean(shifts)) if shifts else 0.0
    sampled = [r.edge_width for r in with_edges if r.timing.rule == "sampled"]
    undecided = [r.edge_width for r in with_edges if r.timing.rule == "undecided"]
    if not without_gap:  # a fallback start, or delays read at the edges
        # Within one sample step, the gap to the pulse fit (on the logged edges) is the
        # edges' timing resolution, and counts.
        gap = min(abs(value - float(getattr(start, name)) - shift), dt)
        se = math.sqrt(se * se + gap * gap)
        method += "; by the gap to the start up to one sample step"
    if sampled:
        w = max(sampled)
        se = math.sqrt(se * se + w * w / 12.0)
        method += (
            f"; logged edges off the log's ticks taken at the middle of their "
            f"{1e3 * w:.3g} ms step (w^2/12 added)"
        )
    lo, hi = value - _Z95 * se, value + _Z95 * se
    notes: list[str] = []
    if undecided:
        w = max(undecided)
        hi += w
        method += (
            f"; the logged edges' timing is undecided (valve_edges not declared, and the data "
            f"cannot tell): one-sided, the true edges up to {1e3 * w:.3g} ms before the "
            "logged ones"
        )
        notes.append(
            f"{name}: whether the valve command was issued on the log's tick is not declared "
            f"and the runs cannot tell; its interval reaches one logging step "
            f"({1e3 * w:.3g} ms) above the estimate. Declare valve_edges: on_tick (the "
            "controller logs on its own tick) or sampled in dataset.yaml."
        )
    resolved = True
    if edges == 0:
        reason = f"no {what} valve edge in any run"
        ests, more = unresolved_delays(max_delay, reason, dt)
        return ests[name], [more[0 if rising else 1]]
    if _Z95 * se > max_delay / 4.0:
        resolved = False
        lo, hi = 0.0, max_delay
        notes.append(
            f"{name} is not resolved: the runs' {what} edges do not show it (95 % half-width "
            f"{1e3 * _Z95 * se:.3g} ms). Designs use the interval [0, {1e3 * max_delay:g}] ms "
            f"(its worst case); to resolve it, {_record_advice(name, dt)}."
        )
        method += f"; unresolved (the {what} edges do not show it): [0, max_delay]"
        value = max_delay
    elif lo <= 0.0:
        # With the edge in the log the output-error fit resolves a delay below one step; a
        # delay whose interval reaches 0 is not told from none.
        resolved = False
        lo, hi = 0.0, max(hi, 2.0 * dt)
        notes.append(
            f"{name} is not resolved: its interval reaches 0 ({1e3 * value:.2g} ms, logging "
            f"step {1e3 * dt:.3g} ms); log pressure and valve command at "
            f">= {_hz(4.0 / max(value + dt, dt))} to resolve it. Designs use the "
            f"interval [0, {1e3 * min(hi, max_delay):.3g}] ms (its worst case)."
        )
        method += "; unresolved (its interval reaches 0)"
    # No estimate outside its own bounds, no bound outside the searched domain.
    lo, hi = max(lo, 0.0), min(hi, max_delay)
    value = min(max(value, lo), hi)
    return (
        Estimate(value, lo, hi, UNITS[name], informed, method, resolved=resolved),
        notes,
    )


def _difference(
    ests: Mapping[str, Estimate],
    ref: Any,
    chosen: str,
    n_edges: Mapping[str, int],
    prepared: list[Any],
    from_edges: bool = False,
) -> Estimate | None:
    """``t_off - t_on`` of a transport valve with both directions' edges: its own interval.

    With ``from_edges`` the delays were read at the command edges, each direction on its
    own edges: their errors are independent and the difference's variance is their sum.

    The difference is known whenever both directions have edges, even when a delay is not
    resolved on its own: a lag the model does not have (a sensor's, a long line's) moves both
    delays together and leaves their difference (the corners clip at 0). Under the transport
    convention the averaged model moves with ``t_off - t_on`` (the time a pulse gains), the
    loop's dead time with the delays themselves: the box spans both
    (:func:`spa.identification.identified.corners`).
    """
    if not (chosen == "transport" and n_edges["t_on"] > 0 and n_edges["t_off"] > 0):
        return None
    if not math.isfinite(ref.se_difference):
        return None
    widths = [r.edge_width for r in prepared if r.timing.rule == "sampled"]
    w = max(widths, default=0.0)
    d_value = ests["t_off"].value - ests["t_on"].value
    d_se = math.sqrt(ref.se_difference**2 + 2.0 * w * w / 12.0)
    return Estimate(
        d_value,
        d_value - _Z95 * d_se,
        d_value + _Z95 * d_se,
        "s",
        tuple(sorted(set(ests["t_on"].runs) | set(ests["t_off"].runs))),
        (
            "the two delays read at the command edges, independent (the sum of their variances)"
            if from_edges
            else "the refinement's sandwich covariance of the two delays (Newey-West), "
            "widened to the leave-one-run-out spread of their difference"
        )
        + "; logged edges off the log's ticks uniform within their step",
    )


def bound_warnings(
    estimates: Mapping[str, Estimate], max_delay: float, dt: float | None
) -> list[str]:
    """A sentence for each resolved delay whose estimate reaches the searched bound
    ``max_delay`` (within one logging step ``dt``, or 0.1 ms): the fit pressed against the
    bound, so the valve's delay may be longer, or the delay stands in for what the model
    misses (a tube, a sensor's lag, the actuator's laws).

    Examples
    --------
    >>> est = {"t_on": Estimate(0.0498, 0.0397, 0.05, "s"),
    ...        "t_off": Estimate(0.01, 0.009, 0.011, "s")}
    >>> [w[:44] for w in bound_warnings(est, 0.05, 0.002)]
    ['t_on = 49.8 ms reaches the search bound max_']
    """
    tol = max(float(dt or 0.0), 1e-4)
    out = []
    for name in ("t_on", "t_off"):
        est = estimates.get(name)
        if est is None or not est.resolved or est.fallback:
            continue
        if est.value >= max_delay - tol:
            out.append(
                f"{name} = {1e3 * est.value:.3g} ms reaches the search bound max_delay = "
                f"{1e3 * max_delay:g} ms (95 % interval "
                f"[{1e3 * (est.lo or 0.0):.3g}, {1e3 * (est.hi or max_delay):.3g}] ms): the "
                "valve's delay may be longer, or the fit stands in for what the model misses "
                "(a tube, a sensor's lag, the actuator's laws); raise identification.max_delay "
                "to see which, and read the designs that use it as unverified"
            )
    return out
