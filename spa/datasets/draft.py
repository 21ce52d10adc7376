"""Guesses for a draft ``dataset.yaml`` (``spa init``): the role of each column of a file, the
units, the kind of run and the pulse modulator, each with the reason it was made.

Every function here is pure: it takes the columns of one file as arrays and returns a
:class:`Guess`, whose ``value`` is None when the data do not decide (the draft then writes a
``TODO`` that ``spa validate`` rejects) and whose ``reason`` says why, in words a user can check.

The rules, in order (see ``raw/README.md``, "Start from ``spa init``"):

* **roles**: a strictly increasing column is time (but a file's only column, unless named
  like time, is the pressure: a rising charge logged alone); a column holding only 0 and 1
  is the valve command; a column named like a pressure set-point (``r``, ``sp``,
  ``setpoint``, ``p_ref``, ``p_set``, ``p_target``, ``p_des``, ...) is the closed loop's
  set-point ``r``; one within [0, 1] is the input fraction ``u``; the others are pressure
  candidates,
  of which the one named like a pressure (``p``, ``pressure``, ``kPa``, ...) or else the one of
  largest variance is the pressure. Names break ties (``time``, ``valve``, ``xi``, ...).
* **time unit** (:mod:`spa.datasets.draft_units`, like the pressure unit): a unit written
  as a word in the time column's name (``time_ms``, ``t[s]``); else a bench samples at
  100 Hz to 100 kHz, so a median step in [1e-6, 1e-2] is in s, in (1e-2, 10] in ms, except
  that a step up to 0.1 in files lasting under 100 in all is s (a coarse log at 10-100 Hz:
  no valve responds within 100 ms); outside, undecided.
* **pressure unit**: a unit written as a word in the column's name (``P_kPa``) when it
  puts the supply within 0.05-20 bar; else the largest magnitude (99.9th percentile, robust
  to a spike) is the supply, typically 0.2-6 bar: of the units putting it there, the first
  of bar, psi, kPa, mbar unless another is more than twice nearer 1.1 bar by ratio (80 is
  0.8 bar in kPa, not 5.5 bar in psi); when none does, bar up to 6, psi up to 90, kPa up
  to 600 and mbar up to 6000; above, undecided. Ranges overlap (40 is 2.8 bar in psi or
  0.4 bar in kPa): the reason names every fitting unit.
* **kind**: a set-point column ``r`` gives a closed-loop run (``closed_loop``; its PI's gains
  are not in the data, so the draft asks for them); else an input ``u`` that moves gives a
  modulated run, by the shape of ``u``: piecewise
  constant with at least 3 levels held at least 0.2 s → staircase; upward crossings of its
  mid-range at a steady period (spread < 10 %) → sine; crossings whose period shrinks (or
  grows) steadily (rank correlation with time above 0.7 in magnitude) by a factor > 2 → chirp.
  Without a moving ``u``: valve held at 1 → charge, held at 0 → discharge; a valve that
  switches at most twice and is open (closed) for at least half the run while the pressure
  rises (falls) → charge (discharge), whatever quiet lead-in comes first; toggling → pulse;
  without a valve either, pressure rising → charge, falling → discharge.
* **modulator** (from the valve's edges): rising edges on a fixed period (or a multiple, to
  a sample) → PWM, ``f_w = 1/period``; every edge on a clock of at least 2.5 samples, the
  shortest high or low time, and high or low times varying → ΔΣ, ``period`` = the clock;
  constant high time → IPFM, ``t_h`` = it,
  ``gain = ∫u / ∫valve`` from the first pulse to the last (each firing adds ``t_h`` of
  opening per ``G t_h`` of integral); constant low time → IIPFM, ``t_l`` = it,
  ``gain = ∫(1 - u) / ∫(1 - valve)``.
"""

from __future__ import annotations

import itertools
import re
from collections.abc import Mapping

import numpy as np
import numpy.typing as npt

from spa.datasets.draft_units import PRESSURE_LIMITS as PRESSURE_LIMITS
from spa.datasets.draft_units import TIME_STEP_BOUNDS as TIME_STEP_BOUNDS
from spa.datasets.draft_units import guess_pressure_unit, guess_time_unit
from spa.datasets.guess import Guess
from spa.model.modulators import MODULATOR_ORDER, get_kind
from spa.model.modulators.trace import Trace

