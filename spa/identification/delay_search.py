"""A coarse search of the delays on the runs' cycle means: the refinement's start when the
three experiments leave a delay unresolved (:mod:`spa.identification.refined`)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from spa.identification.refine import _NOISE_FLOOR, RefineRun
from spa.model.params import ValveParams

__all__ = ["delay_search"]


def delay_search(
    runs: Sequence[RefineRun], start: ValveParams, max_delay: float, points: int = 11
) -> ValveParams:
    """``start`` with ``t_on`` then ``t_off`` set by a coarse search on the runs' cycle means.

    Each delay in turn takes the best of ``points`` values over ``[0, max_delay]`` (the
    other held), by the summed squared block residual, each run normalised by its own
    spread: ``2*points`` simulations of the runs.
    """
    grid = np.linspace(0.0, max_delay, points)
    scale = [max(float(np.std(r.y)), _NOISE_FLOOR) for r in runs]

    def cost(prm: ValveParams) -> float:
        return sum(
            float(np.sum(((r.model(prm) - r.y) / s) ** 2)) for r, s in zip(runs, scale, strict=True)
        )

    best = start
    for name in ("t_on", "t_off"):
        trials = [ValveParams(**{**best.as_dict(), name: float(g)}) for g in grid]
        best = min(trials, key=cost)
    return best
