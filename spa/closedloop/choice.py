"""Which loop the closed-loop design recommends, and the recommendation in words.

Over every designed setting and controller (:data:`CONTROLLERS`), :func:`ranked_choices` puts
first the fastest loop whose worst-case overshoot over the set-point staircase is at most
:data:`MAX_OVERSHOOT` % with every step settled within :data:`SETTLED` % (:func:`end_error`);
:func:`closed_loop_sentence` says what it does and :func:`held_clause` which pressures a setting
cannot hold on the valve.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np
import pandas as pd

from spa.closedloop.levels import idle_duty
from spa.model.modulators import Modulator
from spa.model.params import ValveParams

__all__ = [
    "CONTROLLERS",
    "MAX_OVERSHOOT",
    "SETTLED",
    "TAU_C_FACTORS",
    "closed_loop_sentence",
    "end_error",
    "held_clause",
    "ranked_choices",
]

#: The controllers designed for every setting, in the order of the tables.
CONTROLLERS = ("fixed", "scheduled", "scheduled_ff")


#: Worst-case overshoot (%) over the staircase that a chosen loop may have (default of the
#: config's ``closed_loop.max_overshoot``).
MAX_OVERSHOOT = 10.0

#: Factors by which ``tau_c`` is lengthened, in turn, when no loop meets ``max_overshoot``.
TAU_C_FACTORS = (2.0, 4.0, 8.0)


def _least_overshoot(table: pd.DataFrame) -> float | None:
    if table.empty:
        return None
    sel = table[(table.experiment == "staircase") & (table.metric == "overshoot")]
    values = sel["max"].to_numpy(np.float64)
    values = values[np.isfinite(values)]
    return float(values.min()) if values.size else None


#: A step is settled when its mean pressure over the last quarter of the step is within
#: this share of the step, %.
SETTLED = 2.0


class _Staircases:
    """The staircase's metrics of every designed loop, read once from the comparison's table
    and looked up by (setting, controller, metric), rather than filtering the whole table
    for each of a ranking's questions (a key's first row, as a filter's first match)."""

    def __init__(self, table: pd.DataFrame) -> None:
        self._rows: dict[tuple[str, str, str], tuple[float, float]] = {}
        if table.empty:  # nothing designed: no columns either
            return
        sel = table[table.experiment == "staircase"]
        for label, controller, metric, worst, missing in zip(
            sel.modulator,
            sel.controller,
            sel.metric,
            sel["max"].to_numpy(np.float64),
            sel["n_missing"].to_numpy(np.float64),
            strict=True,
        ):
            key = (str(label), str(controller), str(metric))
            self._rows.setdefault(key, (float(worst), float(missing)))

    def worst(self, label: str, controller: str, metric: str) -> float:
        """The worst value of a staircase metric of a loop (NaN when the loop has none)."""
        return self._rows.get((label, controller, metric), (math.nan, 0.0))[0]

    def settled(self, label: str, controller: str) -> bool:
        """Every staircase step of the loop ends within :data:`SETTLED` % of its size (the
        mean pressure over the last quarter of the step, as a bench measures it)."""
        row = self._rows.get((label, controller, "end_error"))
        if row is None or int(row[1]) != 0:
            return False
        return bool(row[0] <= SETTLED)

    def meets(self, label: str, controller: str, limit: float) -> bool:
        """The loop overshoots at most ``limit`` % over the staircase AND every step ends
        within 2 % of its size (:meth:`settled`): a longer ``tau_c`` that trades overshoot
        for a loop that never settles does not meet."""
        over = self.worst(label, controller, "overshoot")
        return bool(math.isfinite(over) and over <= limit and self.settled(label, controller))


def end_error(steps: pd.DataFrame) -> np.ndarray:
    """Each step's steady-state error in % of its size: ``100*|sse|/|r1 - r0|``.

    Examples
    --------
    >>> e = end_error(pd.DataFrame({"r0": [0.1, 0.4], "r1": [0.4, 0.1],
    ...                             "steady_state_error": [0.003, -0.0015]}))
    >>> e.round(9).tolist()
    [1.0, 0.5]
    """
    size = np.abs(steps["r1"].to_numpy(np.float64) - steps["r0"].to_numpy(np.float64))
    sse = np.abs(steps["steady_state_error"].to_numpy(np.float64))
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(size > 0.0, 100.0 * sse / size, np.nan)


def _measured(recommendation: Mapping[str, Any] | None) -> frozenset[str] | None:
    """The modulator types a loop can be verified with: run on this bench and described by
    the model there (the recommendation's ``adequacy``,
    :meth:`spa.identification.adequacy.Adequacy.modulator_adequate`); None when not assessed.

    Examples
    --------
    >>> sorted(_measured({"adequacy": {"measured_modulators": ["pwm", "dsm"]}}))
    ['dsm', 'pwm']
    >>> _measured({}) is None
    True
    """
    from spa.identification.adequacy import Adequacy

    adequacy = (recommendation or {}).get("adequacy")
    kinds = adequacy.get("measured_modulators") if isinstance(adequacy, Mapping) else None
    if not kinds:
        return None
    a = Adequacy.from_mapping(adequacy)
    return frozenset(str(k) for k in kinds if a.modulator_adequate(str(k)))


