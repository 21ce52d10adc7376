"""A bench session designed from a prior valve and the bench's limits: which settings to
record, how long each level is held, the sine's and chirp's frequencies, the pulse widths,
the replicates and their order.

Every duration comes from the prior: levels held 5 averaged time constants τ_m(ξ)
(:func:`spa.model.averaging.time_constant`) and at least ``min_periods`` periods of the
setting's slowest switching, charge and discharge long enough to settle, pulse lows that
bracket the closing delay (:func:`spa.synthetic.runs.identification_experiment_for`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from spa.model.averaging import time_constant, time_fractions
from spa.model.modulators import Modulator, check_settings, get_kind, kinds
from spa.model.params import ValveParams
from spa.plan.limits import Limits, PlanError, link_check
from spa.plan.session import Q15, PlannedRun, Segment, longest_high, run_commands

__all__ = [
    "NEIGHBOURS",
    "SessionDesign",
    "default_settings",
    "design_session",
    "identification_sizes",
    "neighbour_settings",
    "paper_settings_at_scale",
    "switching_rates",
]

#: The paper's valve: the settings are scaled by this valve's delays against it.
_NOMINAL = ValveParams()


@dataclass(frozen=True)
class SessionDesign:
    """The designed session: runs in the order played, and why each number is what it is."""

    prior: ValveParams
    limits: Limits
    dt: float
    seed: int
    runs: tuple[PlannedRun, ...]
    settings: dict[str, dict[str, Any]]
    refused: dict[str, str]
    rest: float
    link: str
    pilot: bool
    margins: dict[str, Any] = field(default_factory=dict)

    @property
    def duration(self) -> float:
        """The session's length, s (runs and the vents between them)."""
        return sum(r.ticks for r in self.runs) * self.dt + len(self.runs) * self.rest


def _up(x: float, step: float) -> float:
    return round(math.ceil(round(x / step, 6)) * step, 6)


def paper_settings_at_scale(prior: ValveParams, dt: float) -> list[Modulator]:
    """The paper's selected settings (20 Hz, 20 ms) scaled by the prior's delays against the
    paper's valve, kept at 10 steps ``dt`` or more, three significant digits."""
    from spa.openloop.paper import PAPER_SETTING
    from spa.tuning.cost import setting

    scale = (prior.t_on + prior.t_off) / (_NOMINAL.t_on + _NOMINAL.t_off)
    out = []
    for kind in kinds():
        if kind not in PAPER_SETTING:
            continue
        spec = get_kind(kind)
        ref = float(PAPER_SETTING[kind])
        if spec.unit == "Hz":
            value = min(ref / scale, 1.0 / (10 * dt))
        else:
            value = max(ref * scale, 10 * dt)
        out.append(setting(kind, float(f"{value:.3g}"), prior))
    return out


#: A recommended setting's neighbours: its swept parameter (frequency or pulse width) times
#: these, so that a session records the settings around the one it recommends.
NEIGHBOURS = (0.7, 1.4)


def neighbour_settings(
    mod: Modulator, prior: ValveParams, dt: float, factors: tuple[float, ...] = NEIGHBOURS
) -> list[Modulator]:
    """The settings next to ``mod``: its swept parameter times each of ``factors``, three
    significant digits, kept at 10 steps ``dt`` or more (a frequency at a tenth of ``1/dt``
    or less); those that come out as ``mod`` itself are left out.

    Examples
    --------
    >>> from spa.tuning.cost import setting
    >>> [m.label for m in neighbour_settings(setting("pwm", 20.0), ValveParams(), 0.001)]
    ['pwm-14Hz', 'pwm-28Hz']
    """
    from spa.tuning.cost import setting

    spec = get_kind(mod.kind)
    value = float(mod.settings[spec.parameter])
    out: list[Modulator] = []
    for f in factors:
        v = value * f
        v = min(v, 1.0 / (10 * dt)) if spec.unit == "Hz" else max(v, 10 * dt)
        near = setting(mod.kind, float(f"{v:.3g}"), prior)
        if near.label != mod.label and near.label not in {m.label for m in out}:
            out.append(near)
    return out


def default_settings(
    prior: ValveParams, dt: float, recommended: Modulator | None
) -> list[Modulator]:
    """What a full session records unless told otherwise: the recommended setting and its
    neighbours (:func:`neighbour_settings`) first, then the paper's four at the valve's scale
    (:func:`paper_settings_at_scale`), each once."""
    first = (
        [] if recommended is None else [recommended, *neighbour_settings(recommended, prior, dt)]
    )
    seen = {m.label for m in first}
    return first + [m for m in paper_settings_at_scale(prior, dt) if m.label not in seen]


