"""How a logged valve edge relates to the log's clock: the edge-timing rule of the delays.

A log shows the valve command at its samples. Where the controller issued every command on a
logging tick (it logs itself: a dSpace model, an Arduino loop), a logged edge *is* the edge:
``on_tick``, no correction. Where the command ran on its own, faster clock and the log only
samples it, the true edge lies somewhere within the logging step before the sample that first
shows it: ``sampled``, the edge taken at the middle of that step (half a step earlier) with
``w**2/12`` added to the delay's variance. Which one holds is a fact about the bench, declared
in ``dataset.yaml`` (``valve_edges``); where it is not declared, the data decide where they
can:

* a run whose command step is known (a simulated or closed-loop run's ``controller_dt``) at
  or above the logging step cannot switch between ticks: ``on_tick``;
* a modulated run whose modulator, replayed at the logging step from the logged input
  fraction, reproduces the logged valve reproduces every edge on a tick: those edges are
  ``on_tick``, and an edge it misses lies off the log's ticks (``sampled``, that edge alone);
* a run without an input fraction (a pulse train) follows the dataset's modulated runs when
  they all agree (one controller and one logger);
* otherwise the rule is ``undecided``: the delays are fitted as if on the tick, and their
  intervals reach one logging step above (``[d, d + w]``: the true edge may lie anywhere in
  the step before the logged one).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pandas as pd

from spa.model.plant import edge_indices

__all__ = [
    "EDGE_RULES",
    "EdgeTiming",
    "dataset_edge_timing",
    "edge_timing",
    "replayed_edges",
    "summary",
]

#: The rules a dataset may declare (``dataset.yaml``'s ``valve_edges``).
EDGE_RULES: tuple[str, ...] = ("on_tick", "sampled")

#: Share of a run's logged edges a replayed modulator must reproduce for the run to count as
#: logged on the controller's tick (a rounded logged input fraction may move an edge or two).
_ON_TICK_SHARE = 0.98


@dataclass(frozen=True)
class EdgeTiming:
    """A run's edge-timing rule.

    Attributes
    ----------
    rule : {"on_tick", "sampled", "undecided"}
        How the logged edges relate to the true ones.
    source : str
        What decided it: ``"declared"``, ``"command step"``, ``"modulator replayed"``,
        ``"the dataset's modulated runs"`` or ``"not decidable"``.
    width : float
        Logging step within which a true edge lies before the logged one, s (the step less
        the command's own step when that is known); 0 on the tick.
    off_tick : numpy.ndarray of bool or None
        Per logged edge (in order), whether it lies off the log's ticks; None: every edge as
        ``rule`` says.
    """

    rule: str
    source: str
    width: float
    off_tick: np.ndarray | None = field(default=None, repr=False, compare=False)

    def shifts(self, n_edges: int) -> np.ndarray:
        """How much earlier than logged each of ``n_edges`` edges is taken to be, s.

        Examples
        --------
        >>> EdgeTiming("sampled", "declared", 0.02).shifts(2).tolist()
        [0.01, 0.01]
        >>> EdgeTiming("on_tick", "declared", 0.0).shifts(2).tolist()
        [0.0, 0.0]
        """
        if self.rule != "sampled":
            return np.zeros(n_edges)
        if self.off_tick is not None and self.off_tick.size == n_edges:
            return np.where(self.off_tick, 0.5 * self.width, 0.0)
        return np.full(n_edges, 0.5 * self.width)

    def describe(self) -> str:
        """The rule in words, for ``params.yaml`` and the method text.

        Examples
        --------
        >>> EdgeTiming("undecided", "not decidable", 0.02).describe()
        'undecided (not decidable): edges taken on the tick, the delay up to 20 ms longer'
        """
        ms = f"{1e3 * self.width:.3g} ms"
        if self.rule == "on_tick":
            return f"on_tick ({self.source}): logged edges are the true edges"
        if self.rule == "sampled":
            some = "" if self.off_tick is None else f" ({int(self.off_tick.sum())} edge(s))"
            return f"sampled ({self.source}): true edges uniform within {ms} before the log's{some}"
        return f"undecided ({self.source}): edges taken on the tick, the delay up to {ms} longer"


def replayed_edges(
    table: pd.DataFrame, modulator: Mapping[str, Any] | Any, dt: float
) -> np.ndarray | None:
    """Which logged valve edges the modulator, replayed at the logging step, reproduces.

    Parameters
    ----------
    table : pandas.DataFrame
        A modulated run: ``u`` (input fraction) and ``valve`` at each logged sample.
    modulator : mapping or Modulator
        The run's modulator setting.
    dt : float
        The logging step, s.

    Returns
    -------
    numpy.ndarray of bool or None
        Per logged edge, whether the replay has the same edge at the same sample; None when
        the setting cannot be replayed from the log alone (a kind that needs the valve it
        inverts, or settings the log's step cannot run).

    Examples
    --------
    >>> from spa.model.modulators import modulate
    >>> u = np.full(200, 0.3)
    >>> run = pd.DataFrame({"u": u, "valve": modulate("pwm", u, 0.001, f_w=20.0)})
    >>> bool(replayed_edges(run, {"type": "pwm", "f_w": 20.0}, 0.001).all())
    True
    """
    from spa.model.modulators import Modulator

    if "u" not in table.columns or "valve" not in table.columns:
        return None
    try:
        mod = Modulator.from_mapping(modulator)
        replay = mod.modulate(table["u"].to_numpy(dtype=np.float64), dt)
    except (ValueError, TypeError, KeyError):
        return None
    valve = table["valve"].to_numpy().astype(np.int8)
    k = edge_indices(valve)
    if k.size == 0:
        return np.zeros(0, dtype=bool)
    same_level = replay[k] == valve[k]
    same_before = replay[k - 1] == valve[k - 1]
    return np.asarray(same_level & same_before, dtype=bool)


def edge_timing(
    table: pd.DataFrame, meta: Mapping[str, Any] | None, dt: float | None = None
) -> EdgeTiming:
    """A run's edge-timing rule, declared or decided from the run alone.

    Parameters
    ----------
    table : pandas.DataFrame
        The run table (``t``, ``valve``; ``u`` for a modulated run).
    meta : mapping, optional
        The run's metadata: ``valve_edges`` (declared), ``controller_dt`` (the command's own
        step, s) and ``modulator``.
    dt : float, optional
        The logging step, s (the median step of ``t`` when omitted).

    Returns
    -------
    EdgeTiming
        ``undecided`` when neither a declaration, the command step nor a replay settles it.

    Raises
    ------
    ValueError
        For a declared rule that is not one of :data:`EDGE_RULES`.

    Examples
    --------
    >>> run = pd.DataFrame({"t": [0.0, 0.02, 0.04], "valve": [0, 1, 1]})
    >>> edge_timing(run, {"valve_edges": "sampled"}).width
    0.02
    >>> edge_timing(run, {}).rule
    'undecided'
    >>> edge_timing(run, {"controller_dt": 0.02}).rule
    'on_tick'
    """
    meta = meta or {}
    if dt is None:
        dt = float(np.median(np.diff(table["t"].to_numpy(dtype=np.float64))))
    # A step read off float time stamps (0.000999...) is the clock's nominal step: a modulator
    # replayed at the unrounded one drifts a whole step over a long run.
    dt = float(f"{dt:.9g}")
    declared = meta.get("valve_edges")
    cdt = meta.get("controller_dt")
    cdt = float(cdt) if cdt else None
    width = dt if cdt is None else max(dt - cdt, 0.0)
    if declared is not None:
        if declared not in EDGE_RULES:
            raise ValueError(
                f"valve_edges must be one of {', '.join(EDGE_RULES)}, got {declared!r}"
            )
        return EdgeTiming(declared, "declared", width if declared == "sampled" else 0.0)
    if cdt is not None and cdt >= dt * (1.0 - 1e-6):
        return EdgeTiming("on_tick", "command step", 0.0)
    mod = meta.get("modulator")
    if mod:
        same = replayed_edges(table, mod, dt)
        if same is not None and same.size:
            if same.mean() >= _ON_TICK_SHARE:
                return EdgeTiming("on_tick", "modulator replayed", 0.0)
            return EdgeTiming("sampled", "modulator replayed", width, ~same)
    return EdgeTiming("undecided", "not decidable", width)


def dataset_edge_timing(
    runs: Mapping[str, pd.DataFrame], metas: Mapping[str, Mapping[str, Any]]
) -> dict[str, EdgeTiming]:
    """Every run's edge-timing rule, the undecided ones following the dataset's decided runs.

    A run the data alone cannot decide (a pulse train, no declaration, no command step) takes
    the rule of the dataset's runs that a replay decided, when they all agree: one bench
    logs them all with one controller. Otherwise it stays ``undecided``.

    Parameters
    ----------
    runs : mapping
        Run id → table (runs without a ``valve`` column are left out).
    metas : mapping
        Run id → metadata (:func:`edge_timing`).

    Returns
    -------
    dict
        Run id → :class:`EdgeTiming`.
    """
    out = {}
    for rid in sorted(runs):
        table = runs[rid]
        if "valve" not in table.columns or len(table) < 2:
            continue
        out[rid] = edge_timing(table, metas.get(rid))
    replayed = {e.rule for e in out.values() if e.source == "modulator replayed"}
    if len(replayed) == 1:
        (rule,) = replayed
        for rid, e in out.items():
            if e.rule == "undecided":
                width = e.width if rule == "sampled" else 0.0
                out[rid] = EdgeTiming(rule, "the dataset's modulated runs", width)
    return out


def summary(timings: Mapping[str, EdgeTiming]) -> dict[str, Any]:
    """``params.yaml``'s ``valve_edges``: the rule of each run and of the dataset.

    Examples
    --------
    >>> summary({"a": EdgeTiming("on_tick", "declared", 0.0)})["rule"]
    'on_tick'
    """
    rules = {e.rule for e in timings.values()}
    rule = rules.pop() if len(rules) == 1 else ("mixed" if rules else "none")
    return {
        "rule": rule,
        "runs": {rid: e.describe() for rid, e in sorted(timings.items())},
    }
