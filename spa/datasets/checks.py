"""The checks of one run's data, chunk by chunk, and the summary of a valid run."""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from spa.datasets.contract import (
    _MAX_ROWS_LISTED,
    CANONICAL_COLUMNS,
    P_MAX_BAR,
    P_MIN_BAR,
    SPEC_FILE,
    _to_bar,
    _to_seconds,
)
from spa.datasets.problems import Problem
from spa.datasets.spec import RunEntry

# --------------------------------------------------------------------------- checks


class _Tally:
    __slots__ = ("count", "detail", "rows")

    def __init__(self) -> None:
        self.count = 0
        self.rows: list[int] = []
        self.detail = ""


@dataclass(frozen=True, slots=True)
class RunSummary:
    """What a run holds, for the one-line report of ``spa validate``.

    Attributes
    ----------
    run, kind, file : str
        Run id, kind and file (relative to the dataset folder).
    modulator : dict or None
        Completed modulator settings.
    columns : tuple of str
        Canonical columns present.
    rows : int
        Number of samples.
    t_start, t_end : float
        First and last time stamp in s.
    rate_hz : float
        Mean sample rate ``(rows - 1) / (t_end - t_start)`` in Hz.
    p_min, p_max : float
        Pressure range in bar gauge.
    """

    run: str
    kind: str
    file: str
    modulator: dict[str, Any] | None
    columns: tuple[str, ...]
    rows: int
    t_start: float
    t_end: float
    rate_hz: float
    p_min: float
    p_max: float

    @property
    def duration(self) -> float:
        """``t_end - t_start`` in s."""
        return self.t_end - self.t_start

    def __str__(self) -> str:
        return (
            f"{self.run}: {self.kind}, {_modulator_text(self.modulator)}, "
            f"{self.duration:.6g} s at {self.rate_hz:.6g} Hz, "
            f"p {self.p_min:.4g} to {self.p_max:.4g} bar "
            f"({self.file}, {self.rows} rows, columns {' '.join(self.columns)})"
        )


def _modulator_text(modulator: Mapping[str, Any] | None) -> str:
    if not modulator:
        return "no modulator"
    units = {"f_w": " Hz", "t_h": " s", "t_l": " s", "period": " s", "gain": ""}
    settings = " ".join(f"{k}={v:g}{units.get(k, '')}" for k, v in modulator.items() if k != "type")
    return f"{modulator['type']} {settings}"


