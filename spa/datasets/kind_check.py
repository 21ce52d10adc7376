"""The run's declared kind against its valve trace: a charge run opens the valve, a discharge
run closes it and a pulse run makes whole pulses.

:class:`_ValveTrace` follows the valve column of one run over the chunks
(:class:`spa.datasets.checks._RunCheck` feeds it) and judges the run's ``kind:`` against it.
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from spa.datasets.problems import Problem


class _ValveTrace:
    """The valve command of one run, over the chunks: its levels and switches (0/1 rows)."""

    __slots__ = ("edges", "first", "first_edge", "last", "levels")

    def __init__(self) -> None:
        self.last: float | None = None
        self.first: float | None = None
        self.edges = 0
        self.levels: set[int] = set()
        self.first_edge: tuple[float, int] | None = None  # (t in the file's unit, to)

    def feed(self, t: npt.NDArray[np.float64], v: npt.NDArray[np.float64]) -> None:
        """Count the valve's switches and levels over the chunks (0/1 rows only)."""
        good = (v == 0) | (v == 1)
        vv, tt = v[good], t[good]
        if vv.size == 0:
            return
        self.levels.update(int(x) for x in np.unique(vv))
        if self.first is None:
            self.first = float(vv[0])
        seq = vv if self.last is None else np.concatenate(([self.last], vv))
        times = tt if self.last is None else np.concatenate(([np.nan], tt))
        switch = np.flatnonzero(np.diff(seq)) + 1
        if switch.size and self.first_edge is None:
            self.first_edge = (float(times[switch[0]]), int(seq[switch[0]]))
        self.edges += int(switch.size)
        self.last = float(vv[-1])

    def kind_problems(
        self, file: str | None, run: str | None, kind: str, column: str, time_unit: str
    ) -> list[Problem]:
        """The run's declared kind against this trace (errors naming the run).

        A ``charge`` run whose valve never opens, a ``discharge`` run whose valve never
        closes, and a ``pulse`` run whose valve switches fewer than twice (no whole pulse:
        held, or one switch after a lead-in, which is a charge or discharge run) cannot be
        identified from; each is an error that says what the trace shows, on the valve
        ``column`` (times in ``time_unit``, the file's). No valve sample: no problem.
        """
        if self.first is None:
            return []
        name = f"{kind} run {run!r}" if run else f"{kind} run"
        message = None
        if kind == "charge" and 1 not in self.levels:
            message = f"{name}: the valve never opens (valve 0 throughout); a charge run opens it"
        elif kind == "discharge" and 0 not in self.levels:
            message = (
                f"{name}: the valve never closes (valve 1 throughout); a discharge run closes it"
            )
        elif kind == "pulse" and self.edges < 2:
            if self.edges == 0:
                held = int(self.first)
                likely = "charge" if held == 1 else "discharge"
                shows = f"the valve is held at {held} throughout"
            else:
                at, to = self.first_edge or (math.nan, 1)
                likely = "charge" if to == 1 else "discharge"
                verb = "opens" if to == 1 else "closes"
                shows = f"the valve switches once ({verb} at t = {at:.6g} {time_unit} and stays so)"
            message = (
                f"{name}: {shows}; a pulse run needs whole pulses (the valve opening and "
                f"closing). Is it a {likely} run (kind: {likely})?"
            )
        if message is None:
            return []
        return [Problem(file, run, column, None, message)]
