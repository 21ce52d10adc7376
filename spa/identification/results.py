"""What identification returns: estimates with 95 % intervals, the three fits, and the result that
serialises to ``params.yaml``."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, fields
from typing import Any

import numpy as np
import numpy.typing as npt
import pandas as pd

from spa.model.params import ValveParams

__all__ = [
    "UNITS",
    "ChargeFit",
    "DelayFit",
    "DischargeFit",
    "Estimate",
    "IdentificationError",
    "IdentificationResult",
    "estimate_basis",
    "load_params",
    "with_basis",
]

Runs = Mapping[str, pd.DataFrame] | Sequence[pd.DataFrame]


FloatArray = npt.NDArray[np.float64]


#: Units of the five parameters, as written to ``params.yaml``.
UNITS: Mapping[str, str] = {
    "c1": "s*bar^-0.5",
    "k2": "bar",
    "tau2": "s",
    "t_on": "s",
    "t_off": "s",
}


_Z95 = 1.959963984540054


def estimate_basis(runs: Sequence[str], kinds: Mapping[str, str]) -> str:
    """What kind of runs an estimate stands on: its runs' kinds, every kind driven through a
    modulator (:data:`spa.datasets.contract.MODULATED_KINDS`) counted as one, ``modulated``;
    sorted, joined by ``+``; ``""`` when no run of it has a known kind.

    Two sessions' intervals of a parameter are comparable only on the same basis: a delay
    fitted to the pulse runs' edges and one refined on the modulated runs' cycle means are
    different effective delays of one valve (issue 61), so that a pilot and a full session
    of an unchanged plant can disagree without the valve having changed.

    Examples
    --------
    >>> estimate_basis(["p1", "s1", "s2"], {"p1": "pulse", "s1": "staircase", "s2": "sine"})
    'modulated+pulse'
    >>> estimate_basis(["x"], {})
    ''
    """
    from spa.datasets.contract import MODULATED_KINDS

    found = {kinds[r] for r in runs if r in kinds}
    return "+".join(sorted({"modulated" if k in MODULATED_KINDS else k for k in found}))


def with_basis(doc: Mapping[str, Any], kinds: Mapping[str, str]) -> dict[str, Any]:
    """``params.yaml``'s content with each parameter's ``basis`` (:func:`estimate_basis` of
    its ``runs``) written after its ``runs``.

    Examples
    --------
    >>> with_basis({"k2": {"value": 1.0, "runs": ["c"]}}, {"c": "charge"})["k2"]
    {'value': 1.0, 'runs': ['c'], 'basis': 'charge'}
    """
    out = dict(doc)
    for name in UNITS:
        entry = out.get(name)
        if not isinstance(entry, Mapping) or "runs" not in entry:
            continue
        new: dict[str, Any] = {}
        for key, value in entry.items():
            new[key] = value
            if key == "runs":
                new["basis"] = estimate_basis(list(value or ()), kinds)
        out[name] = new
    return out


class IdentificationError(ValueError):
    """The runs cannot support a fit; the message names what is missing."""


# --------------------------------------------------------------------------------------------
# Result containers
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Estimate:
    """One identified parameter with its 95 % interval.

    Attributes
    ----------
    value : float
        Point estimate, in ``unit``.
    lo, hi : float or None
        95 % interval; ``None`` for a fallback value.
    unit : str
        ``"s*bar^-0.5"``, ``"bar"`` or ``"s"``.
    runs : tuple of str
        Ids of the runs the estimate uses.
    method : str
        How the value and the interval were obtained.
    fallback : str or None
        When not ``None`` the value is the caller's nominal one and this says why.
    spread : mapping or None
        For ``t_on``, ``t_off``: statistics of the per-edge delays (``n``, ``sd``, ``median``,
        ``min``, ``max``, in s).
    resolved : bool
        False for a delay the data do not resolve: the interval is what is known, and every
        design uses it (its worst case, ``hi``, and the box's corners), never ``value`` alone.
    """

    value: float
    lo: float | None
    hi: float | None
    unit: str
    runs: tuple[str, ...] = ()
    method: str = ""
    fallback: str | None = None
    spread: Mapping[str, float] | None = None
    resolved: bool = True

    def contains(self, x: float) -> bool:
        """Whether ``x`` lies in the 95 % interval (False for a fallback)."""
        return self.lo is not None and self.hi is not None and self.lo <= x <= self.hi

    def to_dict(self) -> dict[str, Any]:
        """Plain, YAML-ready dictionary."""
        out: dict[str, Any] = {
            "value": float(self.value),
            "lo": None if self.lo is None else float(self.lo),
            "hi": None if self.hi is None else float(self.hi),
            "unit": self.unit,
            "runs": list(self.runs),
            "method": self.method,
            "fallback": self.fallback,
        }
        if self.spread is not None:
            out["spread"] = {k: float(v) for k, v in self.spread.items()}
        if not self.resolved:
            out["resolved"] = False
        return out


class _RateFit:
    """What the derivative fits (:class:`ChargeFit`, :class:`DischargeFit`) share."""

    def summary(self) -> dict[str, float | int]:
        """Fit coefficients and R² as a plain dictionary: the fields declared float or int.

        Returns
        -------
        dict of str to float or int
            In the order of the fields.
        """
        return {
            f.name: getattr(self, f.name)
            for f in fields(self)  # type: ignore[arg-type]
            if f.type in ("float", "int")
        }


@dataclass(frozen=True)
class ChargeFit(_RateFit):
    """Experiment 1: straight line ``dP/dt = slope*P + intercept`` while charging.

    Attributes
    ----------
    k2, tau2 : Estimate
        ``k2 = -intercept/slope`` (bar), ``tau2 = -1/slope`` (s).
    slope, intercept : float
        Line coefficients (1/s, bar/s).
    r2 : float
        Coefficient of determination of the line.
    n_points : int
        Points used in the fit.
    window : float
        Savitzky–Golay window used, s (the shortest over the runs): the configured one, or
        about a third of a run's fit span when that is shorter (see :func:`fit_charge`).
    points : pandas.DataFrame
        ``run``, ``t``, ``p`` (smoothed, bar), ``dpdt`` (bar/s), ``used`` (bool): every grid
        point of every run after the valve opened, for Fig. 2a.
    residuals : mapping
        Run id → residuals of the closed form over the run's fit span, bar.
    """

    k2: Estimate
    tau2: Estimate
    slope: float
    intercept: float
    r2: float
    n_points: int
    window: float
    points: pd.DataFrame = field(repr=False)
    residuals: Mapping[str, FloatArray] = field(default_factory=dict, repr=False, compare=False)


@dataclass(frozen=True)
class DischargeFit(_RateFit):
    """Experiment 2: power law ``dP/dt = -a*P**b`` and ``c1`` with ``b = 1/2`` while exhausting.

    Attributes
    ----------
    c1 : Estimate
        ``1/a`` of the fit with ``b`` fixed at 0.5 (s·bar^-0.5).
    a, b : float
        Free power-law coefficients (bar^(1-b)/s, 1).
    r2_power : float
        R² of the free power law.
    r2 : float
        R² of the ``b = 0.5`` fit that gives ``c1``.
    n_points : int
        Points used in the fits.
    window : float
        Savitzky–Golay window used, s (the shortest over the runs; see :func:`fit_discharge`).
    points : pandas.DataFrame
        ``run``, ``t``, ``p``, ``dpdt``, ``used``, for Fig. 2b.
    residuals : mapping
        Run id → residuals of the closed form over the run's fit span, bar.
    """

    c1: Estimate
    a: float
    b: float
    r2_power: float
    r2: float
    n_points: int
    window: float
    points: pd.DataFrame = field(repr=False)
    residuals: Mapping[str, FloatArray] = field(default_factory=dict, repr=False, compare=False)


@dataclass(frozen=True)
class DelayFit:
    """Experiment 3: switching delays from the pulse runs.

    Attributes
    ----------
    t_on, t_off : Estimate
        Delays in s, with the per-edge spread.
    nuisance : dict
        ``c1``, ``k2``, ``tau2`` as re-fitted on the pulse runs (tied to the experiment 1–2
        values by their uncertainty), and ``z_c1``, ... their shift in prior standard
        deviations: a consistency check between the experiments.
    rmse : float
        RMS residual of the model over the pulse runs, bar.
    inflation : float
        Variance inflation applied for residual autocorrelation (1 for white residuals).
    converged : bool
        Whether the least-squares fit met its tolerance (rather than its evaluation limit).
    edges : pandas.DataFrame
        One row per command edge: ``run``, ``t`` (s), ``direction`` (``"on"``/``"off"``),
        ``segment`` (s until the next edge), ``p_edge`` (bar), ``delay`` (s, NaN when
        ``censored``), ``censored`` (no visible response: the segment ended within the hold,
        or the pressure cannot move, e.g. exhausting at 0 bar).
    traces : dict of str to pandas.DataFrame
        Per run ``t``, ``p``, ``valve``, ``p_model``: data for Fig. 2c.
    """

    t_on: Estimate
    t_off: Estimate
    nuisance: Mapping[str, float]
    rmse: float
    inflation: float
    converged: bool
    edges: pd.DataFrame = field(repr=False)
    traces: Mapping[str, pd.DataFrame] = field(repr=False)

    def summary(self) -> dict[str, Any]:
        """Fit diagnostics as a plain dictionary."""
        used = self.edges[~self.edges["censored"]]
        return {
            **{k: float(v) for k, v in self.nuisance.items()},
            "rmse": self.rmse,
            "inflation": self.inflation,
            "converged": self.converged,
            "n_edges_on": int((used["direction"] == "on").sum()),
            "n_edges_off": int((used["direction"] == "off").sum()),
        }


@dataclass(frozen=True)
class IdentificationResult:
    """All five parameters, the fits behind them and any fallback.

    Attributes
    ----------
    c1, k2, tau2, t_on, t_off : Estimate
        The identified parameters.
    charge, discharge, delays : ChargeFit, DischargeFit, DelayFit or None
        The fits (``None`` where a fallback replaced them).
    fallback : dict of str to str
        Parameter name → why its nominal value was used. Empty when everything was
        identified from data.
    settings : dict
        The settings of the identification (window, polyorder, ...), for the record.
    refinement : dict or None
        The output-error refinement on every run with a valve command
        (:mod:`spa.identification.refine`): where it started, each run's FIT before and after,
        which runs informed which parameter.
    delay_convention : dict or None
        ``chosen``, each convention's delays and held-out FIT. The five estimates are the
        chosen convention's (:attr:`delay`).
    delay_difference : Estimate or None
        ``t_off - t_on`` with its own 95 % interval (transport convention, both delays
        resolved): much narrower than the two delays' intervals, which move together.
    adequacy : dict or None
        :class:`spa.identification.adequacy.Adequacy` as a mapping.
    warnings : tuple of str
        What the data could not resolve and what to record to resolve it.
    checks : dict or None
        The residuals' whiteness (Ljung) per run and the repeats' agreement
        (:mod:`spa.identification.diagnostics`).
    noise : dict or None
        ``sensor`` (bar, where nothing moves), ``method``, ``upper_bound`` and
        ``model_residual`` (the refined model's RMS residual, bar: not the sensor's).
    valve_edges : dict or None
        The edge-timing rule used: ``rule`` and each run's
        (:mod:`spa.identification.edges`).
    laws : dict or None
        ``chosen`` (``"paper"`` or ``"identified"``), the reason, both laws' held-out FITs
        per modulated run, the identified laws' ``coefficients`` and ``covariance``
        (:func:`spa.identification.laws_fit.choose_laws`). With ``identified`` the valve
        carries those laws (:meth:`to_valve_params`).
    """

    c1: Estimate
    k2: Estimate
    tau2: Estimate
    t_on: Estimate
    t_off: Estimate
    charge: ChargeFit | None = field(default=None, repr=False)
    discharge: DischargeFit | None = field(default=None, repr=False)
    delays: DelayFit | None = field(default=None, repr=False)
    fallback: Mapping[str, str] = field(default_factory=dict)
    settings: Mapping[str, Any] = field(default_factory=dict)
    refinement: Mapping[str, Any] | None = field(default=None, repr=False)
    delay_convention: Mapping[str, Any] | None = None
    delay_difference: Estimate | None = None
    adequacy: Mapping[str, Any] | None = None
    warnings: tuple[str, ...] = ()
    checks: Mapping[str, Any] | None = field(default=None, repr=False)
    noise: Mapping[str, Any] | None = None
    valve_edges: Mapping[str, Any] | None = None
    laws: Mapping[str, Any] | None = None

    @property
    def delay(self) -> str:
        """The delay convention of the estimates (``"hold"`` unless the refinement chose
        ``"transport"``)."""
        chosen = (self.delay_convention or {}).get("chosen", "hold")
        return "transport" if chosen == "transport" else "hold"

    def to_valve_params(self) -> ValveParams:
        """The point estimates as :class:`~spa.model.params.ValveParams`, in their
        convention, with the actuator's own laws when they were chosen (:func:`load_params`
        of :meth:`to_dict`)."""
        return load_params(self.to_dict())

    def to_dict(self) -> dict[str, Any]:
        """The content of ``params.yaml``: plain types only, ready for ``yaml.safe_dump``.

        Top-level keys ``c1``, ``k2``, ``tau2``, ``t_on``, ``t_off`` (each ``value``, ``lo``,
        ``hi``, ``unit``, ``runs``, ``method``, ``fallback``), then ``fits`` (``charge``:
        slope, intercept, r2; ``discharge``: a, b, r2_power, r2; ``pulse``: nuisance
        re-fit, rmse, edge counts), ``fallback`` and ``settings``.
        """
        fits: dict[str, Any] = {}
        if self.charge is not None:
            fits["charge"] = self.charge.summary()
        if self.discharge is not None:
            fits["discharge"] = self.discharge.summary()
        if self.delays is not None:
            fits["pulse"] = self.delays.summary()
        out: dict[str, Any] = {
            name: getattr(self, name).to_dict() for name in ("c1", "k2", "tau2", "t_on", "t_off")
        }
        out["fits"] = {
            k: {kk: (vv if isinstance(vv, bool | int) else float(vv)) for kk, vv in v.items()}
            for k, v in fits.items()
        }
        if self.delay != "hold":
            out["delay"] = self.delay  # the convention the five values are in
        out["fallback"] = dict(self.fallback)
        out["settings"] = dict(self.settings)
        if self.refinement is not None:
            out["refinement"] = dict(self.refinement)
        if self.delay_convention is not None:
            out["delay_convention"] = dict(self.delay_convention)
        if self.delay_difference is not None:
            out["delay_difference"] = self.delay_difference.to_dict()
        if self.adequacy is not None:
            out["adequacy"] = dict(self.adequacy)
        if self.laws is not None:
            out["laws"] = dict(self.laws)
        if self.valve_edges is not None:
            out["valve_edges"] = dict(self.valve_edges)
        if self.noise is not None:
            out["noise"] = dict(self.noise)
        if self.checks is not None:
            out["checks"] = {k: v for k, v in self.checks.items() if k != "sentences"}
        out["warnings"] = list(self.warnings)
        return out


def load_params(mapping: Mapping[str, Any]) -> ValveParams:
    """Build :class:`~spa.model.params.ValveParams` from ``params.yaml`` content or a flat mapping.

    Parameters
    ----------
    mapping : mapping
        Either ``{"c1": 0.53, ...}`` or the nested form of
        :meth:`IdentificationResult.to_dict` (``{"c1": {"value": 0.53, ...}, ...}``).

    Returns
    -------
    ValveParams
        With the actuator's own laws (and the ``k2`` and delays fitted with them) when
        ``laws: {chosen: identified}``: the valve the model replays use.

    Raises
    ------
    ValueError
        If a parameter is missing or invalid; the message names it.

    Examples
    --------
    >>> load_params({"c1": {"value": 0.5}, "k2": 0.8, "tau2": 0.8, "t_on": 0.003,
    ...              "t_off": 0.01}).c1
    0.5
    """
    values = {}
    for name in UNITS:
        if name not in mapping:
            raise ValueError(f"mapping has no {name!r}; expected keys {list(UNITS)}")
        item = mapping[name]
        values[name] = item["value"] if isinstance(item, Mapping) else item
    laws = _laws_of(mapping.get("laws"))
    if laws is not None:  # fitted jointly with the laws: k2 and the delays of that fit
        values.update(mapping["laws"].get("valve") or {})
    return ValveParams(**values, delay=_delay_of(mapping), laws=laws)


def _laws_of(record: Any) -> Any:
    """The laws a ``params.yaml``'s ``laws:`` record gives the valve: its coefficients when
    the identified laws were chosen, else None (the paper's)."""
    if isinstance(record, Mapping) and record.get("chosen") == "identified":
        return record.get("coefficients")
    return None


def _delay_of(mapping: Mapping[str, Any]) -> Any:
    """The delay convention ``params.yaml`` states (top-level ``delay``; ``"hold"``, the
    paper's, when absent); :class:`~spa.model.params.ValveParams` checks it."""
    return mapping.get("delay", "hold")