class _RunCheck:
    """Checks of one run's samples, fed chunk by chunk, in the file's own units."""

    def __init__(self, columns: Mapping[str, str], time_unit: str, pressure_unit: str) -> None:
        self.columns = dict(columns)  # canonical -> file column, present ones only
        self.time_unit = time_unit
        self.pressure_unit = pressure_unit
        self.tallies: dict[tuple[str, str], _Tally] = {}
        self.rows = 0
        self.t_first = math.nan
        self.t_prev: float | None = None
        self.p_lo = math.inf
        self.p_hi = -math.inf
        # the valve trace, for the kind check (:meth:`kind_problems`)
        self.v_last: float | None = None
        self.v_first: float | None = None
        self.v_edges = 0
        self.v_levels: set[int] = set()
        self.v_first_edge: tuple[float, int] | None = None  # (t in the file's unit, to)

    @property
    def failed(self) -> bool:
        return bool(self.tallies)

    def _note(
        self, canon: str, check: str, mask: npt.NDArray[np.bool_], offset: int, detail: Any
    ) -> None:
        """Record rows where ``mask`` holds; ``detail(i)`` describes index ``i``."""
        hits = np.flatnonzero(mask)
        if hits.size == 0:
            return
        tally = self.tallies.setdefault((canon, check), _Tally())
        if tally.count == 0:
            tally.detail = detail(int(hits[0]))
        tally.count += int(hits.size)
        room = _MAX_ROWS_LISTED - len(tally.rows)
        if room > 0:
            tally.rows.extend(int(i) + offset + 1 for i in hits[:room])

    def feed(
        self,
        offset: int,
        values: Mapping[str, npt.NDArray[np.float64]],
        bad: Mapping[str, npt.NDArray[np.bool_]],
    ) -> dict[str, npt.NDArray[Any]] | None:
        """Check one chunk (canonical names) and return it in canonical units when clean."""
        tu, pu = self.time_unit, self.pressure_unit
        with np.errstate(invalid="ignore", over="ignore"):
            for canon, x in values.items():
                non_numeric = bad.get(canon)
                if non_numeric is not None and non_numeric.any():
                    self._note(
                        canon,
                        "text",
                        non_numeric,
                        offset,
                        lambda i: "non-numeric value; expected a number",
                    )
                    missing = np.isnan(x) & ~non_numeric
                else:
                    missing = np.isnan(x)
                self._note(
                    canon,
                    "nan",
                    missing,
                    offset,
                    lambda i: "missing value (empty cell or NaN); expected a finite number",
                )
                self._note(
                    canon,
                    "inf",
                    np.isinf(x),
                    offset,
                    lambda i, x=x: f"infinite value ({x[i]}); expected a finite number",
                )

            t = values["t"]
            if t.size:
                if self.rows == 0:
                    self.t_first = float(t[0])
                self._note(
                    "t",
                    "huge",
                    np.abs(t) >= 2.0**53,
                    offset,
                    lambda i: (
                        f"t = {t[i]:.17g} {tu} is beyond 2^53, where a float no longer holds "
                        "every integer (time in ns since 1970?); subtract the start time"
                    ),
                )
                before = np.nan if self.t_prev is None else self.t_prev
                prev = np.concatenate(([before], t[:-1]))
                step = np.where(np.isfinite(t) & np.isfinite(prev), t - prev, np.nan)
                self._note(
                    "t",
                    "dup",
                    step == 0,
                    offset,
                    lambda i: (
                        f"duplicated time stamp t = {t[i]:.10g} {tu}, the same as "
                        "the previous row; expected strictly increasing time"
                    ),
                )
                self._note(
                    "t",
                    "back",
                    step < 0,
                    offset,
                    lambda i: (
                        f"time goes backwards: t = {t[i]:.10g} {tu} after "
                        f"{prev[i]:.10g} {tu} on the previous row; expected strictly "
                        "increasing time"
                    ),
                )
                self.t_prev = float(t[-1])

            p = values["p"]
            p_bar = _to_bar(p, pu)
            finite = np.isfinite(p)
            if finite.any():
                self.p_lo = min(self.p_lo, float(p[finite].min()))
                self.p_hi = max(self.p_hi, float(p[finite].max()))
            self._note(
                "p",
                "range",
                finite & ((p_bar < P_MIN_BAR) | (p_bar > P_MAX_BAR)),
                offset,
                lambda i: (
                    f"pressure {p[i]:.6g} {pu}"
                    + ("" if pu == "bar" else f" (= {p_bar[i]:.6g} bar)")
                    + f" is outside the plausible gauge range {P_MIN_BAR:g} to "
                    f"{P_MAX_BAR:g} bar"
                ),
            )

            if "valve" in values:
                v = values["valve"]
                self._note(
                    "valve",
                    "range",
                    np.isfinite(v) & (v != 0) & (v != 1),
                    offset,
                    lambda i: f"valve = {v[i]:.17g}; expected the command 0 or 1",
                )
                self._trace_valve(t, v)
            if "u" in values:
                u = values["u"]
                self._note(
                    "u",
                    "range",
                    np.isfinite(u) & ((u < 0) | (u > 1)),
                    offset,
                    lambda i: (
                        f"u = {u[i]:.17g} is outside [0, 1]; expected the input fraction in [0, 1]"
                    ),
                )
        self.rows += len(t)
        if self.failed:
            return None
        out: dict[str, npt.NDArray[Any]] = {"t": _to_seconds(t, tu), "p": p_bar}
        if "valve" in values:
            out["valve"] = values["valve"].astype(np.int8)
        if "u" in values:
            out["u"] = values["u"]
        if "r" in values:  # a closed-loop run's set-point, in the file's pressure unit
            out["r"] = _to_bar(values["r"], pu)
        return out

    def _trace_valve(self, t: npt.NDArray[np.float64], v: npt.NDArray[np.float64]) -> None:
        """Count the valve's switches and levels over the chunks (0/1 rows only)."""
        good = (v == 0) | (v == 1)
        vv, tt = v[good], t[good]
        if vv.size == 0:
            return
        self.v_levels.update(int(x) for x in np.unique(vv))
        if self.v_first is None:
            self.v_first = float(vv[0])
        seq = vv if self.v_last is None else np.concatenate(([self.v_last], vv))
        times = tt if self.v_last is None else np.concatenate(([np.nan], tt))
        switch = np.flatnonzero(np.diff(seq)) + 1
        if switch.size and self.v_first_edge is None:
            self.v_first_edge = (float(times[switch[0]]), int(seq[switch[0]]))
        self.v_edges += int(switch.size)
        self.v_last = float(vv[-1])

    def kind_problems(self, file: str | None, run: str | None, kind: str) -> list[Problem]:
        """The run's declared kind against its valve trace (errors naming the run).

        A ``charge`` run whose valve never opens, a ``discharge`` run whose valve never
        closes, and a ``pulse`` run whose valve switches fewer than twice (no whole pulse:
        held, or one switch after a lead-in, which is a charge or discharge run) cannot be
        identified from; each is an error that says what the trace shows.
        """
        if self.failed or self.v_first is None or "valve" not in self.columns:
            return []
        col = self.columns["valve"]
        name = f"{kind} run {run!r}" if run else f"{kind} run"
        message = None
        if kind == "charge" and 1 not in self.v_levels:
            message = f"{name}: the valve never opens (valve 0 throughout); a charge run opens it"
        elif kind == "discharge" and 0 not in self.v_levels:
            message = (
                f"{name}: the valve never closes (valve 1 throughout); a discharge run closes it"
            )
        elif kind == "pulse" and self.v_edges < 2:
            if self.v_edges == 0:
                held = int(self.v_first)
                likely = "charge" if held == 1 else "discharge"
                shows = f"the valve is held at {held} throughout"
            else:
                at, to = self.v_first_edge or (math.nan, 1)
                likely = "charge" if to == 1 else "discharge"
                verb = "opens" if to == 1 else "closes"
                shows = (
                    f"the valve switches once ({verb} at t = {at:.6g} {self.time_unit} and "
                    "stays so)"
                )
            message = (
                f"{name}: {shows}; a pulse run needs whole pulses (the valve opening and "
                f"closing). Is it a {likely} run (kind: {likely})?"
            )
        if message is None:
            return []
        return [Problem(file, run, col, None, message)]

    def problems(self, file: str | None, run: str | None) -> list[Problem]:
        out = []
        for (canon, check), tally in self.tallies.items():
            message = tally.detail
            if tally.count > 1:
                listed = ", ".join(str(r) for r in tally.rows)
                more = ", ..." if tally.count > len(tally.rows) else ""
                message += f" ({tally.count} rows in all: {listed}{more})"
            if (canon, check) == ("p", "range"):
                pu = self.pressure_unit
                message += f"; the column spans {self.p_lo:.6g} to {self.p_hi:.6g} {pu}"
                message += _unit_hint(self.p_lo, self.p_hi, pu)
            out.append(Problem(file, run, self.columns[canon], tally.rows[0], message))
        if self.rows < 2 and not out:
            out.append(
                Problem(
                    file,
                    run,
                    None,
                    None,
                    f"{self.rows} data row(s); a run needs at least 2 samples",
                )
            )
        return out

    def warnings(self, file: str | None, run: str | None, kind: str) -> list[Problem]:
        out = []
        if self.failed or self.rows < 2:
            return out
        duration = _to_seconds(np.float64(self.t_prev - self.t_first), self.time_unit)
        rate = (self.rows - 1) / duration
        tcol = self.columns["t"]
        message = None
        if rate < 5.0:
            message = (
                f"mean sample rate {rate:.3g} Hz is implausibly low for a valve "
                "with ms delays; is time in ms? (set units: {time: ms})"
            )
        elif rate > 2e5:  # 5 µs steps: faster than any valve bench logs
            message = (
                f"mean sample rate {rate:.3g} Hz is implausibly high; "
                f"is time really in {self.time_unit}?"
            )
        if message is not None:
            out.append(Problem(file, run, tcol, None, message, level="warning"))
        peak = max(
            abs(_to_bar(self.p_lo, self.pressure_unit)), abs(_to_bar(self.p_hi, self.pressure_unit))
        )
        if peak < 0.01 and kind != "pulse":  # short pulses may stay below 0.01 bar
            out.append(
                Problem(
                    file,
                    run,
                    self.columns["p"],
                    None,
                    f"pressure never exceeds {peak:.3g} bar in magnitude; are the "
                    f"units right (declared {self.pressure_unit})?",
                    level="warning",
                )
            )
        return out

    def summary(self, run: RunEntry) -> RunSummary:
        t0 = float(_to_seconds(np.float64(self.t_first), self.time_unit))
        t1 = float(_to_seconds(np.float64(self.t_prev), self.time_unit))
        return RunSummary(
            run=run.id,
            kind=run.kind,
            file=run.file,
            modulator=run.modulator,
            columns=tuple(c for c in CANONICAL_COLUMNS if c in self.columns),
            rows=self.rows,
            t_start=t0,
            t_end=t1,
            rate_hz=(self.rows - 1) / (t1 - t0) if t1 > t0 else math.nan,
            p_min=float(_to_bar(self.p_lo, self.pressure_unit)),
            p_max=float(_to_bar(self.p_hi, self.pressure_unit)),
        )