def switching_rates(mod: Modulator, dt: float, xi: np.ndarray, span: float = 2.0) -> np.ndarray:
    """Rising edges per second of the setting held at each input fraction ``xi`` for
    ``span`` s (spa's modulator on a constant input)."""
    n = max(2, round(span / dt))
    rates = []
    for x in np.asarray(xi, dtype=np.float64):
        u = mod.modulate(np.full(n, x), dt)
        rates.append(np.count_nonzero(np.diff(u.astype(np.int8)) > 0) / (n * dt))
    return np.asarray(rates)


def _setting_numbers(
    mod: Modulator,
    prior: ValveParams,
    dt: float,
    levels: np.ndarray,
    hold_taus: float,
    min_periods: int,
) -> dict[str, Any]:
    a1, a2 = time_fractions(mod.kind, levels, prior, **mod.settings)
    tau = np.asarray(time_constant(a1, a2, prior), dtype=np.float64)
    tau_max = float(np.nanmax(tau)) if np.isfinite(tau).any() else prior.tau2
    inner = levels[(levels > 0.0) & (levels < 1.0)]
    rates = switching_rates(mod, dt, inner)
    moving = rates[rates > 0]
    slowest = float(moving.min()) if moving.size else 1.0
    hold = _up(max(hold_taus * tau_max, min_periods / slowest, 10 * dt), 0.1)
    mid = time_constant(*time_fractions(mod.kind, 0.5, prior, **mod.settings), prior)
    tau_mid = float(mid) if np.isfinite(mid) else tau_max
    return {
        "tau_m_max": tau_max,
        "tau_m_mid": tau_mid,
        "max_rate": float(rates.max()) if rates.size else 0.0,
        "slowest_rate": slowest,
        "hold": hold,
    }


def identification_sizes(prior: ValveParams, margin: float) -> dict[str, Any]:
    """Charge, discharge and pulse sizes that hold on valves ``margin`` times slower and
    faster than the prior: durations of the slow corner, pulse lows of both corners
    (:func:`spa.synthetic.runs.identification_experiment_for`)."""
    from spa.plan.prior import scaled
    from spa.synthetic.runs import identification_experiment_for

    slow = identification_experiment_for(scaled(prior, margin))
    quick = scaled(prior, 1.0 / margin)
    fast = identification_experiment_for(quick)
    # a low half the fast corner's closing delay: the exhaust never starts (the dead-zone)
    lows = sorted({*slow["low_times"], *fast["low_times"], round(0.5 * quick.t_off, 6)})
    return {**slow, "low_times": lows}


def _identification(prior: ValveParams, dt: float, tag: str, margin: float) -> list[PlannedRun]:
    exp = identification_sizes(prior, margin)
    tick = lambda s: max(1, round(s / dt))  # noqa: E731
    charge = PlannedRun(
        f"charge-{tag}",
        "charge",
        (Segment(tick(0.1), "valve", 0.0), Segment(tick(exp["charge_time"]), "valve", 1.0)),
        notes=f"valve open {exp['charge_time']:g} s from 0 bar "
        f"(6 tau2 of a valve {margin:g}x slower)",
    )
    discharge = PlannedRun(
        f"discharge-{tag}",
        "discharge",
        (
            Segment(tick(exp["charge_time"]), "valve", 1.0, log=False),
            Segment(tick(0.1), "valve", 1.0),
            Segment(tick(exp["discharge_time"]), "valve", 0.0),
        ),
        notes=f"filled (not logged), then closed {exp['discharge_time']:g} s",
    )
    segs = [Segment(tick(0.2), "valve", 0.0), Segment(tick(exp["high_time"]), "valve", 1.0)]
    for _ in range(int(exp["repeats"])):
        for low in exp["low_times"]:
            segs += [
                Segment(tick(low), "valve", 0.0),
                Segment(tick(exp["high_time"]), "valve", 1.0),
            ]
    segs.append(Segment(tick(0.5), "valve", 0.0))
    lows = ", ".join(f"{v * 1e3:g}" for v in exp["low_times"])
    pulse = PlannedRun(
        f"pulse-{tag}",
        "pulse",
        tuple(segs),
        notes=f"lows {lows} ms (bracketing t_off = {prior.t_off * 1e3:g} ms from "
        f"{margin:g}x faster to {margin:g}x slower), highs {exp['high_time'] * 1e3:g} ms, "
        f"x{exp['repeats']}",
    )
    return [charge, discharge, pulse]


