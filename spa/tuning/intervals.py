"""How the identification's uncertainty moves the tuning: corners of the 95 % box.

The identification gives a 95 % interval for each of ``c1``, ``k2``, ``tau2``, ``t_on`` and
``t_off`` (``params.yaml``: ``lo``, ``hi``). :func:`spa.identification.identified.corners`
lists the valves at every corner of that box (each parameter at its ``lo`` or its ``hi``, the
others too: ``2**k`` valves for ``k`` parameters with an interval) and :func:`propagate`
evaluates a result at each of them
and at the point estimate, returning the smallest and largest value. This is interval
propagation by corners, not a bootstrap: deterministic, and exact for results monotone in
each parameter (the optimum and ``J`` are, over these narrow boxes); it does not give a
coverage probability of its own.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable, Mapping

import numpy as np
import numpy.typing as npt

from spa._progress import progress
from spa.identification.identified import corners
from spa.model.params import ValveParams

__all__ = ["INTERVAL_METHOD", "box_points", "propagate", "spread"]

#: How the intervals of the tuning tables are obtained.
INTERVAL_METHOD = "corners"


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
        As :func:`~spa.identification.identified.corners`; without intervals both ends are
        ``result(params)``.

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
    points = box_points(params, intervals)
    values = np.array(
        [
            np.asarray(result(p), dtype=np.float64)
            for p in progress(points, "95 % box corners", unit="valve")
        ]
    )
    return spread(values)


def box_points(
    params: ValveParams, intervals: Mapping[str, tuple[float, float]] | None
) -> list[ValveParams]:
    """The point estimate, then every corner of the box (:func:`propagate`'s valves).

    Examples
    --------
    >>> [p.c1 for p in box_points(ValveParams(), {"c1": (0.5, 0.6)})]
    [0.533, 0.5, 0.6]
    """
    return [params, *corners(params, intervals)]


def spread(values: npt.ArrayLike) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
    """Element-wise smallest and largest of ``values`` over its first axis (one row a valve
    of :func:`box_points`); NaN where every row is NaN.

    Examples
    --------
    >>> lo, hi = spread([[1.0, np.nan], [3.0, np.nan]])
    >>> lo.tolist(), hi.tolist()
    ([1.0, nan], [3.0, nan])
    """
    with warnings.catch_warnings():  # an all-NaN column gives NaN, as documented
        warnings.simplefilter("ignore", RuntimeWarning)
        rows = np.asarray(values, dtype=np.float64)
        return np.nanmin(rows, axis=0), np.nanmax(rows, axis=0)