__all__ = [
    "Guess",
    "guess_kind",
    "guess_modulator",
    "guess_pressure_unit",
    "guess_roles",
    "guess_time_unit",
]

_Array = npt.NDArray[np.float64]

_NAME_HINTS: Mapping[str, re.Pattern[str]] = {
    "t": re.compile(r"^(t|time|times|zeit|temps|tiempo|timestamp)([_ .\-\[(].*)?$|time", re.I),
    "valve": re.compile(r"valve|vent|ventil|solenoid|cmd|command|switch|onoff|on_off", re.I),
    "u": re.compile(r"^(u|xi|x|duty|d)([_ .\-\[(].*)?$|xi|duty|ref|input|frac|setpoint", re.I),
    "p": re.compile(r"^(p|pa)([_ .\-\[(\d].*)?$|press|kpa|mbar|bar|psi|act", re.I),
    # the set-point of a closed loop (``ref [psi]``, ``r [bar]``, ``setpoint``); a column
    # named only "ref"/"reference" that holds a fraction beside a pressure well above 1 is
    # the input fraction (_WEAK_SETPOINT)
    "r": re.compile(
        r"^(r|ref|reference|sp|w|target|setpoint|set_point|set-point|sollwert|consigna|"
        r"p_?(ref|set|sp|r|d|des|desired|target|cmd|demand))([_ .\-\[(].*)?$|setpoint|set_point",
        re.I,
    ),
}

#: Set-point names that an input fraction may carry too ("ref", "reference", with a suffix).
_WEAK_SETPOINT = re.compile(r"^(ref|reference)([_ .\-\[(].*)?$", re.I)


# --------------------------------------------------------------------------- roles


def _strictly_increasing(x: _Array) -> bool:
    return x.size >= 2 and bool(np.all(np.diff(x) > 0))


def _binary(x: _Array) -> bool:
    return x.size > 0 and bool(np.all((x == 0) | (x == 1)))


def _fraction(x: _Array) -> bool:
    return x.size > 0 and bool(np.all((x >= 0) & (x <= 1)))


def _named(role: str, names: list[str]) -> list[str]:
    return [n for n in names if _NAME_HINTS[role].search(n.strip())]


def _pick(role: str, names: list[str], score: Mapping[str, float], what: str) -> Guess:
    """Pick one column of ``names`` for ``role``: a single one, else one named for the role,
    else the highest ``score``."""
    if not names:
        return Guess(None, f"no column is {what}")
    if len(names) == 1:
        return Guess(names[0], f"the only column {what}")
    named = _named(role, names)
    if len(named) == 1:
        return Guess(named[0], f"{what}, and named like it (of {', '.join(names)})")
    pool = named or names
    best = max(pool, key=lambda n: score[n])
    return Guess(best, f"{what}; picked from {', '.join(pool)} by {_SCORE_WORD[role]}")


_SCORE_WORD = {
    "t": "the most even step",
    "valve": "the most switching",
    "u": "the largest variance",
    "p": "the largest variance",
    "r": "the largest variance",
}