def _modulated(
    mod: Modulator,
    numbers: dict[str, Any],
    levels: np.ndarray,
    dt: float,
    rep: int,
    freq_cap: float,
) -> list[PlannedRun]:
    hold = max(1, round(numbers["hold"] / dt))
    n = levels.size
    step = float(levels[1] - levels[0]) if n > 1 else 0.0
    lab = mod.label
    up = PlannedRun(
        f"staircase-up_{lab}_r{rep}",
        "staircase",
        (Segment(hold * n, "stair", float(levels[0]), step, float(hold)),),
        modulator=mod,
        notes=f"{n} levels up, {numbers['hold']:g} s each",
    )
    down = PlannedRun(
        f"staircase-down_{lab}_r{rep}",
        "staircase",
        (Segment(hold * n, "stair", float(levels[-1]), -step, float(hold)),),
        modulator=mod,
        notes=f"{n} levels down, {numbers['hold']:g} s each",
    )
    f_sine = min(1.0 / (2 * math.pi * numbers["tau_m_mid"]), freq_cap)
    f_sine = float(f"{f_sine:.2g}")
    cycles = 10
    sine_ticks = round(cycles / f_sine / dt)
    sine = PlannedRun(
        f"sine_{lab}_r{rep}",
        "sine",
        (Segment(sine_ticks, "sine", 0.5, 0.4, 2 * math.pi * f_sine * dt),),
        modulator=mod,
        notes=f"0.5 + 0.4 sin, {f_sine:g} Hz (1/(2 pi tau_m(0.5))), {cycles} cycles",
    )
    f_lo = f_sine / 3.0
    f_hi = min(10.0 * f_sine, freq_cap)
    span = 5.0 / f_lo
    ticks = round(span / dt)
    c = 2 * math.pi * f_lo * dt
    d = math.pi * (f_hi - f_lo) * dt * dt / span
    chirp = PlannedRun(
        f"chirp_{lab}_r{rep}",
        "chirp",
        (Segment(ticks, "chirp", 0.5, 0.4, c, d),),
        modulator=mod,
        notes=f"{f_lo:.3g} to {f_hi:.3g} Hz over {span:.3g} s (top below half "
        f"the slowest switching, {numbers['slowest_rate']:.3g} Hz)",
    )
    return [up, down, sine, chirp]