def _unit_hint(lo: float, hi: float, declared: str) -> str:
    """Name the pressure units that would put ``[lo, hi]`` in the plausible range, if any.

    Units giving a peak between 0.05 and 12 bar (what soft actuators see) come first, then
    by how common they are on benches: kPa, bar, mbar, psi.
    """
    fits = []
    for rank, unit in enumerate(("kPa", "bar", "mbar", "psi")):
        if unit == declared:
            continue
        lo_b, hi_b = float(_to_bar(lo, unit)), float(_to_bar(hi, unit))
        if P_MIN_BAR <= lo_b and hi_b <= P_MAX_BAR:
            typical = 0.05 <= max(abs(lo_b), abs(hi_b)) <= 12.0
            fits.append((not typical, rank, unit, f"{unit} ({lo_b:.4g} to {hi_b:.4g} bar)"))
    if not fits:
        return "; is it absolute pressure, or in Pa? spa expects gauge pressure"
    fits.sort()
    others = "".join(f"; or {text}" for *_, text in fits[1:])
    unit, text = fits[0][2], fits[0][3]
    return f"; the values look like {text}{others}: set units: {{pressure: {unit}}} in {SPEC_FILE}"


#: How much nearer (as a factor) the middle of :data:`TYPICAL_SUPPLY_BAR` another unit's
#: reading of the supply must be for that unit to be the likelier.
LIKELIER_FACTOR = 2.0

