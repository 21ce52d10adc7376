"""How the identification's uncertainty moves the tuning: corners of the 95 % box.

The identification gives a 95 % interval for each of ``c1``, ``k2``, ``tau2``, ``t_on`` and
``t_off`` (``params.yaml``: ``lo``, ``hi``). :func:`corners` lists the valves at every corner
of that box (each parameter at its ``lo`` or its ``hi``, the others too: ``2**k`` valves for
``k`` parameters with an interval) and :func:`propagate` evaluates a result at each of them
and at the point estimate, returning the smallest and largest value. This is interval
propagation by corners, not a bootstrap: deterministic, and exact for results monotone in
each parameter (the optimum and ``J`` are, over these narrow boxes); it does not give a
coverage probability of its own.
"""

from __future__ import annotations

import itertools
import warnings
from collections.abc import Callable, Mapping
from typing import Any

import numpy as np
import numpy.typing as npt

from spa import _checks as checks
from spa._progress import progress
from spa.model.params import ValveParams

__all__ = ["INTERVAL_METHOD", "PARAMETERS", "corners", "propagate", "read_intervals"]

#: The identified parameters, in ``params.yaml`` order.
PARAMETERS: tuple[str, ...] = ("c1", "k2", "tau2", "t_on", "t_off")

#: The delays: their domain includes 0 (a valve may switch at once).
DELAYS: tuple[str, ...] = ("t_on", "t_off")

#: How the intervals of the tuning tables are obtained.
INTERVAL_METHOD = "corners"

# A lower end at or below 0 (a delay's interval reaching 0) is raised to this, in the unit.
_FLOOR = 1e-12


def read_intervals(
    mapping: Mapping[str, Any], clipped: dict[str, str] | None = None
) -> dict[str, tuple[float, float]]:
    """The 95 % intervals of a ``params.yaml`` (:meth:`IdentificationResult.to_dict`).

    Parameters
    ----------
    mapping : mapping
        ``{"c1": {"value": ..., "lo": ..., "hi": ...}, ...}``; flat entries (a number) and
        entries whose ``lo`` or ``hi`` is null (a fallback value) have no interval.
    clipped : dict, optional
        Filled with ``name -> what was done`` for every interval clipped to the domain.

    Returns
    -------
    dict
        ``name -> (lo, hi)`` for the parameters that have an interval. A lower bound below
        the parameter's physical domain (a delay's interval reaching below 0, or a rate's at
        or below 0) is clipped to the domain's edge (0 for a delay, ``hi * 1e-3`` for the
        others): such an interval is a valid identification result, touching a bound; the
        corners of the box (:func:`corners`) then start at the bound.

    Raises
    ------
    ValueError
        If an interval is not finite or has ``lo > hi``; the message names the parameter.

    Examples
    --------
    >>> read_intervals({"c1": {"value": 0.5, "lo": 0.49, "hi": 0.51}, "k2": 0.8})
    {'c1': (0.49, 0.51)}
    >>> notes = {}
    >>> read_intervals({"t_on": {"value": 1e-6, "lo": -0.0002, "hi": 0.00068}}, notes)
    {'t_on': (0.0, 0.00068)}
    >>> notes["t_on"]
    'lower end -0.0002 clipped to the domain edge 0'
    """
    out: dict[str, tuple[float, float]] = {}
    for name in PARAMETERS:
        item = mapping.get(name)
        if not isinstance(item, Mapping) or item.get("lo") is None or item.get("hi") is None:
            continue
        lo = checks.number(f"{name}.lo", item["lo"])
        hi = checks.number(f"{name}.hi", item["hi"])
        if not (np.isfinite(lo) and np.isfinite(hi) and lo <= hi):
            raise ValueError(
                f"{name}: 95 % interval must be finite with lo <= hi, got [{lo}, {hi}]"
            )
        edge = 0.0 if name in DELAYS else (hi * 1e-3 if hi > 0 else _FLOOR)
        if lo < edge or (lo <= 0 and name not in DELAYS):
            if clipped is not None:
                clipped[name] = f"lower end {lo:g} clipped to the domain edge {edge:g}"
            lo = edge
            hi = max(hi, edge)
        out[name] = (lo, hi)
    return out


def corners(
    params: ValveParams, intervals: Mapping[str, tuple[float, float]] | None
) -> list[ValveParams]:
    """The valves at the corners of the box of ``intervals``.

    Parameters
    ----------
    params : ValveParams
        Point estimate; parameters without an interval keep its value.
    intervals : mapping or None
        ``name -> (lo, hi)`` (:func:`read_intervals`). A lower end <= 0 is raised to 1e-12.

    Returns
    -------
    list of ValveParams
        ``2**k`` valves (duplicates removed where ``lo == hi``); empty without intervals.

    Raises
    ------
    ValueError
        For an unknown parameter name.

    Examples
    --------
    >>> len(corners(ValveParams(), {"c1": (0.5, 0.56), "t_on": (0.002, 0.004)}))
    4
    """
    if not intervals:
        return []
    unknown = sorted(set(intervals) - set(PARAMETERS))
    if unknown:
        raise ValueError(f"intervals: unknown parameter(s) {unknown}; expected {PARAMETERS}")
    names = [n for n in PARAMETERS if n in intervals]
    ends = [tuple(dict.fromkeys(max(v, _FLOOR) for v in intervals[n])) for n in names]
    base = params.as_dict()
    return [
        ValveParams(**{**base, **dict(zip(names, c, strict=True))})
        for c in itertools.product(*ends)
    ]


def propagate(
    result: Callable[[ValveParams], npt.ArrayLike],
    params: ValveParams,
    intervals: Mapping[str, tuple[float, float]] | None,
) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
    """Smallest and largest ``result`` over the point estimate and the box's corners.

    Parameters
    ----------
    result : callable
        ``ValveParams -> array_like``; every call must give the same shape.
    params : ValveParams
        Point estimate.
    intervals : mapping or None
        As :func:`corners`; without intervals both ends are ``result(params)``.

    Returns
    -------
    lo, hi : numpy.ndarray
        Element-wise minimum and maximum (NaN where every evaluation is NaN).

    Examples
    --------
    >>> lo, hi = propagate(lambda p: p.c1 * p.k2, ValveParams(), {"c1": (0.5, 0.6)})
    >>> round(float(lo), 4), round(float(hi), 4)
    (0.4185, 0.5022)
    """
    points = [params, *corners(params, intervals)]
    values = np.array(
        [
            np.asarray(result(p), dtype=np.float64)
            for p in progress(points, "95 % box corners", unit="valve")
        ]
    )
    with warnings.catch_warnings():  # an all-NaN column gives NaN, as documented
        warnings.simplefilter("ignore", RuntimeWarning)
        return np.nanmin(values, axis=0), np.nanmax(values, axis=0)
