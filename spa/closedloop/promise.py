"""The closed-loop stage's promise, made for a dataset and checked on a plant.

:func:`design_for_dataset` runs what the ``closed_loop`` stage runs for one dataset (the
designs, the model error measured on its staircases, the promise over the merged box and the
header), from an identification's ``params.yaml`` content and the dataset's runs, so that a
test or a benchmark makes the same controller as the pipeline. :func:`promise_kept` compares
a staircase measured on a plant (``spa.synthetic.physical.measure_staircase``) with the
promise in ``controllers.yaml`` (``bench.promise``).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from typing import Any

import pandas as pd

from spa.closedloop.bench import BenchOutputs, _chosen
from spa.closedloop.controller import PIController
from spa.closedloop.pulses import RecordedPulses, loop_pulses, pulse_clause, recorded_settings
from spa.model.modulators import Modulator

__all__ = [
    "OVERSHOOT_MARGIN",
    "RIPPLE_FACTOR",
    "SETTLE_BAND",
    "checked_first",
    "design_for_dataset",
    "promise_kept",
]

#: Percentage points by which the overshoot on the plant may exceed the promised one.
OVERSHOOT_MARGIN = 5.0
#: %: every level must end within this share of its step (the mean over the last quarter).
SETTLE_BAND = 2.0
#: A ripple beyond this many times the promised one is a limit cycle the promise did not make.
RIPPLE_FACTOR = 2.0


def design_for_dataset(
    identified: Mapping[str, Any],
    runs: Mapping[str, pd.DataFrame],
    metas: Mapping[str, Mapping[str, Any]],
    selected: Iterable[Mapping[str, Any]],
    cfg: Mapping[str, Any] | None = None,
    recommendation: Mapping[str, Any] | None = None,
    *,
    valve: Any = None,
) -> tuple[Any, BenchOutputs]:
    """The ``closed_loop`` stage of one dataset, in memory.

    Parameters
    ----------
    identified : mapping
        ``params.yaml``'s content (``IdentificationResult.to_dict()``).
    runs, metas : mapping
        Run id -> run table and metadata (``kind``; staircases give the model error; a
        ``modulator`` is designed too). Their valve commands give the pulses the bench
        recorded: a loop whose pulses on the model are shorter is not verified
        (:mod:`spa.closedloop.pulses`; no runs, no check). The promise tries the loops of
        a setting they recorded open loop before the others (:func:`checked_first`): its
        ripple and dynamics were measured there before the promise predicts them.
    selected : iterable of mapping
        The settings compared (the config's ``analytic.selected``); the runs' own settings
        are added.
    cfg : mapping, optional
        The config's ``closed_loop:`` section.
    recommendation : mapping, optional
        The tuning's ``recommendation.yaml``; without one, ``identified``'s ``adequacy`` is
        used so that the choice knows which modulators the bench ran.
    valve : spa.identification.identified.Identified, optional
        The identified valve, read once where the stage's input enters
        (``read_identified(identified)`` when omitted); every design, simulation, check
        and the header take its ``params``, laws included.

    Returns
    -------
    result : spa.closedloop.comparison.ClosedLoopResult
    bench : BenchOutputs
        ``bench.header`` is ``controller.h``; ``bench.summary["promise"]`` the promise.
    """
    from spa.closedloop.bench import (
        adequacy_clause,
        adequacy_of,
        apply_bench,
        bench_outputs,
        sensor_noise,
    )
    from spa.closedloop.comparison import DEFAULTS, closed_loop
    from spa.closedloop.model_error import dataset_error
    from spa.identification.identified import read_identified

    if valve is None:
        valve = read_identified(identified)
    if recommendation is None and isinstance(identified.get("adequacy"), Mapping):
        recommendation = {"adequacy": identified["adequacy"]}
    # without runs nothing is known of the records' pulses: no check (None)
    recorded = RecordedPulses.from_runs(runs) if runs else None
    # the settings the bench ran are designed too: only loops within the pulses it recorded
    # can be verified (spa.closedloop.pulses)
    settings = [Modulator.from_mapping(m) if isinstance(m, Mapping) else m for m in selected]
    labels = {m.label for m in settings}
    settings += [m for m in recorded_settings(metas) if m.label not in labels]
    result = closed_loop(valve.params, settings, recommendation, cfg)
    ctl = result.controllers
    first = _chosen(ctl)
    adequacy = adequacy_of(identified)

    def adequate(label: str) -> bool:  # "<type>-<setting>": run here, described here
        return adequacy_clause(adequacy, label.split("-", 1)[0]) == ""

    # After the stage's choice, only loops that can be verified: of a modulator the bench ran
    # and the model describes there (an unverifiable promise is no better than none).
    # Those that meet the design at the stage's tau_c first, then the others in the stage's
    # order (the promise lengthens tau_c for each).
    others = [
        (str(label), str(name))
        for label, name in [*ctl.get("meeting", []), *ctl.get("ranked", [])]
        if adequate(label)
    ]
    # One loop of each setting first (the best of each, in that order), then the others: a
    # setting whose loops all miss the promise should not use up the candidates.
    ordered = list(dict.fromkeys([first, *others]))
    seen: set[str] = set()
    heads = []
    for choice in ordered:
        if choice is not None and choice[0] not in seen:
            seen.add(choice[0])
            heads.append(choice)
    candidates = list(dict.fromkeys([first, *heads, *ordered]))
    # loops whose valve pulses on the model lie within the records go first, and of those
    # the loops of a setting the bench recorded open loop (its ripple and dynamics were
    # measured there before the promise predicts them); stable order otherwise
    within = {c: _within_records(ctl, c, valve.params, recorded) for c in candidates}
    candidates = checked_first(candidates, within, {m.label for m in recorded_settings(metas)})
    benches: list[tuple[tuple[str, str] | None, BenchOutputs]] = []
    errors: dict[bool, dict[str, tuple[float, float]]] = {}  # each staircase replayed once

    def check(choice, intervals, below=None) -> BenchOutputs:
        equilibrium = choice is not None and choice[1] == "scheduled_ff"
        if equilibrium not in errors:
            errors[equilibrium] = dataset_error(runs, metas, valve.params, equilibrium=equilibrium)
        return bench_outputs(
            result,
            valve.params,
            intervals,
            cfg,
            sensor_noise(identified),
            model_error=errors[equilibrium],
            adequacy=adequacy,
            choice=choice,
            unresolved=valve.unresolved,
            recorded=recorded,
            below=below,
        )

    for choice in candidates[:MAX_CANDIDATES]:
        benches.append((choice, check(choice, valve.intervals)))
        if benches[-1][1].summary.get("verified"):
            break
    if not any(b.summary.get("verified") for _, b in benches):
        # the loops checked that could be verified: within the records, of an adequate kind
        verifiable = [(c, b) for c, b in benches if c is not None and within[c] and adequate(c[0])]
        benches += _narrowed(verifiable, valve, identified.get("laws"), check)
    kept = [cb for cb in benches if (cb[1].summary.get("promise") or {}).get("kept")]
    verified = [cb for cb in kept if cb[1].summary.get("verified")]
    choice, bench = (verified or kept or benches)[0]
    if choice != first and choice is not None and first is not None:
        fraction = float({**DEFAULTS, **dict(cfg or {})}["max_level_fraction"])
        checked = next((b for c, b in benches if c == first), None)
        _ship_instead(result, first, choice, checked, valve.params, fraction)
    apply_bench(result, bench)
    return result, bench


def checked_first(
    candidates: list[tuple[str, str] | None],
    within: Mapping[tuple[str, str] | None, bool],
    ran: set[str],
) -> list[tuple[str, str] | None]:
    """The promise's candidate loops in the order they are checked: those whose valve pulses
    lie within the records (``within``) first, and of each group those of a setting the
    bench recorded open loop (``ran``, labels) first; the stage's order otherwise.

    Examples
    --------
    >>> loops = [("lpwm-20Hz", "fixed"), ("lpwm-50Hz", "fixed"), ("pwm-9Hz", "fixed")]
    >>> within = {("lpwm-20Hz", "fixed"): True, ("lpwm-50Hz", "fixed"): True,
    ...           ("pwm-9Hz", "fixed"): False}
    >>> [c[0] for c in checked_first(loops, within, {"lpwm-50Hz", "pwm-9Hz"})]
    ['lpwm-50Hz', 'lpwm-20Hz', 'pwm-9Hz']
    """
    return sorted(
        candidates,
        key=lambda choice: (not within[choice], choice is None or choice[0] not in ran),
    )


def _within_records(
    ctl: Mapping[str, Any],
    choice: tuple[str, str] | None,
    params: Any,
    recorded: RecordedPulses | None,
) -> bool:
    """Whether a designed loop's valve open and closed times on the model, over its own
    staircase, lie within those the bench recorded (:func:`spa.closedloop.pulses.pulse_clause`)."""
    if choice is None:
        return False
    if recorded is None:
        return True
    entry = ctl["controllers"][choice[0]]
    levels = [float(v) for v in entry.get("levels", ctl.get("levels", []))]
    if not levels or choice[1] not in entry:
        return False
    ctrl = PIController.from_mapping(entry[choice[1]])
    dt = float(ctl.get("dt", 1e-3))
    pulses = loop_pulses(entry["setting"], ctrl, params, levels, float(entry.get("hold", 3.0)), dt)
    return pulse_clause(*pulses, recorded) == ""


def _narrowed(verifiable, valve, record, check) -> list:
    """A laws valve's promise over fewer set-points: when no loop keeps a verified promise
    over every set-point, the lowest are left out one at a time (at least two kept), each
    time with the laws' box over the pressures the loop then visits
    (:func:`spa.closedloop.box.laws_box_above`, from :data:`BELOW_MARGIN` of ``k2`` under
    the lowest set-point kept), for the first :data:`NARROWED_CANDIDATES` of the checked
    loops that could be verified (``verifiable``, ``[(choice, bench)]``); the widest range
    first. ``record`` is ``params.yaml``'s ``laws:`` (its bands). The first verified one, as
    ``[(choice, bench)]``, or ``[]``.
    """
    from spa.closedloop.bench_text import laws_envelope
    from spa.closedloop.box import laws_box_above

    bands = record.get("bands") if isinstance(record, Mapping) else None
    if valve.params.laws is None or not isinstance(bands, Mapping):
        return []
    verifiable = verifiable[:NARROWED_CANDIDATES]
    whole = laws_envelope(valve.params, valve.intervals)
    margin = BELOW_MARGIN * float(valve.params.k2)
    stairs = {
        c: [float(v) for v in (b.summary.get("promise") or {}).get("levels", [])]
        for c, b in verifiable
    }
    for drop in range(1, max((len(v) for v in stairs.values()), default=0) - 1):
        for choice, _ in verifiable:
            levels = stairs[choice]
            if len(levels) - drop < 2:
                continue
            lowest = levels[drop]
            box = laws_box_above(record, valve.params, valve.intervals, lowest - margin)
            bench = check(choice, box, {"lowest": lowest, "laws_envelope": whole})
            if bench.summary.get("verified"):
                return [(choice, bench)]
    return []


#: Share of ``k2`` under a narrowed promise's lowest set-point that its laws' box still
#: covers: a step down into it undershoots by at most ``max_overshoot`` (10 %) of a step.
BELOW_MARGIN = 0.1

#: Most designed loops checked over the box, in the stage's order, for one that keeps a
#: verified promise (the first is the stage's choice; each costs a robust design).
MAX_CANDIDATES = 6

#: Loops tried at each narrowed range (:func:`_narrowed`): as many as over the whole range.
NARROWED_CANDIDATES = MAX_CANDIDATES


def _ship_instead(
    result: Any,
    first: tuple[str, str],
    choice: tuple[str, str],
    first_bench: BenchOutputs | None,
    params: Any,
    fraction: float,
) -> None:
    """Make ``choice`` the stage's choice in ``result`` (its sentence rewritten), saying why
    the stage's first choice ``first`` is not shipped."""
    from spa.closedloop.choice import closed_loop_sentence, held_clause

    ctl = result.controllers
    gains = ctl["controllers"]
    label, name = choice
    ctl["setting"] = gains[label]["setting"]
    ctl["controller"] = name
    ctl["first_choice"] = {"setting": gains[first[0]]["setting"], "controller": first[1]}
    sentence = closed_loop_sentence(result.table, gains, label, name)
    held = (ctl.get("held_range") or {}).get(label)
    if held is not None:
        sentence += " " + held_clause(gains[label]["setting"], params, held, fraction)
    if ctl.get("tau_c") != ctl.get("tau_c_requested"):
        sentence += f" tau_c was lengthened to {float(ctl['tau_c']):g} s."
    desc = Modulator.from_mapping(gains[first[0]]["setting"]).description
    said = dict(first_bench.summary) if first_bench is not None else {}
    if first_bench is None or (said.get("promise") or {}).get("kept"):
        # kept over the box but not verified, or not checked: its pulses are outside the records
        clause = str(said.get("adequacy_clause") or "") or (
            "its valve's times on the model are shorter than the bench recorded"
        )
        why = f"whose promise the data do not verify ({clause})"
    else:
        try:
            worst = float((said.get("promise") or {}).get("overshoot"))
        except (TypeError, ValueError):
            worst = math.nan
        why = (
            "which keeps no promise over the 95 % box and the model error measured on this "
            "dataset" + (f" (worst overshoot {worst:.0f} %)" if math.isfinite(worst) else "")
        )
    ctl["sentence"] = (
        f"{sentence} It is shipped instead of {desc} with the {first[1]} PI, the fastest on "
        f"the identified model, {why}."
    )


def promise_kept(
    measured: Mapping[str, float],
    promise: Mapping[str, Any],
    max_overshoot: float,
) -> dict[str, Any]:
    """Whether a staircase measured on a plant keeps the promise.

    Parameters
    ----------
    measured : mapping
        ``measure_staircase``'s summary: ``worst_overshoot`` (%), ``worst_error`` (largest
        end error, % of its step), ``worst_ripple_pp`` (bar; the actuator's pressure, as the
        promise's: a sensor's log adds its own noise, some 6 to 8 standard deviations peak
        to peak over a hold).
    promise : mapping
        ``controllers.yaml: bench.promise`` (``kept``, ``overshoot``, ``ripple_pp``).
    max_overshoot : float
        ``closed_loop.max_overshoot``, %: the promise itself must meet it.

    Returns
    -------
    dict
        ``promised`` (a promise was made and meets ``max_overshoot``), ``overshoot_ok``
        (within :data:`OVERSHOOT_MARGIN` points of it), ``settled_ok`` (every level within
        :data:`SETTLE_BAND` % of its step at the end of its hold), ``ripple_ok`` (at most
        :data:`RIPPLE_FACTOR` times the promised ripple) and ``kept`` (all four).

    Examples
    --------
    >>> promise_kept({"worst_overshoot": 12.0, "worst_error": 0.5, "worst_ripple_pp": 0.01},
    ...              {"kept": True, "overshoot": 8.0, "ripple_pp": 0.008}, 10.0)["kept"]
    True
    >>> promise_kept({"worst_overshoot": 14.0, "worst_error": 0.5, "worst_ripple_pp": 0.01},
    ...              {"kept": True, "overshoot": 8.0, "ripple_pp": 0.008}, 10.0)["overshoot_ok"]
    False
    """

    def num(v: Any) -> float:
        try:
            return float(v)
        except (TypeError, ValueError):
            return math.nan

    over, ripple = num(promise.get("overshoot")), num(promise.get("ripple_pp"))
    promised = bool(promise.get("kept")) and math.isfinite(over) and over <= max_overshoot
    out = {
        "promised": promised,
        "overshoot_ok": promised
        and num(measured.get("worst_overshoot")) <= over + OVERSHOOT_MARGIN,
        "settled_ok": num(measured.get("worst_error")) <= SETTLE_BAND,
        "ripple_ok": math.isfinite(ripple)
        and num(measured.get("worst_ripple_pp")) <= RIPPLE_FACTOR * ripple,
    }
    out["kept"] = all(out.values())
    return out
