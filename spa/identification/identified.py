"""The valve as an identification left it: ``params.yaml`` read once, with its 95 % box.

:func:`read_identified` reads an identification's ``params.yaml`` (its point estimates, 95 %
intervals, fallbacks and adequacy) into an :class:`Identified` and refuses one that failed
(:class:`TuningError`: nothing to tune or design with); the tuning and the closed-loop design
both start from it. :func:`read_intervals` reads the intervals alone and :func:`corners` lists
the valves at the corners of their box (each parameter at its ``lo`` or its ``hi``: ``2**k``
valves for ``k`` parameters with an interval), which the tuning
(:func:`spa.tuning.intervals.propagate`) and the closed loop's robust design evaluate.
"""

from __future__ import annotations

import itertools
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from spa import _checks as checks
from spa._yaml import read_yaml
from spa.identification.results import _delay_of, _laws_of
from spa.model.params import ValveParams

__all__ = [
    "DELAYS",
    "PARAMETERS",
    "Identified",
    "TuningError",
    "corners",
    "laws_intervals",
    "read_identified",
    "read_intervals",
    "unresolved_clause",
]

#: The identified parameters, in ``params.yaml`` order.
PARAMETERS: tuple[str, ...] = ("c1", "k2", "tau2", "t_on", "t_off")

#: The interval of ``t_off - t_on`` a transport-delay identification adds
#: (``params.yaml``'s ``delay_difference``): with it, the box's delays span their mean's
#: range and their difference's (:func:`corners`).
DIFFERENCE = "delay_difference"

#: The delays: their domain includes 0 (a valve may switch at once).
DELAYS: tuple[str, ...] = ("t_on", "t_off")

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
        interval = _interval(mapping, name)
        if interval is None:
            continue
        lo, hi = interval
        edge = 0.0 if name in DELAYS else (hi * 1e-3 if hi > 0 else _FLOOR)
        if lo < edge or (lo <= 0 and name not in DELAYS):
            if clipped is not None:
                clipped[name] = f"lower end {lo:g} clipped to the domain edge {edge:g}"
            lo = edge
            hi = max(hi, edge)
        out[name] = (lo, hi)
    difference = _interval(mapping, DIFFERENCE)  # signed: no domain edge
    if difference is not None:
        out[DIFFERENCE] = difference
    return out


def _interval(mapping: Mapping[str, Any], name: str) -> tuple[float, float] | None:
    """``mapping[name]``'s ``(lo, hi)``, checked finite with ``lo <= hi``; None for a flat
    entry or one whose ``lo`` or ``hi`` is null (no interval)."""
    item = mapping.get(name)
    if not isinstance(item, Mapping) or item.get("lo") is None or item.get("hi") is None:
        return None
    lo = checks.number(f"{name}.lo", item["lo"])
    hi = checks.number(f"{name}.hi", item["hi"])
    if not (np.isfinite(lo) and np.isfinite(hi) and lo <= hi):
        raise ValueError(f"{name}: 95 % interval must be finite with lo <= hi, got [{lo}, {hi}]")
    return lo, hi


