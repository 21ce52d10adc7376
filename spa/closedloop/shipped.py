"""One shipped controller: when the promise lengthens ``tau_c``, everything names that loop.

The ``closed_loop`` stage designs every setting at its ``tau_c`` and chooses one loop; the
promise over the identification's box (:func:`spa.closedloop.bench.bench_outputs`) may hold
only at a longer ``tau_c``, and then the header ships the loop designed there, with other
gains. :func:`ship_lengthened` makes ``controllers.yaml``'s chosen entry, its sentence and the
chosen setting's rows of ``table.csv`` (and Figs. 10-11's data) describe that loop, the one
in the header; the design at the stage's ``tau_c`` stays in ``controllers.yaml`` under
``for_comparison`` and in ``table.csv`` under a controller name that says so
(:func:`comparison_name`).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import pandas as pd

from spa.closedloop.controller import PIController
from spa.model.modulators import Modulator
from spa.model.params import ValveParams

__all__ = ["ShippedLoop", "comparison_name", "ship_lengthened", "shipped_loop"]


@dataclass(frozen=True)
class ShippedLoop:
    """The chosen setting's loop at the ``tau_c`` the header ships, when it is not the
    stage's.

    Attributes
    ----------
    label, name : str
        The setting's label and the controller (``fixed``, ``scheduled``, ``scheduled_ff``).
    tau_c, design_tau_c : float
        The shipped ``tau_c`` and the stage's, s.
    controller : dict
        The shipped PI's mapping (:meth:`PIController.to_mapping`).
    rows : list of dict
        Its ``table.csv`` rows (staircase, steps, sine), as the stage's.
    steps, trace : pandas.DataFrame
        Its Fig. 11 rows and Fig. 10 trace.
    """

    label: str
    name: str
    tau_c: float
    design_tau_c: float
    controller: dict[str, Any]
    rows: list[dict[str, Any]]
    steps: pd.DataFrame
    trace: pd.DataFrame


def comparison_name(name: str, tau_c: float) -> str:
    """The controller name of a design at another ``tau_c`` kept for comparison.

    Examples
    --------
    >>> comparison_name("scheduled", 0.2)
    'scheduled at tau_c = 0.2 s (for comparison, not shipped)'
    """
    return f"{name} at tau_c = {tau_c:g} s (for comparison, not shipped)"


def shipped_loop(
    mod: Modulator,
    name: str,
    ctrl: PIController,
    params: ValveParams,
    levels: list[float],
    cfg: Mapping[str, Any],
    tau_c: float,
    design_tau_c: float,
) -> ShippedLoop:
    """The shipped loop evaluated as the stage evaluates its designs (its table rows, steps
    and trace), on the setting's levels held as long as the stage holds them for that
    ``tau_c`` (:func:`spa.closedloop.comparison.level_hold`).

    Parameters
    ----------
    mod, name, ctrl
        The setting, the controller's name and the shipped PI.
    params : ValveParams
        The identified valve.
    levels : list of float
        The setting's set-points in ``controllers.yaml``, bar.
    cfg : mapping
        The ``closed_loop:`` section with its defaults filled in.
    tau_c, design_tau_c : float
        The shipped ``tau_c`` and the stage's, s.
    """
    from spa.closedloop.comparison import _evaluate, level_hold

    hold = level_hold(mod, params, levels, tau_c, cfg)
    rows, steps, trace = _evaluate(mod, name, ctrl, params, levels, cfg, hold)
    return ShippedLoop(
        mod.label,
        name,
        float(tau_c),
        float(design_tau_c),
        ctrl.to_mapping(),
        rows,
        pd.concat(steps, ignore_index=True),
        trace,
    )


def _swap(frame: pd.DataFrame, loop: ShippedLoop, new: pd.DataFrame, keep: bool) -> pd.DataFrame:
    """``frame`` with the chosen loop's rows replaced by ``new``'s; the old ones kept under
    :func:`comparison_name` when ``keep``."""
    if frame.empty or "controller" not in frame:
        return pd.concat([frame, new], ignore_index=True)
    mine = (frame["modulator"] == loop.label) & (frame["controller"] == loop.name)
    old = frame[mine].assign(controller=comparison_name(loop.name, loop.design_tau_c))
    parts = [frame[~mine], new, old] if keep else [frame[~mine], new]
    return pd.concat([p for p in parts if not p.empty], ignore_index=True)


def ship_lengthened(result: Any, loop: ShippedLoop) -> None:
    """Make ``result`` (a :class:`~spa.closedloop.comparison.ClosedLoopResult`) name the
    loop the header ships.

    * ``controllers.yaml``: the chosen entry's controller is the shipped PI, with its
      ``tau_c`` (``shipped_tau_c`` at the top level too); the stage's design is kept under
      ``for_comparison``, labelled as such.
    * The sentence's first clause (the setting, the PI's gains and its metrics) is the shipped
      loop's, and says that the promise lengthened ``tau_c``.
    * ``table.csv``: the chosen loop's rows are the shipped loop's; the stage's design keeps
      its rows under :func:`comparison_name`. Figs. 10-11 show the shipped loop.
    """
    from spa.closedloop.choice import closed_loop_sentence

    ctl = result.controllers
    gains = ctl["controllers"]
    entry = gains[loop.label]
    before = closed_loop_sentence(result.table, gains, loop.label, loop.name)
    entry["for_comparison"] = {
        "tau_c": loop.design_tau_c,
        loop.name: entry[loop.name],
        "note": (
            f"the {loop.name} PI designed at the stage's tau_c = {loop.design_tau_c:g} s, shown "
            f"for comparison: not shipped (the header ships tau_c = {loop.tau_c:g} s)"
        ),
    }
    entry[loop.name] = dict(loop.controller)
    entry["tau_c"] = loop.tau_c
    ctl["shipped_tau_c"] = loop.tau_c
    result.table = _swap(result.table, loop, pd.DataFrame(loop.rows), keep=True)
    result.steps = _swap(result.steps, loop, loop.steps, keep=False)
    result.traces = _swap(result.traces, loop, loop.trace, keep=False)
    after = closed_loop_sentence(result.table, gains, loop.label, loop.name)
    after = after.replace(" (Kp = ", f" designed at τ_c = {loop.tau_c:.3g} s (Kp = ", 1)
    after += (
        f" τ_c is lengthened from the stage's {loop.design_tau_c:g} s so that the promise "
        f"holds over the 95 % box; the design at {loop.design_tau_c:g} s is in controllers.yaml "
        "and table.csv for comparison only, not shipped."
    )
    sentence = str(ctl.get("sentence", ""))
    ctl["sentence"] = sentence.replace(before, after, 1) if before in sentence else after