def guess_roles(columns: Mapping[str, npt.ArrayLike]) -> dict[str, Guess]:
    """Guess which column of a file is time, pressure, valve command and input fraction.

    Parameters
    ----------
    columns : mapping of str to array_like
        The numeric columns of one file, all of one length (missing values as NaN; a column
        with a NaN or an infinity takes no role).

    Returns
    -------
    dict of str to Guess
        For each canonical name ``t``, ``p``, ``valve``, ``u``, ``r``: the file column (None
        when no column fits; ``valve``, ``u`` and ``r`` are optional) and the reason.

    Examples
    --------
    >>> g = guess_roles({"ms": [0, 1, 2, 3], "P": [0.0, 5.0, 9.0, 12.0], "v": [1, 1, 0, 1]})
    >>> [g[k].value for k in ("t", "p", "valve", "u")]
    ['ms', 'P', 'v', None]
    """
    arrays = {str(k): np.asarray(v, dtype=np.float64).ravel() for k, v in columns.items()}
    finite = {k: v for k, v in arrays.items() if v.size and np.all(np.isfinite(v))}
    increasing = [k for k, v in finite.items() if _strictly_increasing(v)]
    out: dict[str, Guess] = {}

    def even(name: str) -> float:
        d = np.diff(finite[name])
        return -float(np.std(d) / np.mean(d))

    out["t"] = _pick("t", increasing, {k: even(k) for k in increasing}, "strictly increasing")
    alone = len(finite) == 1 and not _named("t", list(finite))
    if out["t"].decided and alone:  # a rising pressure logged alone, not a clock
        out["t"] = Guess(None, f"no time column (the only column, {out['t'].value!r}, is p)")
    rest = [k for k in finite if k != out["t"].value]
    binary = [k for k in rest if _binary(finite[k])]
    switches = {k: float(np.count_nonzero(np.diff(finite[k]))) for k in binary}
    out["valve"] = _pick("valve", binary, switches, "holding only 0 and 1")
    rest = [k for k in rest if k != out["valve"].value]
    setpoints = _named("r", [k for k in rest if np.ptp(finite[k]) > 0])
    top = max((float(np.max(np.abs(finite[k]))) for k in rest), default=0.0)
    setpoints = [  # a "ref" within [0, 1] while the pressure reaches well above 1: a fraction
        k
        for k in setpoints
        if not (_WEAK_SETPOINT.match(k.strip()) and _fraction(finite[k]) and top > 1.5)
    ]
    if setpoints:
        var_r = {k: float(np.var(finite[k])) for k in setpoints}
        out["r"] = _pick("r", setpoints, var_r, "named like a pressure set-point")
    else:
        out["r"] = Guess(None, "no column named like a set-point (r, ref, setpoint, p_ref, ...)")
    rest = [k for k in rest if k != out["r"].value]
    named_p = set(_named("p", rest)) - set(_named("u", rest))
    fractions = [k for k in rest if _fraction(finite[k]) and k not in named_p]
    others = [k for k in rest if k not in fractions]
    var = {k: float(np.var(finite[k])) for k in rest}
    if not others and len(fractions) > 1:  # a pressure in bar may stay within [0, 1]
        non_u = [k for k in fractions if k not in _named("u", fractions)] or fractions
        best = max(non_u, key=lambda n: var[n])
        others, fractions = [best], [k for k in fractions if k != best]
    out["u"] = _pick("u", fractions, var, "within [0, 1] (not only 0/1)")
    if not others and len(fractions) == 1 and not _named("u", fractions):
        others, out["u"] = fractions, Guess(None, "no column left for u")
    p = _pick("p", others, var, "numeric and not time, valve or a fraction")
    if p.value is not None and len(others) == 1 and others[0] in fractions:
        p = Guess(p.value, "the only numeric column left (within [0, 1]: pressure in bar?)")
    out["p"] = p
    return out


# --------------------------------------------------------------------------- kind


def _crossing_times(t: _Array, x: _Array) -> _Array:
    """Times at which ``x`` crosses its mid-range upwards (linear interpolation)."""
    centred = x - 0.5 * (np.min(x) + np.max(x))
    s = np.signbit(centred)
    up = np.flatnonzero(s[:-1] & ~s[1:])
    frac = -centred[up] / (centred[up + 1] - centred[up])
    return t[up] + frac * (t[up + 1] - t[up])


def _rank_correlation(x: _Array, y: _Array) -> float:
    """Spearman's rank correlation of ``x`` and ``y`` (0 when either is constant)."""
    rx = np.argsort(np.argsort(x)).astype(np.float64)
    ry = np.argsort(np.argsort(y, kind="stable")).astype(np.float64)
    if x.size < 3 or np.ptp(rx) == 0 or np.ptp(ry) == 0:
        return 0.0
    return float(np.corrcoef(rx, ry)[0, 1])


