"""The valve pulses a loop asks for, against those the bench recorded.

A model identified from a bench's runs is checked only at the pulse lengths those runs
contain. A loop whose valve stays open (or closed) for shorter than the records ever did,
a 20 ms IIPFM on a valve recorded only with 50 ms pulses, say, asks the model for the delay
convention's effect at a time scale the data never tested: its levels and its ripple are the
model's extrapolation there. A promise built on them is not verified by the data.

:class:`RecordedPulses` holds the shortest open and closed times of a dataset's runs (their
1st percentile, :data:`FLOOR_QUANTILE`); :func:`loop_pulses` the open and closed times of a
loop on the identified model over a staircase; :func:`pulse_clause` says, in words, when
more than :data:`UNCOVERED_SHARE` of either lies below the records ("" when covered).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt
import pandas as pd

from spa.closedloop.controller import PIController
from spa.model.modulators import Modulator
from spa.model.params import ValveParams

__all__ = [
    "FLOOR_QUANTILE",
    "UNCOVERED_SHARE",
    "RecordedPulses",
    "loop_pulses",
    "pulse_clause",
    "recorded_settings",
    "valve_durations",
]

#: The records' shortest open (closed) time is this quantile of their pooled durations, so
#: that a few stray edges (a PWM duty grazing 0 or 1) do not stand for the records.
FLOOR_QUANTILE = 0.01

#: Fewest pooled durations for :data:`FLOOR_QUANTILE`; below it the shortest one is taken.
MIN_POOLED = 100

#: A loop is outside the records when more than this share of its open (or closed) times
#: are shorter than the records' shortest.
UNCOVERED_SHARE = 0.25


def valve_durations(
    t: npt.ArrayLike, valve: npt.ArrayLike
) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
    """Complete open and closed times of a valve command, s.

    An interval counts only when both its edges are in the record: a run's first and last
    stretches are left out.

    Parameters
    ----------
    t : array_like of float, shape (n,)
        Sample times, s, increasing.
    valve : array_like, shape (n,)
        The command, 0/1, held from each sample to the next.

    Returns
    -------
    open, closed : numpy.ndarray of float
        Each complete stretch of ``valve == 1`` (``== 0``), from the edge that starts it to
        the edge that ends it.

    Examples
    --------
    >>> o, c = valve_durations([0, 1, 2, 3, 4, 5, 6], [0, 1, 1, 0, 0, 0, 1])
    >>> o.tolist(), c.tolist()
    ([2.0], [3.0])
    """
    from spa.model.plant import edge_indices

    time = np.asarray(t, dtype=np.float64)
    v = np.asarray(valve) > 0
    edges = edge_indices(v)
    if edges.size < 2:
        return np.empty(0), np.empty(0)
    lengths = np.diff(time[edges])
    opened = v[edges[:-1]]  # the stretch after each edge but the last
    return lengths[opened], lengths[~opened]


@dataclass(frozen=True)
class RecordedPulses:
    """The shortest open and closed times a dataset's runs contain, s (None: none recorded).

    ``open_floor`` (``closed_floor``) is the :data:`FLOOR_QUANTILE` quantile of every
    complete open (closed) time of every run with a valve command, pooled; the shortest one
    when fewer than :data:`MIN_POOLED` were recorded. ``n_open`` and ``n_closed`` count them.
    """

    open_floor: float | None
    closed_floor: float | None
    n_open: int = 0
    n_closed: int = 0

    @classmethod
    def from_runs(cls, runs: Mapping[str, pd.DataFrame] | Iterable[pd.DataFrame]) -> RecordedPulses:
        """Pool the runs' open and closed times (runs without a ``valve`` column are skipped).

        Examples
        --------
        >>> run = pd.DataFrame({"t": np.arange(8.0), "valve": [0, 1, 0, 0, 1, 1, 0, 1]})
        >>> r = RecordedPulses.from_runs({"a": run})
        >>> r.open_floor, r.closed_floor, r.n_open, r.n_closed
        (1.0, 1.0, 2, 2)
        """
        frames = runs.values() if isinstance(runs, Mapping) else runs
        opens, closes = [], []
        for run in frames:
            if "valve" not in run or "t" not in run:
                continue
            o, c = valve_durations(run["t"].to_numpy(), run["valve"].to_numpy())
            opens.append(o)
            closes.append(c)
        o = np.concatenate(opens) if opens else np.empty(0)
        c = np.concatenate(closes) if closes else np.empty(0)
        return cls(_floor(o), _floor(c), int(o.size), int(c.size))

    def to_mapping(self) -> dict[str, Any]:
        """Plain values for YAML."""

        def said(x: float | None) -> float | None:
            return None if x is None else float(f"{x:.6g}")

        return {
            "open_floor": said(self.open_floor),
            "closed_floor": said(self.closed_floor),
            "n_open": self.n_open,
            "n_closed": self.n_closed,
        }


def _floor(durations: npt.NDArray[np.float64]) -> float | None:
    if durations.size == 0:
        return None
    if durations.size < MIN_POOLED:
        return float(durations.min())
    return float(np.quantile(durations, FLOOR_QUANTILE))


def loop_pulses(
    modulator: Modulator | Mapping[str, Any],
    controller: PIController,
    params: ValveParams,
    levels: Sequence[float],
    hold: float,
    dt: float,
) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
    """Open and closed times of a loop on the model over a staircase, s.

    The staircase climbs ``levels`` and comes back down, each held ``hold`` s, from the
    first level with the integrator at rest; the loop is :func:`spa.closedloop.loop.
    closed_loop_arrays` at ``params``.

    Examples
    --------
    >>> from spa.model.params import ValveParams
    >>> o, c = loop_pulses({"type": "pwm", "f_w": 20.0}, PIController(kp=2.0, ki=5.0),
    ...                    ValveParams(), [0.3, 0.5], 1.0, 1e-3)
    >>> bool(o.size > 20 and c.size > 20), bool(o.max() < 0.05 and c.max() < 0.05)
    (True, True)
    """
    from spa.closedloop.experiments import staircase_reference
    from spa.closedloop.loop import closed_loop_arrays

    stairs = [float(v) for v in levels]
    # at least one sample a level, even for a hold shorter than dt
    reference = staircase_reference(stairs, max(float(hold), dt), dt)
    _, _, u = closed_loop_arrays(reference, dt, modulator, controller, params, p0=stairs[0])
    return valve_durations(np.arange(reference.size) * dt, u)


def pulse_clause(
    opened: npt.ArrayLike,
    closed: npt.ArrayLike,
    recorded: RecordedPulses | None,
) -> str:
    """Why a loop's promise is not verified by the data: its pulses are shorter than any
    the bench recorded ("" when they are not, or when nothing is known of the records).

    A loop is outside the records when more than :data:`UNCOVERED_SHARE` of its open times
    are shorter than the records' shortest open time, or likewise of its closed times. A
    bench that recorded no pulse at all (charges and discharges only) covers none.

    Examples
    --------
    >>> rec = RecordedPulses(open_floor=0.015, closed_floor=0.02)
    >>> pulse_clause([0.004, 0.006, 0.012], [0.02, 0.02, 0.02], rec)[:66]
    "its valve's open times on the model (open 4.2–11 ms, closed 20 ms,"
    >>> pulse_clause([0.02, 0.03], [0.03, 0.04], rec)
    ''
    >>> pulse_clause([0.02], [0.03], None)
    ''
    """
    if recorded is None:
        return ""
    o = np.asarray(opened, dtype=np.float64)
    c = np.asarray(closed, dtype=np.float64)
    short = []
    for name, times, floor in (
        ("open", o, recorded.open_floor),
        ("closed", c, recorded.closed_floor),
    ):
        if times.size == 0:
            continue
        if floor is None or np.mean(times < floor) > UNCOVERED_SHARE:
            short.append(name)
    if not short:
        return ""

    def spread(times: npt.NDArray[np.float64]) -> str:
        lo, hi = np.percentile(times, [5, 95]) * 1e3
        return f"{lo:.2g} ms" if f"{lo:.2g}" == f"{hi:.2g}" else f"{lo:.2g}–{hi:.2g} ms"

    said = ", ".join(f"{name} {spread(t)}" for name, t in (("open", o), ("closed", c)) if t.size)
    floors = [
        f"{name} ≥ {floor * 1e3:.2g} ms"
        for name, floor in (("open", recorded.open_floor), ("closed", recorded.closed_floor))
        if floor is not None
    ]
    bench = ", ".join(floors) if floors else "no pulses"
    return (
        f"its valve's {' and '.join(short)} times on the model ({said}, 5th–95th "
        f"percentile) are shorter than the bench recorded ({bench}), so its levels and "
        "ripple are the model's extrapolation: "
        "record a staircase with this setting to verify it"
    )


def recorded_settings(metas: Mapping[str, Mapping[str, Any]]) -> list[Modulator]:
    """The modulator settings a dataset's runs were recorded with, once each, in run order.

    Examples
    --------
    >>> m = Modulator.from_mapping({"type": "pwm", "f_w": 5.0})
    >>> [s.label for s in recorded_settings({"a": {"modulator": m}, "b": {"modulator": m},
    ...                                      "c": {"modulator": None}})]
    ['pwm-5Hz']
    """
    found: dict[str, Modulator] = {}
    for meta in metas.values():
        mod = meta.get("modulator") if isinstance(meta, Mapping) else None
        if mod is None:
            continue
        mod = mod if isinstance(mod, Modulator) else Modulator.from_mapping(mod)
        found.setdefault(mod.label, mod)
    return list(found.values())