#: Units in the order a draft prefers them when several readings are typical (the largest
#: reading first).
_UNIT_ORDER = ("bar", "psi", "kPa", "mbar")


def typical_readings(top: float, bounds: tuple[float, float] | None = None) -> dict[str, float]:
    """The readings in bar of a supply pressure ``top`` (in the file's unit) that are typical.

    Parameters
    ----------
    top : float
        The supply pressure (a charge run's plateau) as logged, in an unknown unit.
    bounds : (float, float), optional
        Typical supply in bar; default :data:`TYPICAL_SUPPLY_BAR`.

    Returns
    -------
    dict of str to float
        Unit to ``top`` converted to bar, for the units that put it within ``bounds``, in the
        order bar, psi, kPa, mbar.

    Examples
    --------
    >>> {u: round(b, 2) for u, b in typical_readings(80.0).items()}
    {'psi': 5.52, 'kPa': 0.8}
    """
    from spa.datasets.contract import TYPICAL_SUPPLY_BAR

    lo, hi = bounds if bounds is not None else TYPICAL_SUPPLY_BAR
    readings = {unit: float(_to_bar(abs(top), unit)) for unit in _UNIT_ORDER}
    return {unit: bar for unit, bar in readings.items() if lo <= bar <= hi}


def likelier_unit(
    top: float, declared: str, bounds: tuple[float, float] | None = None
) -> tuple[str, float] | None:
    """Another pressure unit under which a supply pressure is much more typical.

    Parameters
    ----------
    top : float
        The supply pressure (a charge run's plateau) in the ``declared`` unit.
    declared : str
        The unit it is read in (a key of :data:`PRESSURE_UNITS`).
    bounds : (float, float), optional
        Typical supply in bar; default :data:`TYPICAL_SUPPLY_BAR`.

    Returns
    -------
    (str, float) or None
        The unit and its reading in bar, when that reading is typical and its ratio to the
        middle of ``bounds`` (their geometric mean, 1.1 bar) is more than
        :data:`LIKELIER_FACTOR` times smaller than the declared reading's; else None.

    Notes
    -----
    A soft actuator's supply is typically 0.2-6 bar and most often near 1 bar; a number such
    as 80 reads 5.5 bar in psi and 0.8 bar in kPa, both typical, but 5.5 bar is 5.0 times the
    middle and 0.8 bar 1.4 times below it: kPa is likelier. The rule names another unit only
    when its reading is more than twice nearer the middle, so: psi gives way to kPa above
    4.1 bar (59 psi), kPa to mbar above 4.9 bar (490 kPa), bar to psi above 5.9 bar. A real
    supply that high logged in psi, kPa or bar is therefore called likely kPa, mbar or psi:
    a warning to check, not a correction; below those the ranges overlap (40 is 2.8 bar in
    psi or 0.4 bar in kPa) and neither is called likelier.

    Examples
    --------
    >>> unit, bar = likelier_unit(80.0, "psi")
    >>> unit, round(bar, 2)
    ('kPa', 0.8)
    >>> likelier_unit(50.0, "psi") is None  # 3.4 bar: not much further than kPa's 0.5
    True
    """
    from spa.datasets.contract import TYPICAL_SUPPLY_BAR

    lo, hi = bounds if bounds is not None else TYPICAL_SUPPLY_BAR
    middle = math.sqrt(lo * hi)
    mine = float(_to_bar(abs(top), declared))
    if not (math.isfinite(mine) and mine > 0):
        return None
    others = {u: b for u, b in typical_readings(top, bounds).items() if u != declared}
    if not others:
        return None
    unit = min(others, key=lambda u: abs(math.log(others[u] / middle)))
    nearer = abs(math.log(mine / middle)) - abs(math.log(others[unit] / middle))
    return (unit, others[unit]) if nearer > math.log(LIKELIER_FACTOR) else None


