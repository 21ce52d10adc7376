"""The checks of one run's data, chunk by chunk, and the summary of a valid run.

The run's kind is checked against its valve trace by :mod:`spa.datasets.kind_check`; a
supply pressure against the unit declared by :mod:`spa.datasets.supply`, whose names stay
importable from here.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from spa.datasets.clock import INDEX_TIME
from spa.datasets.contract import (
    _MAX_ROWS_LISTED,
    CANONICAL_COLUMNS,
    P_MAX_BAR,
    P_MIN_BAR,
    SPEC_FILE,
    _to_bar,
    _to_seconds,
)
from spa.datasets.kind_check import _ValveTrace
from spa.datasets.problems import Problem
from spa.datasets.spec import RunEntry

# Defined with the supply pressure's checks; importable from here as before.
from spa.datasets.supply import LIKELIER_FACTOR as LIKELIER_FACTOR
from spa.datasets.supply import k2_warning as k2_warning
from spa.datasets.supply import likelier_unit as likelier_unit
from spa.datasets.supply import supply_warning as supply_warning
from spa.datasets.supply import typical_readings as typical_readings

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
    sample_step : float or None
        The logging step (s) that made ``t`` (row index times it) for a log without time
        stamps; None when ``t`` was read.
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
    sample_step: float | None = None

    @property
    def duration(self) -> float:
        """``t_end - t_start`` in s."""
        return self.t_end - self.t_start

    def _clock(self) -> str:
        if self.sample_step is None:
            return ""
        return f" (t = row index * sample_step {self.sample_step:g} s)"

    def __str__(self) -> str:
        return (
            f"{self.run}: {self.kind}, {_modulator_text(self.modulator)}, "
            f"{self.duration:.6g} s at {self.rate_hz:.6g} Hz{self._clock()}, "
            f"p {self.p_min:.4g} to {self.p_max:.4g} bar "
            f"({self.file}, {self.rows} rows, columns {' '.join(self.columns)})"
        )


def _modulator_text(modulator: Mapping[str, Any] | None) -> str:
    if not modulator:
        return "no modulator"
    units = {"f_w": " Hz", "t_h": " s", "t_l": " s", "period": " s", "gain": ""}
    settings = " ".join(f"{k}={v:g}{units.get(k, '')}" for k, v in modulator.items() if k != "type")
    return f"{modulator['type']} {settings}"


#: Time steps kept for :meth:`_RunCheck.median_step` (8 MiB): the median of the first million
#: steps stands for a whole recording.
_STEPS_KEPT = 1 << 20


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
        self.valve = _ValveTrace()  # for the kind check (:meth:`kind_problems`)
        self.steps: list[npt.NDArray[np.float64]] = []  # the first _STEPS_KEPT time steps
        self.steps_kept = 0

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
                if self.steps_kept < _STEPS_KEPT:
                    kept = step[np.isfinite(step)][: _STEPS_KEPT - self.steps_kept]
                    self.steps.append(kept)
                    self.steps_kept += kept.size

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
                self.valve.feed(t, v)
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

    def median_step(self) -> float:
        """The median time step in s, over the first :data:`_STEPS_KEPT` steps (NaN when
        there are none)."""
        if not self.steps_kept:
            return math.nan
        step = np.float64(np.median(np.concatenate(self.steps)))
        return float(_to_seconds(step, self.time_unit))

    def kind_problems(self, file: str | None, run: str | None, kind: str) -> list[Problem]:
        """The run's declared kind against its valve trace (errors naming the run): see
        :meth:`spa.datasets.kind_check._ValveTrace.kind_problems`."""
        if self.failed or "valve" not in self.columns:
            return []
        return self.valve.kind_problems(file, run, kind, self.columns["valve"], self.time_unit)

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
            sample_step=run.sample_step if self.columns["t"] == INDEX_TIME else None,
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
