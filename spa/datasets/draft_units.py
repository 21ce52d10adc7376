"""``spa init``'s guesses of units: time from the time column's name, else its median step
(and the files' length); pressure from the pressure column's name, else the supply the
readings reach. Importable from :mod:`spa.datasets.draft` too."""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from spa.datasets.guess import Guess

__all__ = ["guess_pressure_unit", "guess_time_unit"]

# --------------------------------------------------------------------------- units


#: Median time step (in the file's unit) bounding s and ms: a bench samples at 100 Hz to
#: 100 kHz; a step of 0.01 is 100 Hz in s (taken) or 100 kHz in ms.
TIME_STEP_BOUNDS = (1e-6, 1e-2, 10.0)


#: Largest pressure magnitude for each unit (soft actuators run at 0 to ~4 bar).
PRESSURE_LIMITS: tuple[tuple[str, float], ...] = (
    ("bar", 6.0),
    ("psi", 90.0),
    ("kPa", 600.0),
    ("mbar", 6000.0),
)


#: A median step up to this (in the file's unit) is 10-100 Hz in s or 10-100 kHz in ms: a
#: coarse log or a fast one; the files' length tells them apart (:func:`guess_time_unit`).
COARSE_STEP = 0.1

#: A file shorter than this in ms (100 ms) holds no valve response: its time is in s.
SHORTEST_RUN_MS = 100.0


def guess_time_unit(
    t: npt.ArrayLike, name: str | None = None, span: float | None = None
) -> Guess:
    """Guess whether time is in s or ms: from the time column's name, else its median step.

    Parameters
    ----------
    t : array_like
        Time stamps in the file's unit (pooled steps of several files may be passed as
        ``np.cumsum(steps)``; only the steps count).
    name : str, optional
        The time column's name: a unit written in it as a word (``time_ms``, ``t[s]``,
        ``Time (ms)``: :func:`~spa.datasets.contract.time_unit_in_name`) is taken.
    span : float, optional
        The files' median duration in their unit: a median step in (1e-2, 0.1] (50 Hz in s,
        or 50 kHz in ms) with files lasting under 100 in all is s, as no valve responds
        within 100 ms.

    Returns
    -------
    Guess
        The unit the name states; else ``"s"`` for a median step in [1e-6, 1e-2] (or in
        (1e-2, 0.1] with files too short in ms), ``"ms"`` in (1e-2, 10], else None.

    Examples
    --------
    >>> guess_time_unit([0, 1, 2, 3]).value, guess_time_unit([0, 1e-3, 2e-3]).value
    ('ms', 's')
    >>> guess_time_unit([0, 20, 40], "time_ms").reason
    "named 'time_ms': median step 20 ms, 50 Hz"
    >>> guess_time_unit(np.arange(50) * 0.02, span=0.98).value  # 50 Hz for 1 s, not 1 ms
    's'
    """
    from spa.datasets.contract import TIME_UNITS, time_unit_in_name

    t = np.asarray(t, dtype=np.float64).ravel()
    if t.size < 2:
        return Guess(None, "fewer than 2 time stamps")
    step = float(np.median(np.diff(t)))
    named = time_unit_in_name(name)
    if named is not None:
        rate = f", {1 / (step * TIME_UNITS[named]):.4g} Hz" if step > 0 else ""
        return Guess(named, f"named {name!r}: median step {step:.4g} {named}{rate}")
    low, mid, high = TIME_STEP_BOUNDS
    if low <= step <= mid * (1 + 1e-9):
        return Guess("s", f"median step {step:.4g}: {1 / step:.4g} Hz if in s")
    if mid < step <= COARSE_STEP and span is not None and span < SHORTEST_RUN_MS:
        return Guess(
            "s",
            f"median step {step:.4g}: {1 / step:.4g} Hz if in s (in ms the files would last "
            f"{span:.3g} ms, median, too short for a valve's response)",
        )
    if mid < step <= high:
        return Guess("ms", f"median step {step:.4g}: {1e3 / step:.4g} Hz if in ms")
    return Guess(
        None,
        f"median step {step:.4g} fits neither s ({low:g} to {mid:g}) nor ms ({mid:g} to {high:g})",
    )