def supply_warning(
    value: float,
    what: str,
    declared: str = "bar",
    bounds: tuple[float, float] | None = None,
    likelier: bool = True,
) -> str | None:
    """A warning when a supply pressure is implausible, naming the likely unit mistake.

    Parameters
    ----------
    value : float
        The pressure in bar gauge, as converted from the ``declared`` unit (the identified
        ``k2``, or a charge run's highest pressure).
    what : str
        What it is, for the message (``"k2"``).
    declared : str
        The pressure unit the dataset declared (a key of :data:`PRESSURE_UNITS`).
    bounds : (float, float), optional
        Plausible range in bar; default :data:`PLAUSIBLE_SUPPLY_BAR` (config
        ``datasets.plausible_supply_bar``).
    likelier : bool
        Also warn, inside ``bounds``, when another unit is much likelier
        (:func:`likelier_unit`); False for simulated data, whose unit is known.

    Returns
    -------
    str or None
        None when ``value`` is within ``bounds`` and no other unit is much likelier
        (:func:`likelier_unit`); else the message, with the unit that would put it in range
        or that is likelier.

    Examples
    --------
    >>> supply_warning(0.0115, "k2", "kPa").split(": ")[1]
    'pressure logged in bar but declared kPa?'
    >>> supply_warning(83.7, "k2", "bar").split(": ")[1]
    'pressure logged in kPa but declared bar?'
    >>> supply_warning(0.8, "k2") is None
    True
    >>> supply_warning(5.52, "k2", "psi").split(": ")[1]
    'pressure logged in kPa but declared psi? (set units'
    """
    from spa.datasets.contract import PLAUSIBLE_SUPPLY_BAR, PRESSURE_UNITS

    lo, hi = bounds if bounds is not None else PLAUSIBLE_SUPPLY_BAR
    factor = PRESSURE_UNITS.get(declared)
    if not math.isfinite(value):
        return None
    if lo <= value <= hi:
        other = likelier_unit(value / factor, declared) if likelier and factor else None
        if other is None:
            return None
        unit, bar = other
        shown = "" if declared == "bar" else f" ({value / factor:.4g} {declared})"
        return (
            f"{what} = {value:.3g} bar{shown} is unusual for a soft actuator's supply "
            f"(typically {_typical_text()}); in {unit} it would be {bar:.3g} bar: pressure "
            f"logged in {unit} but declared {declared}? (set units: {{pressure: {unit}}} if so)"
        )
    message = f"{what} = {value:.3g} bar is outside the plausible supply range {lo:g}-{hi:g} bar"
    fits = {  # the units that would put it in range, the likeliest nearest 1 bar
        unit: abs(math.log(value * other / factor))
        for unit, other in PRESSURE_UNITS.items()
        if factor is not None and unit != declared and lo <= value * other / factor <= hi
    }
    if value > 0 and fits:
        unit = min(fits, key=fits.__getitem__)
        return f"{message}: pressure logged in {unit} but declared {declared}?"
    return f"{message}: check the pressure unit and the sensor's calibration"