def ranked_choices(
    table: pd.DataFrame,
    rec: Modulator | None,
    limit: float = 10.0,
    measured: frozenset[str] | None = None,
) -> list[tuple[str, str]]:
    """Every designed (setting, controller), best first. The best: over every designed
    setting and controller, the smallest worst-case rise time among those overshooting at
    most ``limit`` % over the staircase with every step settled (:meth:`_Staircases.meets`); else,
    among those that settle, the smallest worst-case overshoot; else the smallest worst-case
    overshoot. Ties go to the tuning's recommended setting, then to the order of the table.
    When ``measured`` (the modulator types run on this bench and described there by the
    model, :func:`_measured`) is given, a loop of such a modulator goes before one of
    another, among those that meet the design: only such a loop can be verified.

    The open-loop recommendation ranks linearity; a loop also needs speed without overshoot,
    so the closed loop chooses on its own metrics (its sentence names the setting).
    """
    if table.empty:
        return []
    designed = list(dict.fromkeys(table.modulator))
    recommended = rec.label if rec is not None else None
    stairs = _Staircases(table)
    scores = []
    for order, label in enumerate(designed):
        for name in CONTROLLERS:
            rise = stairs.worst(label, name, "rise_time")
            over = stairs.worst(label, name, "overshoot")
            if not (math.isfinite(rise) and math.isfinite(over)):
                continue
            ok = stairs.meets(label, name, limit)
            settled = stairs.settled(label, name)
            key = rise if ok else over
            kind = label.split("-", 1)[0]  # Modulator.label: "<type>-<setting>"
            unmeasured = measured is not None and kind not in measured
            scores.append(
                (not ok, not settled, unmeasured, key, label != recommended, order, label, name)
            )
    return [(label, name) for *_, label, name in sorted(scores)]


def closed_loop_sentence(
    table: pd.DataFrame, gains: Mapping[str, Any], label: str, controller: str
) -> str:
    """The recommendation: ``use <setting> with the <controller> PI (Kp, Ki): rise <= ...``."""
    g = gains[label][controller]
    desc = table.loc[table.modulator == label, "description"].iloc[0]

    def fmt(v: Any) -> str:
        if isinstance(v, list):
            return f"{min(v):.3g}–{max(v):.3g}"
        return f"{v:.3g}"

    kind = {"fixed": "fixed", "scheduled": "gain-scheduled", "scheduled_ff": "gain-scheduled"}
    ff = " with the averaged-model feed-forward" if controller == "scheduled_ff" else ""
    stairs = _Staircases(table)
    rise = stairs.worst(label, controller, "rise_time")
    over = stairs.worst(label, controller, "overshoot")
    sse = table[
        (table.modulator == label)
        & (table.controller == controller)
        & (table.experiment == "staircase")
        & (table.metric == "steady_state_error")
    ]
    err = max(abs(float(sse["min"].iloc[0])), abs(float(sse["max"].iloc[0])))
    settle = stairs.worst(label, controller, "settling_time")
    levels = gains[label].get("levels") or []
    where = f" {min(levels):.3g}–{max(levels):.3g} bar" if levels else ""
    rise_text = (
        f"rise time (10–90 %) ≤ {rise:.2f} s"
        if math.isfinite(rise)
        else "a step that does not reach 90 %"
    )
    settle_text = (
        f", settling (2 %) ≤ {settle:.2f} s" if math.isfinite(settle) else ", a level not settled"
    )
    err_text = f"{err * 1e3:.1f} mbar" if math.isfinite(err) else "unknown"
    return (
        f"Closed loop: use {desc} with the {kind[controller]} PI{ff} "
        f"(Kp = {fmt(g['kp'])} /bar, Ki = {fmt(g['ki'])} /(bar·s), controllers.yaml): over the "
        f"set-point staircase{where}, {rise_text}, overshoot ≤ {over:.0f} %{settle_text} "
        f"and steady-state error ≤ {err_text} in the exact simulation of the identified model."
    )


def held_clause(
    setting: Mapping[str, Any] | Modulator,
    params: ValveParams,
    held: tuple[float, float] | list[float],
    max_fraction: float = 1.0,
) -> str:
    """Which pressures the setting cannot hold on the valve, in one sentence.

    Examples
    --------
    >>> held_clause({"type": "iipfm", "t_l": 0.02, "gain": 1.15}, ValveParams(k2=5.5),
    ...             (1.07, 5.2), 0.95)[:62]
    'It holds 1.07–5.2 bar on this valve and cannot hold below 1.07'
    """
    lo, hi = float(held[0]), float(held[1])
    text = f"It holds {lo:.3g}–{hi:.3g} bar on this valve"
    low = lo > 0.02 * params.k2
    idle = idle_duty(setting, params)
    if low:
        text += f" and cannot hold below {lo:.3g} bar"
        if idle > 0.005:
            text += f" (at ξ = 0 it still opens the valve {idle * 100:.0f} % of the time)"
    if hi < 0.98 * max_fraction * params.k2:
        text += f", nor above {hi:.3g} bar" if low else f" and cannot hold above {hi:.3g} bar"
    return text + "."