def design_session(
    prior: ValveParams,
    limits: Limits,
    *,
    dt: float = 0.002,
    seed: int = 0,
    levels: int = 11,
    replicates: int = 3,
    hold_taus: float = 5.0,
    min_periods: int = 10,
    precondition: int = 5,
    settings: list[Modulator] | None = None,
    recommended: Modulator | None = None,
    pilot: bool = False,
    margin: float = 3.0,
) -> SessionDesign:
    """Design the session.

    Parameters
    ----------
    prior : ValveParams
        The valve expected.
    limits : Limits
        The bench's limits.
    dt : float, default 0.002
        The player's tick, s: it reads, commands and prints once per tick.
    seed : int, default 0
        Seed of the modulated runs' random order (recorded in ``plan.yaml``).
    levels : int, default 11
        Staircase levels from 0 to 1.
    replicates : int, default 3
        Replicates of each experiment (at least 3).
    hold_taus, min_periods : optional
        Each level is held ``hold_taus`` τ_m(ξ) and ``min_periods`` of the slowest switching.
    precondition : int, default 5
        Fill-and-vent cycles before the first run (silicone softens over its first ones).
    settings : list of Modulator, optional
        The settings to record; by default the recommended one, its neighbours and the
        paper's four at the valve's scale (:func:`default_settings`).
    recommended : Modulator, optional
        The recommended setting (:func:`spa.tuning.tune` on the prior), listed first.
    margin : float, default 3
        The identification runs are sized for valves this many times slower and faster
        than the prior (the plan's margins).
    pilot : bool, default False
        Only the zero, preconditioning, charge, discharge and pulses (the first stage of a
        two-stage session).

    Raises
    ------
    PlanError
        For a link that cannot carry the logging, a supply above the rated maximum, fewer
        than 3 replicates, or a run that holds the valve open longer than the coil takes.
    """
    link = link_check(dt, limits)
    if replicates < 3:
        raise PlanError(f"replicates = {replicates}: at least 3 of each experiment")
    if levels < 2:
        raise PlanError(f"levels = {levels}: a staircase needs at least 2")
    if prior.k2 > limits.p_max:
        raise PlanError(
            f"the supply (k2 = {prior.k2:g} bar) is above the actuator's rated maximum "
            f"{limits.p_max:g} bar: set the regulator to {limits.p_max:g} bar or less and plan "
            "with that supply"
        )
    if not margin >= 1.0:
        raise PlanError(f"margin = {margin!r}: at least 1 (the prior itself)")
    rest = _up(2.0 * margin * prior.c1 * math.sqrt(prior.k2) * 1.5 + 0.2, 0.1)
    xi_levels = np.round(np.linspace(0.0, 1.0, levels) * Q15) / Q15
    chosen: list[Modulator] = []
    if not pilot:
        chosen = (
            list(settings) if settings is not None else default_settings(prior, dt, recommended)
        )
        if recommended is not None and recommended.label not in {m.label for m in chosen}:
            chosen.insert(0, recommended)
    numbers: dict[str, dict[str, Any]] = {}
    refused: dict[str, str] = {}
    for mod in chosen:
        try:
            check_settings(mod.kind, dt, **mod.settings)
            num = _setting_numbers(mod, prior, dt, xi_levels, hold_taus, min_periods)
        except ValueError as exc:
            refused[mod.label] = f"does not run at the tick {dt * 1e3:g} ms: {exc}"
            continue
        if limits.f_switch_max is not None and num["max_rate"] > limits.f_switch_max:
            refused[mod.label] = (
                f"switches up to {num['max_rate']:.3g} times per second, above the valve's "
                f"{limits.f_switch_max:g} Hz"
            )
            continue
        num["recommended"] = recommended is not None and mod.label == recommended.label
        num["setting"] = mod.to_mapping()
        numbers[mod.label] = num
    rng = np.random.default_rng(seed)
    runs: list[PlannedRun] = [
        PlannedRun(
            "zero",
            "zero",
            (Segment(round(2.0 / dt), "valve", 0.0),),
            block="start",
            notes="valve closed at atmosphere: the sensor's zero",
        ),
    ]
    fill = _identification(prior, dt, "x", margin)[0].segments[1].ticks
    vent = round(rest / dt)
    cycles = tuple(
        s
        for _ in range(precondition)
        for s in (Segment(fill, "valve", 1.0), Segment(vent, "valve", 0.0))
    )
    if precondition:
        runs.append(
            PlannedRun(
                "precondition",
                "precondition",
                cycles,
                block="start",
                notes=f"{precondition} fill-and-vent cycles",
            )
        )
    for r in range(1, replicates + 1):
        runs += [_with(x, "start") for x in _identification(prior, dt, f"start{r}", margin)]
    by_mod = {m.label: m for m in chosen}
    modulated: list[PlannedRun] = []
    for label, num in numbers.items():
        cap = 0.45 * num["slowest_rate"]
        for r in range(1, replicates + 1):
            modulated += _modulated(by_mod[label], num, xi_levels, dt, r, cap)
    order = rng.permutation(len(modulated)) if modulated else []
    runs += [_with(modulated[i], "modulated") for i in order]
    if not pilot:
        runs += [_with(x, "end") for x in _identification(prior, dt, "end", margin)]
    if limits.on_time_max is not None:
        too_long = []
        for run in runs:
            longest = longest_high(run_commands(run, dt)) * dt
            if longest > limits.on_time_max:
                too_long.append(f"{run.id} ({longest:.3g} s)")
        if too_long:
            raise PlanError(
                f"runs hold the valve open longer than the coil's {limits.on_time_max:g} s: "
                + ", ".join(too_long[:5])
                + (" ..." if len(too_long) > 5 else "")
                + "; raise --on-time-max if the coil takes it, or use a valve that does"
            )
    return SessionDesign(
        prior,
        limits,
        dt,
        seed,
        tuple(runs),
        numbers,
        refused,
        rest,
        link,
        pilot,
        {
            "time_scale": margin,
            "sizes": identification_sizes(prior, margin),
            "warnings": resolution_warnings(prior, dt, margin),
        },
    )


def resolution_warnings(prior: ValveParams, dt: float, margin: float) -> list[str]:
    """What the tick cannot resolve on the valves the plan covers: a delay of the fast
    corner shorter than one tick is known only to within a tick.

    Examples
    --------
    >>> [w[:43] for w in resolution_warnings(ValveParams(), 0.002, 3.0)]
    ['t_on of a valve 3x faster (1 ms) is shorter']
    """
    out = []
    for name in ("t_on", "t_off"):
        fast = getattr(prior, name) / margin
        if fast < dt:
            out.append(
                f"{name} of a valve {margin:g}x faster ({fast * 1e3:.3g} ms) is shorter than "
                f"the {dt * 1e3:g} ms tick: its interval will span about a tick; a shorter "
                "tick needs a faster link"
            )
    return out


def _with(run: PlannedRun, block: str) -> PlannedRun:
    return PlannedRun(run.id, run.kind, run.segments, run.modulator, block, run.notes, run.meta)