def _typical_text() -> str:
    from spa.datasets.contract import TYPICAL_SUPPLY_BAR

    lo, hi = TYPICAL_SUPPLY_BAR
    return f"{lo:g}-{hi:g} bar, most often near {math.sqrt(lo * hi):.2g} bar"


def k2_warning(
    k2: float, metas: Mapping[str, Mapping[str, Any]], bounds: tuple[float, float] | None = None
) -> str | None:
    """:func:`supply_warning` for an identified ``k2``, in the unit its charge runs declared.

    Parameters
    ----------
    k2 : float
        The identified supply pressure, bar.
    metas : mapping
        Run id -> run table metadata (:func:`spa.io.read_runs`): ``kind``, ``units`` and
        ``origin`` (a simulated dataset, every run ``synthetic``, is only checked against
        ``bounds``: its unit is known; so is a pressure column whose name states the unit
        declared, ``source.columns.p``).
    bounds : (float, float), optional
        As :func:`supply_warning`.

    Examples
    --------
    >>> metas = {"c": {"kind": "charge", "units": {"pressure": "kPa"}}}
    >>> k2_warning(0.0115, metas).split(": ")[1]
    'pressure logged in bar but declared kPa?'
    """
    units = [dict(m.get("units") or {}).get("pressure") for m in metas.values()]
    charge = [
        dict(m.get("units") or {}).get("pressure")
        for m in metas.values()
        if m.get("kind") == "charge"
    ]
    declared = next((u for u in [*charge, *units] if u), "bar")
    from spa.datasets.contract import unit_in_name

    unsure = [
        m
        for m in metas.values()
        if m.get("origin") != "synthetic"
        and unit_in_name(dict(dict(m.get("source") or {}).get("columns") or {}).get("p"))
        != dict(m.get("units") or {}).get("pressure", "bar")
    ]
    return supply_warning(float(k2), "k2", str(declared), bounds, likelier=bool(unsure))
