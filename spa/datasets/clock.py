"""The log's clock in ``dataset.yaml``: ``sample_step`` (a fixed logging step, for logs
without time stamps) and ``valve_edges`` (how the logged valve command relates to that
clock).

Both keys sit at the dataset level and in a run, the run's overriding the dataset's. Each
checker is pure: it takes the value written and returns the value kept and the problem
found, in words that name what was expected.

* ``sample_step``: the logging step in s (always s, whatever ``units.time`` says, like the
  modulator settings), finite, > 0 and at most :data:`MAX_SAMPLE_STEP`. A run without a time
  column (``columns: {t: null}``, or ``t`` not mapped and absent from its file) gets
  ``t = row index * sample_step`` from 0 (:func:`index_time`); a run with both a time column
  and ``sample_step`` keeps its time column, whose median step must agree with
  ``sample_step`` within :data:`STEP_TOLERANCE` (:func:`step_problem`).
* ``valve_edges``: ``on_tick`` (the controller issued every command on a logging tick, so a
  logged edge is the true edge time) or ``sampled`` (the command ran on its own faster clock
  and the log samples it, so a true edge lies uniformly within the step before the sample
  that shows it). Undeclared (None): the data decide.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np
import numpy.typing as npt

from spa.datasets.problems import _is_one_of, _one_of, _suggest

__all__ = [
    "MAX_SAMPLE_STEP",
    "STEP_TOLERANCE",
    "VALVE_EDGES",
    "check_sample_step",
    "check_valve_edges",
    "index_time",
    "step_problem",
]

#: Largest ``sample_step`` accepted, s: a valve bench logs far faster.
MAX_SAMPLE_STEP = 10.0

#: Relative disagreement allowed between a time column's median step and ``sample_step``.
STEP_TOLERANCE = 0.01

#: The values of ``valve_edges``, with what each means (for messages and the docs).
VALVE_EDGES: Mapping[str, str] = {
    "on_tick": "the controller issued every command on a logging tick: a logged edge is the "
    "true edge time",
    "sampled": "the command ran on its own faster clock and the log samples it: a true edge "
    "lies uniformly within the step before the sample that shows it",
}

#: What a run table's ``t`` is called in messages when it is made from ``sample_step``.
INDEX_TIME = "row index * sample_step"

#: How ``sample_step`` is written, for messages.
SAMPLE_STEP_EXAMPLE = "sample_step: <s>, e.g. 0.02 for 50 Hz"


def check_sample_step(value: Any) -> tuple[float | None, str | None]:
    """Check a ``sample_step:`` value.

    Parameters
    ----------
    value : object
        As written in ``dataset.yaml``.

    Returns
    -------
    step : float or None
        The step in s, or None when ``value`` is not valid.
    problem : str or None
        What is wrong, or None.

    Examples
    --------
    >>> check_sample_step(0.02)
    (0.02, None)
    >>> check_sample_step("TODO")[1][:40]
    "sample_step 'TODO' is not a number: the "
    """
    expected = (
        "the logging step in s (always s, whatever units: says), > 0 and at most "
        f"{MAX_SAMPLE_STEP:g}"
    )
    if isinstance(value, bool) or not isinstance(value, int | float):
        return None, f"sample_step {value!r} is not a number: {expected}, e.g. 0.02 for 50 Hz"
    step = float(value)
    if not (math.isfinite(step) and 0.0 < step <= MAX_SAMPLE_STEP):
        return None, f"sample_step = {value!r} is not {expected}"
    return step, None


def check_valve_edges(value: Any) -> tuple[str | None, str | None]:
    """Check a ``valve_edges:`` value: one of :data:`VALVE_EDGES`.

    Returns
    -------
    value : str or None
        The value, or None when it is not valid.
    problem : str or None
        What is wrong (with the closest value), or None.

    Examples
    --------
    >>> check_valve_edges("on_tick")
    ('on_tick', None)
    >>> check_valve_edges("ontick")[1][:51]
    "valve_edges 'ontick' is not one of on_tick, sampled"
    """
    if _is_one_of(value, VALVE_EDGES):
        return str(value), None
    meanings = "; ".join(f"{k}: {v}" for k, v in VALVE_EDGES.items())
    return None, (
        f"valve_edges {value!r} is not one of {_one_of(VALVE_EDGES)}{_suggest(value, VALVE_EDGES)} "
        f"({meanings}); leave it out to let the data decide"
    )


def index_time(offset: int, rows: int, sample_step: float) -> npt.NDArray[np.float64]:
    """Time stamps of rows ``offset`` to ``offset + rows - 1`` of a log without time stamps.

    Examples
    --------
    >>> index_time(2, 3, 0.02).tolist()
    [0.04, 0.06, 0.08]
    """
    return np.arange(offset, offset + rows, dtype=np.float64) * sample_step


def step_problem(median_step: float, sample_step: float, column: str) -> str | None:
    """What is wrong when a time column's median step (s) and ``sample_step`` disagree by
    more than :data:`STEP_TOLERANCE`, or None.

    Examples
    --------
    >>> step_problem(0.0201, 0.02, "time_ms") is None
    True
    >>> step_problem(0.025, 0.02, "time_ms")[:45]
    "the median step of the time column 'time_ms',"
    """
    if abs(median_step - sample_step) <= STEP_TOLERANCE * sample_step:
        return None
    return (
        f"the median step of the time column {column!r}, {median_step:.6g} s, disagrees with "
        f"sample_step = {sample_step:.6g} s by more than {STEP_TOLERANCE:.0%}; correct "
        "sample_step, or leave it out and let the time column give the time"
    )