def guess_pressure_unit(p: npt.ArrayLike, name: str | None = None) -> Guess:
    """Guess the pressure unit from the supply pressure the readings reach.

    Parameters
    ----------
    p : array_like
        Pressure readings in the file's unit (NaN ignored); pooled over the files of a
        session, whose highest reading is the supply (a charge run's plateau).
    name : str, optional
        The column's name: a unit written in it as a word (``P_act_kPa``) is taken when it
        puts the supply within the plausible range (``datasets.plausible_supply_bar``'s
        default, 0.05-20 bar).

    Returns
    -------
    Guess
        The unit, else None.

    Notes
    -----
    The supply is taken as the 99.9th percentile of ``|p|`` (robust to a spike). Unless the
    name states the unit, of the
    units that put it within a soft actuator's typical supply, 0.2-6 bar
    (:data:`~spa.datasets.contract.TYPICAL_SUPPLY_BAR`), the first of bar, psi, kPa, mbar is
    taken unless another reading is more than twice nearer the middle of that range, 1.1
    bar, by ratio (:func:`~spa.datasets.checks.likelier_unit`, the rule ``spa validate``
    warns by): 80 is kPa (0.8 bar), not psi (5.5 bar). When several units fit, the reason
    names them all. When none does, the first unit of :data:`PRESSURE_LIMITS` whose limit
    holds the supply.

    Examples
    --------
    >>> [guess_pressure_unit([0, x]).value for x in (2.5, 40, 80, 250, 2500, 1e5)]
    ['bar', 'psi', 'kPa', 'kPa', 'mbar', None]
    """
    from spa.datasets.checks import likelier_unit, typical_readings
    from spa.datasets.contract import (
        PLAUSIBLE_SUPPLY_BAR,
        PRESSURE_UNITS,
        TYPICAL_SUPPLY_BAR,
        unit_in_name,
    )

    lo, hi = TYPICAL_SUPPLY_BAR
    p = np.asarray(p, dtype=np.float64).ravel()
    p = p[np.isfinite(p)]
    if p.size == 0:
        return Guess(None, "no pressure readings")
    top = float(np.percentile(np.abs(p), 99.9, method="higher"))
    named = unit_in_name(name)
    if named is not None:
        bar = top * PRESSURE_UNITS[named]
        if PLAUSIBLE_SUPPLY_BAR[0] <= bar <= PLAUSIBLE_SUPPLY_BAR[1]:
            return Guess(named, f"named {name!r}; |p| up to {top:.4g}, the supply: {bar:.3g} bar")
    fits = typical_readings(top)
    if fits:
        unit = next(u for u in fits if likelier_unit(top, u) is None)
        first = next(iter(fits))
        reason = f"|p| up to {top:.4g}, the supply (a charge run's plateau): "
        reason += f"{fits[unit]:.3g} bar in {unit}"
        others = [f"{bar:.3g} bar in {u}" for u, bar in fits.items() if u != unit]
        if not others:
            return Guess(unit, reason + f" (a typical supply is {lo:g}-{hi:g} bar)")
        reason += f", or {', or '.join(others)}: all typical ({lo:g}-{hi:g} bar)"
        if unit == first:
            return Guess(unit, reason + ", check")
        return Guess(
            unit,
            f"{reason}; {unit}, as a supply is most often near 1 bar and {fits[first]:.3g} "
            f"bar is more than twice as far from it (likely {unit} read as {first})",
        )
    for unit, limit in PRESSURE_LIMITS:
        if top <= limit:
            return Guess(unit, f"|p| up to {top:.4g}: within {limit:g} {unit} (0 to ~4 bar)")
    return Guess(None, f"|p| up to {top:.4g}: above {PRESSURE_LIMITS[-1][1]:g} mbar")