def _shape_of_u(t: _Array, u: _Array) -> Guess:
    changes = np.flatnonzero(np.diff(u)) + 1
    bounds = np.concatenate([[0], changes, [u.size]])
    hold = np.diff(t[np.minimum(bounds, t.size - 1)])
    levels = np.unique(u[bounds[:-1]])
    if changes.size <= 200 and levels.size >= 3 and np.median(hold) >= 0.2:
        return Guess(
            "staircase",
            f"u piecewise constant: {levels.size} levels from {levels[0]:g} to {levels[-1]:g}, "
            f"held {np.median(hold):.3g} s (median)",
        )
    ups = _crossing_times(t, u)
    if ups.size < 3:
        return Guess(
            None,
            f"could not tell: u moves ({changes.size} changes, {levels.size} levels) but is "
            f"neither a staircase nor oscillating ({ups.size} upward crossings of mid-range)",
        )
    periods = np.diff(ups)
    q = max(1, min(5, periods.size // 4))  # the first and last few periods
    first, last = float(np.median(periods[:q])), float(np.median(periods[-q:]))
    spread = float(np.std(periods) / np.mean(periods))
    rho = _rank_correlation(ups[1:], periods)
    if (first / last > 2 or last / first > 2) and abs(rho) > 0.7:
        way = "rising" if first > last else "falling"
        return Guess(
            "chirp",
            f"u oscillates with frequency {way} from {1 / first:.3g} to {1 / last:.3g} Hz "
            f"({ups.size} upward crossings)",
        )
    if spread < 0.1:
        f = 1.0 / float(np.median(periods))
        basis = np.column_stack(
            [np.ones_like(t), np.sin(2 * np.pi * f * t), np.cos(2 * np.pi * f * t)]
        )
        coef = np.linalg.lstsq(basis, u, rcond=None)[0]
        return Guess(
            "sine",
            f"u oscillates at a steady {f:.4g} Hz ({ups.size} periods); best-fit sinusoid "
            f"{coef[0]:.3g} + {np.hypot(coef[1], coef[2]):.3g} sin(2π {f:.4g} t + φ)",
        )
    return Guess(
        None,
        f"could not tell: u oscillates with uneven periods (spread {spread:.0%}), "
        "neither a sine nor a chirp",
    )


def guess_kind(
    t: npt.ArrayLike,
    p: npt.ArrayLike | None,
    valve: npt.ArrayLike | None = None,
    u: npt.ArrayLike | None = None,
) -> Guess:
    """Guess the kind of run from its signals.

    Parameters
    ----------
    t : array_like
        Time in s.
    p : array_like or None
        Pressure (any unit: only its trend is used).
    valve : array_like, optional
        0/1 valve command.
    u : array_like, optional
        Input fraction.

    Returns
    -------
    Guess
        ``charge``, ``discharge``, ``pulse``, ``staircase``, ``sine``, ``chirp`` or None.

    Examples
    --------
    >>> t = np.arange(100) * 0.01
    >>> guess_kind(t, 1 - np.exp(-t), np.ones(100)).value
    'charge'
    """
    t = np.asarray(t, dtype=np.float64).ravel()
    if u is not None:
        u = np.asarray(u, dtype=np.float64).ravel()
        if np.ptp(u) > 0:
            return _shape_of_u(t, u)
    if valve is not None:
        v = np.asarray(valve, dtype=np.float64).ravel()
        edges = int(np.count_nonzero(np.diff(v)))
        if edges == 0:
            kind = "charge" if v[0] == 1 else "discharge"
            return Guess(kind, f"valve held at {int(v[0])} throughout{_trend(p)}")
        held = _held_kind(t, p, v)
        if held is not None:
            return held
        note = "" if u is None else ", u constant"
        return Guess("pulse", f"valve switches {edges} times{note}")
    if p is None:
        return Guess(None, "could not tell: no pressure, valve or u")
    start, end = _ends(p)
    span = float(np.ptp(np.asarray(p, dtype=np.float64)))
    if span > 0 and abs(end - start) > 0.5 * span:
        return Guess("charge" if end > start else "discharge", f"no valve column{_trend(p)}")
    return Guess(
        None,
        "could not tell: no valve or u column, and the pressure neither rises nor falls by "
        f"half its range (from {start:.4g} to {end:.4g}, range {span:.4g})",
    )


#: Share of a run the valve's longest spell must cover for a charge or discharge run.
HELD_SHARE = 0.5


def _held_kind(t: _Array, p: npt.ArrayLike | None, v: _Array) -> Guess | None:
    """A charge or discharge run behind a quiet lead-in (or before a closing tail).

    The valve switches at most twice and its longest spell, open (charge) or closed
    (discharge), covers at least :data:`HELD_SHARE` of the run; the pressure, when given,
    moves the same way over that spell. Anything else (pulses) gives None.
    """
    edges = np.flatnonzero(np.diff(v)) + 1
    if edges.size > 2 or t.size < 2:
        return None
    bounds = np.concatenate(([0], edges, [v.size]))
    spans = [(t[min(b, t.size - 1)] - t[a], a, b) for a, b in itertools.pairwise(bounds)]
    span, a, b = max(spans)
    total = float(t[-1] - t[0])
    if total <= 0 or span < HELD_SHARE * total:
        return None
    level = int(v[a])
    kind = "charge" if level == 1 else "discharge"
    word = "open" if level else "closed"
    when = f"from t = {t[a] - t[0]:.3g} s" if a > 0 else "from the start"
    reason = f"valve {word} {when} for {span:.3g} s ({span / total:.0%} of the run)"
    if p is not None:
        seg = np.asarray(p, dtype=np.float64).ravel()[a:b]
        start, end = _ends(seg)
        if (end > start) != (level == 1):
            return None  # the pressure contradicts the valve: not a clean charge/discharge
        reason += f"; pressure {'rises' if end > start else 'falls'} from {start:.4g} to {end:.4g}"
    return Guess(kind, reason)


def _ends(p: npt.ArrayLike) -> tuple[float, float]:
    """Median of the first and of the last 1 % of ``p``."""
    x = np.asarray(p, dtype=np.float64).ravel()
    m = max(1, x.size // 100)
    return float(np.median(x[:m])), float(np.median(x[-m:]))


def _trend(p: npt.ArrayLike | None) -> str:
    if p is None:
        return ""
    start, end = _ends(p)
    return f"; pressure {'rises' if end > start else 'falls'} from {start:.4g} to {end:.4g}"


# --------------------------------------------------------------------------- modulator


def guess_modulator(t: npt.ArrayLike, valve: npt.ArrayLike, u: npt.ArrayLike | None) -> Guess:
    """Guess the pulse modulator and its setting from the valve's edges.

    Parameters
    ----------
    t : array_like
        Time in s, evenly sampled.
    valve : array_like
        0/1 valve command.
    u : array_like or None
        Input fraction (needed for the IPFM/IIPFM gain; without it the gain is left at 1).

    Returns
    -------
    Guess
        A mapping as in ``dataset.yaml`` (settings in s and Hz) or None.

    Examples
    --------
    >>> t = np.arange(2000) * 1e-3
    >>> v = ((t % 0.05) < 0.05 * np.where(t < 1, 0.3, 0.6)).astype(float)
    >>> guess_modulator(t, v, np.where(t < 1, 0.3, 0.6)).value
    {'type': 'pwm', 'f_w': 20.0}
    """
    t = np.asarray(t, dtype=np.float64).ravel()
    v = np.asarray(valve, dtype=np.float64).ravel()
    if t.size < 3:
        return Guess(None, "could not tell the modulator: fewer than 3 samples")
    dt = float(np.median(np.diff(t)))
    d = np.diff(v)
    n_rise, n_fall = int(np.count_nonzero(d > 0)), int(np.count_nonzero(d < 0))
    if n_rise < 4 or n_fall < 4:
        return Guess(
            None,
            f"could not tell the modulator: the valve switches only {n_rise + n_fall} times",
        )
    iu = None if u is None else np.asarray(u, dtype=np.float64).ravel()
    trace = Trace.from_samples(t, v, iu, dt)
    for kind in sorted(MODULATOR_ORDER, key=lambda k: get_kind(k).guess_rank):
        found = get_kind(kind).guess(trace)
        if found is not None:
            return Guess(*found)
    h_share, l_share = trace.shares
    return Guess(
        None,
        f"could not tell the modulator: rises not periodic, neither high nor low time "
        f"constant ({_share_text(h_share, l_share)}), edges not on a clock ({trace.count})",
    )


def _share_text(h_share: float, l_share: float) -> str:
    """``"x% of highs, y% of lows at their median"`` for a reason string."""
    return f"{h_share:.0%} of highs, {l_share:.0%} of lows at their median"
