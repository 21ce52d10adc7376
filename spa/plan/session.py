"""A session's runs as the player plays them: segments of ticks, each a valve held, a level,
a staircase, a sine or a chirp of the input fraction, and how spa expands them into the
commands the player issues (:func:`run_commands`).

Every input fraction the player feeds its modulator is a Q15 fixed-point number,
``xi = q / 32768``, exact in float and double alike, so the board, the host harness and
spa's simulation feed the modulator the same value; sines and chirps are computed in float
(``double`` is 32-bit on AVR) before that rounding.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt

from spa.model.modulators import Modulator

__all__ = [
    "MODES",
    "Q15",
    "SESSION_KINDS",
    "PlannedRun",
    "Segment",
    "longest_high",
    "quantise",
    "run_commands",
    "run_xi",
]

#: Segment modes, as the player's header numbers them.
MODES = {"valve": 0, "level": 1, "sine": 2, "chirp": 3, "stair": 4, "loop": 5}

#: Kinds of the session's own runs, which dataset.yaml does not list.
SESSION_KINDS = ("zero", "precondition", "closed_loop")

#: The fixed-point scale of the input fraction the player logs and feeds its modulator.
Q15 = 32768


@dataclass(frozen=True, slots=True)
class Segment:
    """``ticks`` steps of one mode.

    ``valve``: the valve held at ``a`` (0 or 1). ``level``: ``xi = a``. ``sine``:
    ``xi = a + b sin(c k)`` with ``c`` rad per tick. ``chirp``: ``xi = a + b sin(c k + d k^2)``.
    ``stair``: ``xi = a + b floor(k / c)`` (``c`` ticks per level). ``loop``: the exported
    controller (``controller.h``) holds the set-point ``a`` bar, closed on the pressure read.
    ``k`` counts from the segment's start; ``log`` False: played but not printed (a fill
    before a discharge).
    """

    ticks: int
    mode: str
    a: float = 0.0
    b: float = 0.0
    c: float = 0.0
    d: float = 0.0
    log: bool = True


@dataclass(frozen=True, slots=True)
class PlannedRun:
    """One run of the session: its id, kind (``dataset.yaml``'s, or ``zero``,
    ``precondition`` and ``closed_loop`` for the session's own runs), segments and modulator
    (None: the valve is commanded directly, or by the controller in ``loop`` segments)."""

    id: str
    kind: str
    segments: tuple[Segment, ...]
    modulator: Modulator | None = None
    block: str = ""
    notes: str = ""
    meta: dict[str, Any] = field(default_factory=dict)

    @property
    def ticks(self) -> int:
        """Steps the run plays."""
        return sum(s.ticks for s in self.segments)

    @property
    def analysed(self) -> bool:
        """Whether ``dataset.yaml`` lists the run (the zero, preconditioning and closed-loop
        runs do not)."""
        return self.kind not in SESSION_KINDS

    @property
    def closed(self) -> bool:
        """Whether the run plays the exported controller (its commands follow the pressure)."""
        return any(s.mode == "loop" for s in self.segments)

    @property
    def file(self) -> str:
        """The run's file in the dataset folder."""
        return f"{'runs' if self.analysed else 'session'}/{self.id}.csv"

    def logged(self) -> npt.NDArray[np.bool_]:
        """Per tick, whether the player prints it."""
        return np.concatenate([np.full(s.ticks, s.log) for s in self.segments])


def quantise(xi: npt.ArrayLike) -> npt.NDArray[np.int32]:
    """Q15 counts of an input fraction, as the player rounds it: ``floor(xi*32768 + 0.5)``
    within [0, 32768].

    Examples
    --------
    >>> quantise([0.0, 0.1, 1.0, 1.2]).tolist()
    [0, 3277, 32768, 32768]
    """
    x = np.asarray(xi, dtype=np.float32) * np.float32(Q15) + np.float32(0.5)
    return np.clip(np.floor(x), 0, Q15).astype(np.int32)


def _sin(x: npt.NDArray[np.float32]) -> npt.NDArray[np.float32]:
    """``(float)sin(x)`` of the player: the float argument, sine in double, rounded."""
    return np.sin(x.astype(np.float64)).astype(np.float32)


def _segment_xi(s: Segment) -> npt.NDArray[np.float32]:
    """A segment's input fraction in float, the player's operations in its order."""
    k = np.arange(s.ticks, dtype=np.float32)
    f = np.float32
    if s.mode == "level":
        return np.full(s.ticks, f(s.a), dtype=np.float32)
    if s.mode == "sine":
        return f(s.a) + f(s.b) * _sin(k * f(s.c))
    if s.mode == "chirp":
        return f(s.a) + f(s.b) * _sin(k * f(s.c) + (k * k) * f(s.d))
    if s.mode == "stair":
        level = (np.arange(s.ticks) // int(s.c)).astype(np.float32)
        return f(s.a) + level * f(s.b)
    raise ValueError(f"segment mode {s.mode!r} has no input fraction")


def run_xi(run: PlannedRun) -> npt.NDArray[np.float64] | None:
    """The input fraction the player feeds the modulator at every tick (``q / 32768``), or
    None for a run that commands the valve directly."""
    if run.modulator is None:
        return None
    if run.closed:
        raise ValueError(f"run {run.id}: a closed loop's input fraction follows the pressure")
    q = np.concatenate([quantise(_segment_xi(s)) for s in run.segments])
    return q.astype(np.float64) / Q15


def run_commands(run: PlannedRun, dt: float) -> npt.NDArray[np.int8]:
    """The valve command the player issues at every tick of ``run`` (no venting): the
    segments' held valve, or spa's modulator (:meth:`Modulator.modulate`) on :func:`run_xi`.

    Raises
    ------
    ValueError
        For a closed-loop run: its commands follow the pressure (play it on a plant,
        :func:`spa.plan.host.play_on_plant`).
    """
    if run.closed:
        raise ValueError(f"run {run.id}: a closed loop's commands follow the pressure")
    xi = run_xi(run)
    if xi is None:
        return np.concatenate([np.full(s.ticks, int(s.a), dtype=np.int8) for s in run.segments])
    assert run.modulator is not None
    return run.modulator.modulate(xi, dt)


def longest_high(u: npt.ArrayLike) -> int:
    """The longest stretch of consecutive 1s, in steps.

    Examples
    --------
    >>> longest_high([0, 1, 1, 0, 1, 1, 1, 0])
    3
    """
    v = np.concatenate([[0], np.asarray(u, dtype=np.int8), [0]])
    edges = np.flatnonzero(np.diff(v))
    return int((edges[1::2] - edges[::2]).max()) if edges.size else 0