def laws_intervals(
    record: Mapping[str, Any], params: ValveParams, clipped: dict[str, str] | None = None
) -> dict[str, tuple[float, float]]:
    """The 95 % intervals of a valve with the actuator's own laws, from the ``laws:`` record.

    Parameters
    ----------
    record : mapping
        ``params.yaml``'s ``laws:`` (chosen ``identified``): its ``bands``, ``visited`` and
        ``covariance`` (:func:`spa.identification.laws_record.laws_record`).
    params : ValveParams
        The laws valve (its ``c1``, ``tau2``, ``k2`` and delays are the centres).
    clipped : dict, optional
        Filled with ``name -> note`` for a delay's interval clipped at 0.

    Returns
    -------
    dict
        ``name -> (lo, hi)``:

        * ``tau2`` and ``c1``: the envelopes of the simultaneous bands. The laws' rates scale
          as ``1/tau2`` (charge) and ``1/c1`` (discharge), so a band that lies within
          ``f*(1 + delta)**(±1)`` over the pressures the data visited in that mode
          (:func:`spa.identification.laws_bands.band_envelope`, ``delta`` the largest
          relative half-width there, leaving out the tenth of ``k2`` next to each law's zero,
          where rate and band both vanish) is ``[tau2/(1 + delta_open), tau2*(1 + delta_open)]``
          and ``[c1/(1 + delta_closed), c1*(1 + delta_closed)]``: each corner scales the
          whole law by ``1/(1 ∓ delta')`` with ``1 - delta' = 1/(1 + delta)``.
        * ``k2``: ``k2*exp(±1.96 se)``, ``se`` the laws fit's standard error of ``log k2``.
        * ``t_on``, ``t_off``: ``±1.96 se`` of the laws fit (clipped at 0), and
          ``delay_difference``: ``t_off - t_on`` ± 1.96 times its standard error from the
          same covariance, so that :func:`corners` moves the delays together.

        An entry the record does not give (no bands, no covariance) is left out.

    Raises
    ------
    ValueError
        If the covariance is not square over its names, or a band is malformed; named.

    Examples
    --------
    >>> rec = {"bands": {"grid": [0.2, 0.4], "open": {"rate": [1, 1], "lo": [.8, .9],
    ...        "hi": [1.25, 1.1]}, "closed": {"rate": [-1, -1], "lo": [-1.1, -1.1],
    ...        "hi": [-.95, -.95]}}, "visited": {"open": [0, 0.5], "closed": [0, 0.5]}}
    >>> iv = laws_intervals(rec, ValveParams(tau2=1.0, c1=0.5))
    >>> [round(v, 3) for v in iv["tau2"]], [round(v, 3) for v in iv["c1"]]
    ([0.8, 1.25], [0.455, 0.55])
    """
    from spa.identification.laws_bands import band_envelope

    out: dict[str, tuple[float, float]] = {}
    bands = record.get("bands")
    if isinstance(bands, Mapping):
        try:
            delta = band_envelope(bands, record.get("visited"), params.k2)
        except (KeyError, TypeError, ValueError) as exc:
            raise ValueError(
                f"laws.bands: malformed ({exc!r}); expected LawBands.to_dict()'s form"
            ) from None
        for name, mode in (("tau2", "open"), ("c1", "closed")):
            d = delta[mode]
            if np.isfinite(d):
                x = float(getattr(params, name))
                out[name] = (x / (1.0 + d), x * (1.0 + d))
    cov = record.get("covariance")
    if isinstance(cov, Mapping) and cov.get("names"):
        names = [str(n) for n in cov["names"]]
        matrix = np.asarray(cov.get("matrix"), dtype=np.float64)
        if matrix.shape != (len(names), len(names)):
            raise ValueError(
                f"laws.covariance: matrix must be {len(names)}x{len(names)} over its names, "
                f"got shape {matrix.shape}"
            )
        idx = {n: i for i, n in enumerate(names)}
        var = np.maximum(np.diag(matrix), 0.0)
        if "log_k2" in idx:
            half = 1.96 * float(np.sqrt(var[idx["log_k2"]]))
            out["k2"] = (params.k2 * float(np.exp(-half)), params.k2 * float(np.exp(half)))
        if "t_on" in idx and "t_off" in idx:
            i, j = idx["t_on"], idx["t_off"]
            for name, k in (("t_on", i), ("t_off", j)):
                x = float(getattr(params, name))
                half = 1.96 * float(np.sqrt(var[k]))
                if x - half < 0.0 and clipped is not None:
                    clipped[name] = f"lower end {x - half:g} clipped to the domain edge 0"
                out[name] = (max(x - half, 0.0), x + half)
            sd = float(np.sqrt(max(var[i] + var[j] - 2.0 * matrix[i, j], 0.0)))
            gap = params.t_off - params.t_on
            out[DIFFERENCE] = (gap - 1.96 * sd, gap + 1.96 * sd)
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
        With ``delay_difference`` beside ``t_on`` and ``t_off``, the delays' corners are
        those of their mean (between the means of the two intervals' ends) and of their
        difference ``t_off - t_on`` (its own interval), not of the two delays apart: the
        delays' errors move together, and two delays at opposite ends of their intervals
        would make a valve whose pulses gain a time the data exclude.

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
    unknown = sorted(set(intervals) - {*PARAMETERS, DIFFERENCE})
    if unknown:
        raise ValueError(f"intervals: unknown parameter(s) {unknown}; expected {PARAMETERS}")
    paired = DIFFERENCE in intervals and "t_on" in intervals and "t_off" in intervals
    names = [n for n in PARAMETERS if n in intervals and not (paired and n in DELAYS)]
    ends = [tuple(dict.fromkeys(max(v, _FLOOR) for v in intervals[n])) for n in names]
    delays: list[dict[str, float]] = [{}]
    if paired:
        (on_lo, on_hi), (off_lo, off_hi) = intervals["t_on"], intervals["t_off"]
        means = dict.fromkeys((0.5 * (on_lo + off_lo), 0.5 * (on_hi + off_hi)))
        delays = [
            {"t_on": max(m - 0.5 * d, _FLOOR), "t_off": max(m + 0.5 * d, _FLOOR)}
            for m in means
            for d in dict.fromkeys(intervals[DIFFERENCE])
        ]
    base = params.as_dict()
    return [
        ValveParams(**{**base, **dict(zip(names, c, strict=True)), **pair})
        for c in itertools.product(*ends)
        for pair in delays
    ]


def unresolved_clause(unresolved: Mapping[str, Any] | None) -> str:
    """A clause naming the delays the data do not resolve and the interval designed over.

    Parameters
    ----------
    unresolved : mapping or None
        ``name -> (lo, hi)`` in s (:attr:`Identified.unresolved`).

    Returns
    -------
    str
        ``""`` when every delay is resolved.

    Examples
    --------
    >>> unresolved_clause({"t_on": (0.0, 0.05)})
    't_on is not resolved by the data: designed over its interval [0, 50] ms (worst case 50 ms)'
    """
    parts = [
        f"{name} is not resolved by the data: designed over its interval "
        f"[{1e3 * lo:.3g}, {1e3 * hi:.3g}] ms (worst case {1e3 * hi:.3g} ms)"
        for name, (lo, hi) in (unresolved or {}).items()
    ]
    return "; ".join(parts)


class TuningError(ValueError):
    """The valve cannot be tuned or a loop designed for it (no usable identification): the
    message says why. Its name is the tuning's, the first stage that reads the valve back."""


@dataclass(frozen=True)
class Identified:
    """A valve as an identification left it: parameters, 95 % intervals, fallbacks.

    Attributes
    ----------
    params : ValveParams
        Point estimates.
    intervals : dict
        ``name -> (lo, hi)`` for the parameters with an interval.
    fallback : dict
        ``name -> reason`` for parameters that took a nominal value instead of a fit.
    source : str
        Where they came from (a file name, or ``"arguments"``).
    clipped : dict
        ``name -> note`` for intervals clipped to the parameter's domain
        (:func:`read_intervals`).
    adequacy : dict or None
        The identification's ``adequacy:`` (None: not assessed).
    unresolved : dict
        ``name -> (lo, hi)`` for the delays the data do not resolve (``resolved: false``):
        ``params`` holds their worst case ``hi`` and the box spans the whole interval, so no
        design rests on a point the data do not give.
    laws : mapping or None
        The actuator's own laws' coefficients when the identification chose them
        (``params.yaml``'s ``laws:``), else None. ``params`` then IS the laws valve
        (``params.laws`` set, ``k2`` and the delays those fitted with the laws) and the
        intervals are the laws' (:func:`laws_intervals`: ``c1`` and ``tau2`` the envelopes of
        the simultaneous bands), so every stage that reads the valve designs on the laws the
        identification chose; ``adequacy`` is then that model's held-out verdict.
    """

    params: ValveParams
    intervals: Mapping[str, tuple[float, float]] = field(default_factory=dict)
    fallback: Mapping[str, str] = field(default_factory=dict)
    source: str = "arguments"
    clipped: Mapping[str, str] = field(default_factory=dict)
    adequacy: Mapping[str, Any] | None = None
    unresolved: Mapping[str, tuple[float, float]] = field(default_factory=dict)
    laws: Mapping[str, Any] | None = None


def _still_unresolved(
    unresolved: Mapping[str, tuple[float, float]], own: Mapping[str, tuple[float, float]]
) -> dict[str, tuple[float, float]]:
    """The delays the paper's refinement left unresolved that the laws' fit does not resolve
    either: its 95 % interval (``own``) is missing or wider than half of the unresolved one
    (the refinement's own rule: an interval wider than half of ``[0, max_delay]``)."""
    out = {}
    for name, (lo, hi) in unresolved.items():
        mine = own.get(name)
        if mine is None or (mine[1] - mine[0]) > 0.5 * (hi - lo):
            out[name] = (lo, hi)
    return out


def read_identified(source: str | Path | Mapping[str, Any]) -> Identified:
    """Read the identified valve from ``params.yaml`` (or its content).

    Parameters
    ----------
    source : str, pathlib.Path or mapping
        A ``params.yaml`` written by the identification
        (:meth:`spa.identification.IdentificationResult.to_dict`), or its content, or a flat
        ``{"c1": ..., ...}`` mapping (no intervals).

    Returns
    -------
    Identified
        When ``laws: {chosen: identified}``, its ``params`` carry the actuator's own laws
        (with ``k2``, ``t_on`` and ``t_off`` from the laws record's ``valve``) and its
        intervals are :func:`laws_intervals`'. A delay the paper's refinement left
        unresolved counts as resolved when the laws' fit gives it a 95 % interval at most
        half as wide; otherwise it stays in ``unresolved``, at its worst case.

    Raises
    ------
    TuningError
        If the file is missing or unreadable (the identification did not run or failed), it
        records an error, or a parameter is missing or outside the model's domain; the
        message names the file and the parameter. An interval reaching past a physical
        bound is not an error: it is clipped to the domain and the note kept in
        ``clipped``.

    Examples
    --------
    >>> v = read_identified({"c1": 0.5, "k2": 0.8, "tau2": 0.8, "t_on": 0.003, "t_off": 0.01})
    >>> v.params.c1, v.intervals
    (0.5, {})
    """
    where = "arguments"
    if isinstance(source, str | Path):
        where = str(source)
        path = Path(source)
        if not path.is_file():
            raise TuningError(
                f"{where}: no such file; the identification of this dataset did not run or "
                "failed (see its log), so it gets no tuning"
            )
        try:
            source = read_yaml(path)
        except yaml.YAMLError as exc:
            raise TuningError(f"{where}: not valid YAML ({exc}); no tuning") from None
    if not isinstance(source, Mapping):
        raise TuningError(f"{where}: expected a mapping of c1, k2, tau2, t_on, t_off")
    if source.get("error"):
        raise TuningError(f"{where}: the identification failed: {source['error']}; no tuning")
    values = {}
    unresolved: dict[str, tuple[float, float]] = {}
    for name in PARAMETERS:
        item = source.get(name)
        value = item.get("value") if isinstance(item, Mapping) else item
        if isinstance(item, Mapping) and item.get("resolved") is False and name in DELAYS:
            # not resolved: the interval is what is known, and its worst case is designed for
            value = item.get("hi")
            unresolved[name] = (float(item.get("lo") or 0.0), float(value or 0.0))
        if value is None:
            raise TuningError(
                f"{where}: no value for {name!r}; the identification failed for it, so the "
                "valve gets no tuning"
            )
        values[name] = value
    clipped: dict[str, str] = {}
    try:
        laws = _laws_of(source.get("laws"))
        record = source.get("laws")
        if laws is not None:  # k2 and the delays fitted with the laws
            values.update(record.get("valve") or {})
        params = ValveParams(**values, delay=_delay_of(source), laws=laws)
        intervals = read_intervals(source, clipped)
        if laws is not None:
            own = laws_intervals(record, params, clipped)
            unresolved = _still_unresolved(unresolved, own)
            if unresolved:  # the laws do not resolve it either: the worst case, as without
                params = replace(params, **{k: hi for k, (_, hi) in unresolved.items()})
                own = {k: v for k, v in own.items() if k not in (*unresolved, DIFFERENCE)}
            intervals = {**intervals, **own}
    except ValueError as exc:
        raise TuningError(f"{where}: {exc}") from None
    fallback = source.get("fallback") or {}
    adequacy = source.get("adequacy")
    adequacy = dict(adequacy) if isinstance(adequacy, Mapping) else None
    return Identified(params, intervals, dict(fallback), where, clipped, adequacy, unresolved, laws)
