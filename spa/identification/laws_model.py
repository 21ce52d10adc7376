"""The exact model under the actuator's own laws as the laws' fit sees it: the fit vector's
names, the valve it stands for, and a run's block means under a valve
(:mod:`spa.identification.laws_fit`, :mod:`spa.identification.laws_heldout`)."""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence

import numpy as np

from spa.identification.refine import RefineRun, block_means
from spa.identification.results import FloatArray
from spa.model.laws import DEFAULT_KNOTS, Laws
from spa.model.laws.sensitivity import law_replay_sensitivity
from spa.model.laws.timemap import FIT_NODES, law_replay
from spa.model.params import ValveParams

__all__ = ["law_model", "law_model_sensitivity", "law_names"]


def law_names(knots: Sequence[float] = DEFAULT_KNOTS) -> tuple[str, ...]:
    """Names of the fit vector: ``log_g[i]``, ``log_h[i]`` per knot, ``m``, then the
    valve's ``log_k2``, ``t_on`` and ``t_off``.

    Examples
    --------
    >>> law_names((0.0, 1.0))
    ('log_g[0]', 'log_g[1]', 'log_h[0]', 'log_h[1]', 'm', 'log_k2', 't_on', 't_off')
    """
    n = len(knots)
    return (
        *(f"log_g[{i}]" for i in range(n)),
        *(f"log_h[{i}]" for i in range(n)),
        "m",
        "log_k2",
        "t_on",
        "t_off",
    )


def law_model(
    run: RefineRun, prm: ValveParams, delay: str | None = None, nodes: int = FIT_NODES
) -> FloatArray:
    """Block means of the exact model's pressure at the run's samples, under ``prm``'s laws.

    The paper's laws (``prm.laws is None``) go through the refinement's own replay
    (:meth:`RefineRun.model`); general laws through their time maps with ``nodes`` per mode,
    from the same command runs (:attr:`RefineRun.command_starts`: an edge logged off the
    log's ticks moves alike under either laws).
    """
    dl = prm.delay if delay is None else delay
    if prm.laws is None:
        return run.model(prm, dl)
    hold = np.where(run.level, prm.t_on, prm.t_off)
    hold[0] = 0.0
    counts = run.samples_per_command if dl == "hold" else None
    p = law_replay(
        run.t, run.command_starts, run.level, hold, run.p0, prm, delay=dl, nodes=nodes,
        counts=counts,
    )  # fmt: skip
    return block_means(p, run.block)


def law_model_sensitivity(
    run: RefineRun, prm: ValveParams, delay: str | None = None, nodes: int = FIT_NODES
) -> tuple[FloatArray, FloatArray] | None:
    """:func:`law_model` and its exact derivatives in the fit vector's entries
    (:func:`law_names`: ``log_g[i]``, ``log_h[i]``, ``m``, ``log_k2``, ``t_on``,
    ``t_off``), block means of :func:`~spa.model.laws.sensitivity.law_replay_sensitivity`,
    shape ``(blocks, 2n + 4)``.

    None where they are not exact: the paper's laws (closed forms), the transport
    convention, or a run starting outside ``[0, k2]``; the caller then differentiates
    numerically.
    """
    dl = prm.delay if delay is None else delay
    if prm.laws is None or dl != "hold":
        return None
    hold = np.where(run.level, prm.t_on, prm.t_off)
    hold[0] = 0.0
    out = law_replay_sensitivity(
        run.t, run.command_starts, run.level, hold, run.p0, prm, nodes=nodes,
        counts=run.samples_per_command,
    )  # fmt: skip
    if out is None:
        return None
    p, dp = out
    return block_means(p, run.block), block_means(dp, run.block)


def _laws(x: FloatArray, knots: tuple[float, ...]) -> Laws:
    n = len(knots)
    return Laws(log_g=tuple(x[:n]), log_h=tuple(x[n : 2 * n]), m=float(x[2 * n]), knots=knots)


def _valve(start: ValveParams, x: FloatArray, knots: tuple[float, ...]) -> ValveParams:
    """``start`` with the laws, ``k2`` and delays of the full fit vector ``x``."""
    im = 2 * len(knots)
    return dataclasses.replace(
        start,
        k2=math.exp(x[im + 1]),
        t_on=float(x[im + 2]),
        t_off=float(x[im + 3]),
        laws=_laws(x, knots),
    )
