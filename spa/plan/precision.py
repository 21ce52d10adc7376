"""Predicted precision: the plan's identification runs simulated on its prior and on corners
3× slower and 3× faster, logged through the declared calibration with sensor noise, and
identified as ``spa identify`` would; the 95 % half-widths against the targets.

Targets: each delay known to one tick (the log cannot place an edge finer), ``c1``, ``k2``
and ``tau2`` to 5 % (the tuning's cost J moves by about that much over such a box).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
import pandas as pd

from spa.model.params import ValveParams
from spa.plan.design import SessionDesign
from spa.plan.prior import scaled
from spa.plan.session import run_commands

__all__ = ["CORNERS", "MAX_RESIZES", "predict_precision", "size_for_targets", "targets"]

#: Times a plan is resized when its predicted precision misses a target.
MAX_RESIZES = 2

#: The valves the plan is checked on: ``name -> time-scale factor`` of the prior.
CORNERS = {"prior": 1.0, "3x faster": 1.0 / 3.0, "3x slower": 3.0}

_NAMES = ("c1", "k2", "tau2", "t_on", "t_off")


def targets(params: ValveParams, dt: float) -> dict[str, float]:
    """The half-width each parameter should reach, in its unit."""
    return {
        "c1": 0.05 * params.c1,
        "k2": 0.05 * params.k2,
        "tau2": 0.05 * params.tau2,
        "t_on": dt,
        "t_off": dt,
    }


def _runs(
    design: SessionDesign, valve: ValveParams, cal: dict[str, Any], noise: float, seed: int
) -> tuple[dict[str, pd.DataFrame], dict[str, dict[str, Any]]]:
    from spa import simulate
    from spa.plan.host import counts

    rng = np.random.default_rng(seed)
    runs, metas = {}, {}
    for run in design.runs:
        if run.kind not in ("charge", "discharge", "pulse"):
            continue
        u = run_commands(run, design.dt)
        p = simulate(u, design.dt, valve)
        c = counts(p + rng.normal(0.0, noise, p.size), cal)
        keep = run.logged()
        t = np.arange(int(keep.sum())) * design.dt
        pv = (c[keep] - cal["zero_counts"]) * cal["bar_per_count"]
        runs[run.id] = pd.DataFrame({"t": t, "p": pv, "valve": u[keep]})
        metas[run.id] = {"kind": run.kind, "valve_edges": "on_tick"}
    return runs, metas


def predict_precision(
    design: SessionDesign, cal: dict[str, Any], noise: float = 0.003, seed: int = 0
) -> pd.DataFrame:
    """The 95 % half-widths the plan's identification runs give on each corner.

    Returns
    -------
    pandas.DataFrame
        One row per corner and parameter: ``corner``, ``parameter``, ``truth``, ``value``,
        ``half_width``, ``target``, ``met`` (half-width within the target and the truth
        inside the interval), ``covered``; a corner that does not identify has NaN values and
        ``met`` False, with the reason in ``note``.
    """
    from spa.identification import identify_with_config

    rows = []
    for corner, factor in CORNERS.items():
        valve = scaled(design.prior, factor)
        goal = targets(valve, design.dt)
        runs, metas = _runs(design, valve, cal, noise, seed)
        try:
            res = identify_with_config(
                runs, {k: m["kind"] for k, m in metas.items()}, None, metas=metas
            ).to_dict()
            note = ""
        except (ValueError, RuntimeError) as exc:
            res, note = {}, str(exc)
        for name in _NAMES:
            entry = res.get(name) if isinstance(res.get(name), dict) else {}
            value = entry.get("value", np.nan)
            lo, hi = entry.get("lo"), entry.get("hi")
            half = (hi - lo) / 2 if lo is not None and hi is not None else np.nan
            truth = float(getattr(valve, name))
            covered = lo is not None and hi is not None and lo <= truth <= hi
            rows.append(
                {
                    "corner": corner,
                    "parameter": name,
                    "truth": truth,
                    "value": value,
                    "half_width": half,
                    "target": goal[name],
                    "met": bool(np.isfinite(half) and half <= goal[name] * (1 + 1e-6) and covered),
                    "covered": bool(covered),
                    "note": note,
                }
            )
    return pd.DataFrame(rows)


def size_for_targets(
    make: Callable[[int, float], SessionDesign],
    replicates: int,
    margin: float,
    cal: dict[str, Any],
    rounds: int = MAX_RESIZES,
) -> tuple[SessionDesign, pd.DataFrame, list[str]]:
    """Design, predict the precision, and resize while a target is missed.

    Each resize adds two replicates of the identification runs (a half-width shrinks about
    as one over the square root of the runs) and, when a corner did not identify at all
    (its runs too short for it: ``note``), widens the margin by half.

    Parameters
    ----------
    make : callable
        ``(replicates, margin) -> SessionDesign``.
    replicates, margin : int, float
        The first design's.
    cal : dict
        The declared calibration.
    rounds : int, default :data:`MAX_RESIZES`
        Resizes at most.

    Returns
    -------
    design : SessionDesign
        The last design (the first that meets every target, else the last tried).
    table : pandas.DataFrame
        Its :func:`predict_precision`.
    said : list of str
        One sentence per resize, naming the targets missed and what changed.
    """
    design = make(replicates, margin)
    table = predict_precision(design, cal)
    said: list[str] = []
    for _ in range(max(0, int(rounds))):
        missed = table[~table["met"]]
        if missed.empty:
            break
        unidentified = bool((missed["note"] != "").any())
        names = ", ".join(dict.fromkeys(f"{r.parameter} ({r.corner})" for r in missed.itertuples()))
        replicates += 2
        margin = margin * 1.5 if unidentified else margin
        said.append(
            f"resized: {names} missed the target; now {replicates} replicates"
            + (f", runs sized for valves {margin:.3g}x slower and faster" if unidentified else "")
        )
        design = make(replicates, margin)
        table = predict_precision(design, cal)
    return design, table, said
