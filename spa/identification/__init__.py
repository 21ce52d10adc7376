"""Identification of the valve + actuator parameters from three experiments (Section 3.2).

MODEL.md section 1 and the paper's Fig. 2:

* experiment 1, **charge** (valve open from 0 bar until the supply pressure): ``k2`` and
  ``tau2`` from the straight line ``dP/dt = (k2 - P)/tau2`` fitted to ``dP/dt`` against ``P``
  (:func:`fit_charge`);
* experiment 2, **discharge** (valve closed from the supply pressure down to 0 bar): the power
  law ``dP/dt = -a*P**b`` and ``c1`` from the same fit with ``b = 1/2``
  (``dP/dt = -sqrt(P)/c1``, :func:`fit_discharge`);
* experiment 3, **pulse** (a pulse train with several low-state durations): ``t_on`` and
  ``t_off`` from a least-squares fit of the exact model over the whole run, plus the delay of
  every single edge for the spread (:func:`fit_delays`).

:func:`identify` chains the three and returns an :class:`IdentificationResult` that serialises
to the content of ``params.yaml``; :func:`identification_commands` and
:func:`simulate_identification` describe the three experiments' valve commands.

Run tables follow the project's contract: a DataFrame with ``t`` (s), ``p`` (bar), and
optionally ``valve`` (0/1, the command over ``[t_k, t_{k+1})``). Time need not start at 0 and
the sampling may be slightly irregular: the derivative fits work on a uniform grid at the
median sample step (linear interpolation), the delay fit on the raw sample times.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt
import pandas as pd
from scipy.optimize import curve_fit, least_squares
from scipy.signal import fftconvolve, savgol_coeffs, savgol_filter

from spa.model.params import ValveParams
from spa.model.plant import simulate
from spa.validation import _edges, _evaluate

__all__ = [
    "ChargeFit",
    "DelayFit",
    "DischargeFit",
    "Estimate",
    "IdentificationError",
    "IdentificationResult",
    "fit_charge",
    "fit_delays",
    "fit_discharge",
    "identification_commands",
    "identify",
    "identify_runs",
    "load_params",
    "pressure_rate",
    "simulate_identification",
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

# Relative prior standard deviation given to c1, k2, tau2 in the pulse fit when they come from
# a fallback rather than from experiments 1-2 (weak: the pulse run then pins them itself).
_FALLBACK_PRIOR_REL_SD = 0.2
# Noise floor (bar) for residual scaling, so that noise-free synthetic data stay well posed.
_NOISE_FLOOR = 1e-5
# Replicates per chunk of the bootstrap are limited to about this many samples in memory.
_CHUNK_SAMPLES = 2_000_000
_Z95 = 1.959963984540054


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
    """

    value: float
    lo: float | None
    hi: float | None
    unit: str
    runs: tuple[str, ...] = ()
    method: str = ""
    fallback: str | None = None
    spread: Mapping[str, float] | None = None

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
        return out


@dataclass(frozen=True)
class ChargeFit:
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
    points : pandas.DataFrame
        ``run``, ``t``, ``p`` (smoothed, bar), ``dpdt`` (bar/s), ``used`` (bool): every grid
        point of every run after the valve opened, for Fig. 2a.
    """

    k2: Estimate
    tau2: Estimate
    slope: float
    intercept: float
    r2: float
    n_points: int
    points: pd.DataFrame = field(repr=False)

    def summary(self) -> dict[str, float | int]:
        """Fit coefficients and R² as a plain dictionary."""
        return {
            "slope": self.slope,
            "intercept": self.intercept,
            "r2": self.r2,
            "n_points": self.n_points,
        }


@dataclass(frozen=True)
class DischargeFit:
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
    points : pandas.DataFrame
        ``run``, ``t``, ``p``, ``dpdt``, ``used``, for Fig. 2b.
    """

    c1: Estimate
    a: float
    b: float
    r2_power: float
    r2: float
    n_points: int
    points: pd.DataFrame = field(repr=False)

    def summary(self) -> dict[str, float | int]:
        """Fit coefficients and R² as a plain dictionary."""
        return {
            "a": self.a,
            "b": self.b,
            "r2_power": self.r2_power,
            "r2": self.r2,
            "n_points": self.n_points,
        }


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

    def to_valve_params(self) -> ValveParams:
        """The point estimates as :class:`~spa.model.params.ValveParams`."""
        return ValveParams(
            c1=self.c1.value,
            k2=self.k2.value,
            tau2=self.tau2.value,
            t_on=self.t_on.value,
            t_off=self.t_off.value,
        )

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
        out["fallback"] = dict(self.fallback)
        out["settings"] = dict(self.settings)
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
    return ValveParams(**values)


# --------------------------------------------------------------------------------------------
# Run tables and derivatives
# --------------------------------------------------------------------------------------------


def _as_runs(runs: Runs | None, kind: str) -> list[tuple[str, pd.DataFrame]]:
    """Normalise ``runs`` to a list of ``(id, table)``; ids of a sequence are ``kind[i]``."""
    if runs is None:
        return []
    if isinstance(runs, pd.DataFrame):
        raise ValueError(f"{kind} must be a mapping of run id to table or a list of tables")
    if isinstance(runs, Mapping):
        items = [(str(k), v) for k, v in runs.items()]
    else:
        items = [(str(v.attrs.get("run_id", f"{kind}[{i}]")), v) for i, v in enumerate(runs)]
    for rid, table in items:
        if not isinstance(table, pd.DataFrame):
            raise ValueError(f"{kind} run {rid!r} must be a DataFrame, got {type(table).__name__}")
        for col in ("t", "p"):
            if col not in table.columns:
                raise ValueError(f"{kind} run {rid!r} has no {col!r} column")
    return items


def _arrays(table: pd.DataFrame, rid: str) -> tuple[FloatArray, FloatArray, np.ndarray | None]:
    """``t``, ``p`` and ``valve`` (or None) of a run, checked."""
    t = table["t"].to_numpy(dtype=np.float64)
    p = table["p"].to_numpy(dtype=np.float64)
    if t.size < 10:
        raise IdentificationError(f"run {rid!r} has only {t.size} samples")
    if not (np.all(np.isfinite(t)) and np.all(np.isfinite(p))):
        raise ValueError(f"run {rid!r}: columns 't' and 'p' must be finite")
    if np.any(np.diff(t) <= 0):
        raise ValueError(f"run {rid!r}: column 't' must be strictly increasing")
    valve = None
    if "valve" in table.columns:
        valve = table["valve"].to_numpy()
        if not np.all((valve == 0) | (valve == 1)):
            raise ValueError(f"run {rid!r}: column 'valve' must hold only 0 and 1")
        valve = valve.astype(np.int8)
    return t, p, valve


def _uniform(
    t: FloatArray, p: FloatArray, valve: np.ndarray | None
) -> tuple[FloatArray, FloatArray, np.ndarray | None, float]:
    """Resample onto a uniform grid at the median step (unchanged if already uniform)."""
    dt = float(np.median(np.diff(t)))
    if np.max(np.abs(np.diff(t) - dt)) <= 1e-6 * dt:
        return t, p, valve, dt
    n = math.floor((t[-1] - t[0]) / dt + 1e-9) + 1
    grid = t[0] + dt * np.arange(n)
    pg = np.interp(grid, t, p)
    vg = None
    if valve is not None:
        idx = np.searchsorted(t, grid + 1e-9 * dt, side="right") - 1
        vg = valve[np.clip(idx, 0, t.size - 1)]
    return grid, pg, vg, dt


def _window_samples(window: float, polyorder: int, dt: float, n: int | None = None) -> int:
    """Odd Savitzky–Golay window length in samples closest to ``window`` seconds."""
    if not (isinstance(polyorder, int | np.integer) and polyorder >= 1):
        raise ValueError(f"polyorder must be an integer >= 1, got {polyorder!r}")
    if not (math.isfinite(window) and window > 0):
        raise ValueError(f"window must be finite and > 0 s, got {window!r}")
    w = 2 * math.floor(window / (2.0 * dt) + 0.5) + 1
    if w <= polyorder + 1:
        raise ValueError(
            f"window = {window:g} s is {w} samples at dt = {dt:g} s; it must span more than "
            f"polyorder + 1 = {polyorder + 1} samples"
        )
    if n is not None and w > n:
        raise IdentificationError(
            f"window = {window:g} s ({w} samples) is longer than the run ({n} samples)"
        )
    return w


def _savgol(
    p: npt.ArrayLike, w: int, polyorder: int, dt: float, deriv: int = 0
) -> npt.NDArray[np.float64]:
    return savgol_filter(p, w, polyorder, deriv=deriv, delta=dt, axis=-1, mode="interp")


def pressure_rate(table: pd.DataFrame, window: float, polyorder: int) -> pd.DataFrame:
    """Smoothed pressure and its time derivative (Savitzky–Golay) on a uniform grid.

    Parameters
    ----------
    table : pandas.DataFrame
        Run table with ``t`` (s) and ``p`` (bar).
    window : float
        Savitzky–Golay window in s (rounded to the nearest odd number of samples).
    polyorder : int
        Polynomial order (>= 1).

    Returns
    -------
    pandas.DataFrame
        ``t`` (uniform grid at the median step), ``p`` (interpolated measurement),
        ``p_smooth`` (bar) and ``dpdt`` (bar/s).

    Raises
    ------
    ValueError
        If ``window`` spans no more than ``polyorder + 1`` samples or ``polyorder < 1``.

    Examples
    --------
    >>> import numpy as np, pandas as pd
    >>> t = np.arange(200) * 1e-3
    >>> out = pressure_rate(pd.DataFrame({"t": t, "p": 0.5 * t**2}), 0.021, 2)
    >>> bool(np.allclose(out["dpdt"], t))
    True
    """
    t, p, _ = _arrays(table, "table")
    tg, pg, _, dt = _uniform(t, p, None)
    w = _window_samples(window, polyorder, dt, tg.size)
    return pd.DataFrame(
        {
            "t": tg,
            "p": pg,
            "p_smooth": _savgol(pg, w, polyorder, dt),
            "dpdt": _savgol(pg, w, polyorder, dt, deriv=1),
        }
    )


# --------------------------------------------------------------------------------------------
# Experiments 1 and 2: derivative fits with a residual block bootstrap
# --------------------------------------------------------------------------------------------


@dataclass
class _Segment:
    """The usable part of one charge/discharge run on its uniform grid."""

    rid: str
    t: FloatArray  # grid times of the bootstrap region
    ps: FloatArray  # smoothed pressure over the region
    d: FloatArray  # derivative over the region
    p: FloatArray  # measured pressure over the region
    w: int  # Savitzky-Golay window, samples
    dt: float  # grid step, s
    used: npt.NDArray[np.bool_]  # points of the region that enter the fit
    points: pd.DataFrame  # all points after the edge, for the figure
    ref: FloatArray = field(default_factory=lambda: np.empty(0))  # reference curve (bootstrap)
    resid: FloatArray = field(default_factory=lambda: np.empty(0))  # p - ref


def _select_edge(valve: np.ndarray | None, rising: bool, rid: str, kind: str) -> tuple[int, int]:
    """Index of the first edge of the wanted direction and of the end of that command run."""
    n = 0 if valve is None else valve.size
    if valve is None:
        return 0, -1
    target = 1 if rising else 0
    k = _edges(valve)
    k = k[valve[k] == target]
    if k.size:
        start = int(k[0])
    elif valve[0] == target:
        start = 0
    else:
        state = "opens" if rising else "closes"
        raise IdentificationError(f"{kind} run {rid!r}: the valve never {state}")
    after = np.flatnonzero(valve[start:] != target)
    end = start + int(after[0]) - 1 if after.size else n - 1
    return start, end


def _segment(
    rid: str,
    table: pd.DataFrame,
    kind: str,
    window: float,
    polyorder: int,
    skip: float,
    onset_fraction: float,
    tail_fraction: float,
) -> _Segment:
    """Locate the response after the valve edge and compute smoothed pressure and rate."""
    t, p, valve = _arrays(table, rid)
    tg, pg, vg, dt = _uniform(t, p, valve)
    w = _window_samples(window, polyorder, dt, tg.size)
    half = w // 2
    rising = kind == "charge"
    k_edge, k_end = _select_edge(vg, rising, rid, kind)
    k_end = tg.size - 1 if k_end < 0 else k_end
    ps = _savgol(pg, w, polyorder, dt)
    d = _savgol(pg, w, polyorder, dt, deriv=1)
    # Level at the edge (mean of the half window before it, or the first samples) and at the
    # end of the command run (mean of its last half window).
    before = pg[max(k_edge - half, 0) : k_edge + 1]
    p_a = float(before.mean())
    p_b = float(pg[max(k_end - half, k_edge) : k_end + 1].mean())
    change = (p_b - p_a) if rising else (p_a - p_b)
    tail = slice(max(k_end - w, k_edge), k_end + 1)
    noise = float(np.std(pg[tail] - ps[tail]))
    if change <= max(10.0 * noise, 1e-6):
        what = "rise" if rising else "fall"
        raise IdentificationError(
            f"{kind} run {rid!r}: the pressure does not {what} after the valve edge "
            f"({p_a:.4g} -> {p_b:.4g} bar)"
        )
    moved = (ps[k_edge:] - p_a) if rising else (p_a - ps[k_edge:])
    crossed = np.flatnonzero(moved >= onset_fraction * change)
    k_onset = k_edge + (int(crossed[0]) if crossed.size else 0)
    t_start = max(tg[k_edge] + skip, tg[k_onset]) + half * dt
    t_stop = tg[k_end] - half * dt
    if not rising:
        below = np.flatnonzero(ps[k_onset : k_end + 1] < tail_fraction * p_a)
        if below.size:
            t_stop = min(t_stop, tg[k_onset + int(below[0])] - 0.5 * dt)
    used_all = (tg >= t_start - 1e-9 * dt) & (tg <= t_stop + 1e-9 * dt)
    idx = np.flatnonzero(used_all)
    if idx.size < max(2 * w, 20):
        raise IdentificationError(
            f"{kind} run {rid!r}: only {idx.size} samples between the response start and "
            f"{'the end of the run' if rising else 'the near-zero tail'}; need at least "
            f"{max(2 * w, 20)} (lengthen the run or shorten the window)"
        )
    lo = max(int(idx[0]) - half, 0)
    hi = min(int(idx[-1]) + half, tg.size - 1)
    region = slice(lo, hi + 1)
    points = pd.DataFrame(
        {
            "run": rid,
            "t": tg[k_edge : k_end + 1],
            "p": ps[k_edge : k_end + 1],
            "dpdt": d[k_edge : k_end + 1],
            "used": used_all[k_edge : k_end + 1],
        }
    )
    return _Segment(
        rid=rid,
        t=tg[region],
        ps=ps[region],
        d=d[region],
        p=pg[region],
        w=w,
        dt=dt,
        used=used_all[region],
        points=points,
    )


def _line(x: FloatArray, y: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Least-squares line ``y = slope*x + intercept`` along the last axis."""
    xm = x.mean(axis=-1, keepdims=True)
    ym = y.mean(axis=-1, keepdims=True)
    sxy = ((x - xm) * (y - ym)).sum(axis=-1)
    sxx = ((x - xm) ** 2).sum(axis=-1)
    slope = sxy / np.where(sxx > 0, sxx, np.nan)
    return slope, ym[..., 0] - slope * xm[..., 0]


def _r2(y: FloatArray, fit: FloatArray) -> float:
    ss_tot = float(np.sum((y - y.mean()) ** 2))
    return 1.0 - float(np.sum((y - fit) ** 2)) / ss_tot if ss_tot > 0 else math.nan


def _charge_stats(x: FloatArray, y: FloatArray) -> FloatArray:
    """``(k2, tau2)`` per row from the line fit of ``dP/dt`` on ``P``."""
    slope, icept = _line(x, y)
    with np.errstate(divide="ignore", invalid="ignore"):
        tau2 = np.where(slope < 0, -1.0 / slope, np.nan)
        k2 = np.where(slope < 0, -icept / slope, np.nan)
    return np.stack([k2, tau2], axis=-1)


def _c1_stat(x: FloatArray, y: FloatArray) -> FloatArray:
    """``c1`` per row from ``dP/dt = -sqrt(P)/c1`` (least squares through the origin)."""
    num = -(y * np.sqrt(np.maximum(x, 0.0))).sum(axis=-1)
    den = np.maximum(x, 0.0).sum(axis=-1)
    with np.errstate(divide="ignore", invalid="ignore"):
        a = num / den
        return np.where(a > 0, 1.0 / a, np.nan)[..., None]


def _bootstrap(
    segments: Sequence[_Segment],
    stat: Callable[[FloatArray, FloatArray], FloatArray],
    polyorder: int,
    n_boot: int,
    rng: np.random.Generator,
) -> FloatArray:
    """Moving-block residual bootstrap of the whole derivative-fit pipeline.

    Replicate ``b`` of run ``j`` is ``ref_j + r*_j`` where ``r*_j`` strings together blocks of
    ``w`` consecutive residuals ``p - ref`` drawn with replacement; each replicate is smoothed,
    differentiated and fitted exactly like the data. Returns ``(n_boot, n_stats)``.
    """
    total = sum(s.t.size for s in segments)
    chunk = max(1, _CHUNK_SAMPLES // max(total, 1))
    # Only interior points (a half window from the region's ends) are used, so the filters
    # are plain 'valid' convolutions (FFT), without savgol_filter's edge fits.
    kernels = [
        (
            savgol_coeffs(s.w, polyorder, deriv=0, delta=s.dt, use="conv")[None, :],
            savgol_coeffs(s.w, polyorder, deriv=1, delta=s.dt, use="conv")[None, :],
        )
        for s in segments
    ]
    out = []
    for b0 in range(0, n_boot, chunk):
        nb = min(chunk, n_boot - b0)
        xs, ys = [], []
        for seg, (k_smooth, k_rate) in zip(segments, kernels, strict=True):
            n, w = seg.t.size, seg.w
            n_blocks = -(-n // w)
            starts = rng.integers(0, n - w + 1, size=(nb, n_blocks))
            idx = (starts[:, :, None] + np.arange(w)).reshape(nb, -1)[:, :n]
            rep = seg.ref + seg.resid[idx]
            cols = np.flatnonzero(seg.used) - w // 2
            xs.append(fftconvolve(rep, k_smooth, mode="valid", axes=1)[:, cols])
            ys.append(fftconvolve(rep, k_rate, mode="valid", axes=1)[:, cols])
        out.append(stat(np.concatenate(xs, axis=1), np.concatenate(ys, axis=1)))
    return np.concatenate(out, axis=0)


def _interval(value: float, reps: FloatArray) -> tuple[float, float]:
    """Percentile interval of the replicates, re-centred on the estimate (95 %)."""
    reps = reps[np.isfinite(reps)]
    if reps.size < 10:
        return math.nan, math.nan
    q_lo, med, q_hi = np.percentile(reps, [2.5, 50.0, 97.5])
    return value + float(q_lo - med), value + float(q_hi - med)


def _check_fraction(name: str, value: float) -> float:
    if not (math.isfinite(value) and 0.0 < value < 1.0):
        raise ValueError(f"{name} must be in (0, 1), got {value!r}")
    return float(value)


def _check_common(window: float, polyorder: int, skip: float, n_boot: int) -> None:
    if not (math.isfinite(window) and window > 0):
        raise ValueError(f"window must be finite and > 0 s, got {window!r}")
    if not (isinstance(polyorder, int | np.integer) and polyorder >= 1):
        raise ValueError(f"polyorder must be an integer >= 1, got {polyorder!r}")
    if not (math.isfinite(skip) and skip >= 0):
        raise ValueError(f"skip must be finite and >= 0 s, got {skip!r}")
    if not (isinstance(n_boot, int | np.integer) and n_boot >= 20):
        raise ValueError(f"n_boot must be an integer >= 20, got {n_boot!r}")


def fit_charge(
    runs: Runs,
    *,
    window: float = 0.1,
    polyorder: int = 3,
    skip: float = 0.03,
    onset_fraction: float = 0.02,
    supply_fraction: float = 0.9,
    n_boot: int = 200,
    seed: int = 0,
) -> ChargeFit:
    """Identify ``k2`` and ``tau2`` from charge runs (experiment 1, Fig. 2a).

    Parameters
    ----------
    runs : mapping of run id to table, or sequence of tables
        Charge runs: valve opened at 0 bar (edge at the first 0→1 of ``valve``, or at the
        first sample when there is no ``valve`` column or it starts open) and kept open until
        the pressure settles at the supply.
    window : float, optional
        Savitzky–Golay window in s for the smoothed pressure and its derivative.
    polyorder : int, optional
        Savitzky–Golay polynomial order.
    skip : float, optional
        Time in s after the edge that is never used: covers the opening delay ``t_on`` and the
        ringing after the edge.
    onset_fraction : float, optional
        The response has started once the smoothed pressure has covered this fraction of the
        total rise.
    supply_fraction : float, optional
        The run must end above this fraction of the fitted ``k2``, otherwise ``k2`` is an
        extrapolation and :class:`IdentificationError` is raised.
    n_boot : int, optional
        Bootstrap replicates for the 95 % intervals.
    seed : int, optional
        Seed of the :class:`numpy.random.Generator` of the bootstrap.

    Returns
    -------
    ChargeFit

    Raises
    ------
    IdentificationError
        No run, the valve never opens, the pressure does not rise, too few usable points, or
        the pressure never gets near the fitted supply.
    ValueError
        For invalid settings (the message names the argument).

    Notes
    -----
    Eq. 2, ``dP/dt = (k2 - P)/tau2``, is a straight line in the ``(P, dP/dt)`` plane with slope
    ``-1/tau2`` and intercept ``k2/tau2``; it is fitted by ordinary least squares to the
    smoothed pressure and its Savitzky–Golay derivative, pooling all runs.

    *Window.* A point enters the fit when its whole Savitzky–Golay window lies inside the
    charging response: from ``max(edge + skip, onset) + window/2`` (onset: the smoothed
    pressure has covered ``onset_fraction`` of the rise) to the end of the open command minus
    ``window/2``. So no derivative mixes the hold ``t_on``, the ringing or the end of the
    record. The settled tail near the supply stays in: it pins the intercept.

    *Intervals.* The derivative residuals are correlated over the window, so the OLS
    covariance would be far too optimistic. Instead a moving-block residual bootstrap repeats
    the whole pipeline (smooth, differentiate, fit) on ``ref + r*``, where ``ref`` is the
    closed-form charge curve with the fitted ``k2``, ``tau2`` and ``r*`` resamples blocks (one
    window long) of the measured residuals ``p - ref``: it keeps sensor noise, quantisation and
    ringing as they are. The 95 % interval is the percentile interval of the replicates,
    re-centred on the estimate.
    """
    _check_common(window, polyorder, skip, n_boot)
    onset_fraction = _check_fraction("onset_fraction", onset_fraction)
    supply_fraction = _check_fraction("supply_fraction", supply_fraction)
    items = _as_runs(runs, "charge")
    if not items:
        raise IdentificationError(
            "no charge run: k2 and tau2 need experiment 1 (valve open from 0 bar until the "
            "supply pressure)"
        )
    segs = [
        _segment(rid, tab, "charge", window, polyorder, skip, onset_fraction, 0.0)
        for rid, tab in items
    ]
    x = np.concatenate([s.ps[s.used] for s in segs])
    y = np.concatenate([s.d[s.used] for s in segs])
    slope, icept = (float(v) for v in _line(x, y))
    if not slope < 0:
        raise IdentificationError(
            f"charge runs {[s.rid for s in segs]}: dP/dt does not decrease with P "
            f"(slope {slope:.3g} 1/s); not a charging response"
        )
    tau2, k2 = -1.0 / slope, -icept / slope
    for s in segs:
        reached = float(s.ps[s.used][-max(1, s.used.sum() // 20) :].mean())
        if reached < supply_fraction * k2:
            raise IdentificationError(
                f"charge run {s.rid!r}: the pressure never gets near the supply: it reaches "
                f"{reached:.4g} bar, {100 * reached / k2:.0f} % of the fitted k2 = {k2:.4g} bar "
                f"(need >= {100 * supply_fraction:.0f} %); keep the valve open longer"
            )
    # Reference curve for the bootstrap: the closed form with (k2, tau2), amplitude by LS.
    for s in segs:
        e = np.exp(-(s.t - s.t[0]) / tau2)
        amp = float(np.dot(k2 - s.p, e) / np.dot(e, e))
        s.ref = k2 - amp * e
        s.resid = s.p - s.ref
    reps = _bootstrap(segs, _charge_stats, polyorder, n_boot, np.random.default_rng([seed, 1]))
    rids = tuple(s.rid for s in segs)
    method = "line fit of dP/dt against P (Savitzky-Golay); 95% moving-block residual bootstrap"
    k2_lo, k2_hi = _interval(k2, reps[:, 0])
    t_lo, t_hi = _interval(tau2, reps[:, 1])
    return ChargeFit(
        k2=Estimate(k2, k2_lo, k2_hi, UNITS["k2"], rids, method),
        tau2=Estimate(tau2, t_lo, t_hi, UNITS["tau2"], rids, method),
        slope=slope,
        intercept=icept,
        r2=_r2(y, slope * x + icept),
        n_points=int(x.size),
        points=pd.concat([s.points for s in segs], ignore_index=True),
    )


def fit_discharge(
    runs: Runs,
    *,
    window: float = 0.1,
    polyorder: int = 3,
    skip: float = 0.03,
    onset_fraction: float = 0.02,
    tail_fraction: float = 0.05,
    n_boot: int = 200,
    seed: int = 0,
) -> DischargeFit:
    """Identify ``c1`` (and the free power law) from discharge runs (experiment 2, Fig. 2b).

    Parameters
    ----------
    runs : mapping of run id to table, or sequence of tables
        Discharge runs: valve closed at the supply pressure (edge at the first 1→0 of
        ``valve``, or at the first sample when there is no ``valve`` column or it starts
        closed), the pressure falls to 0.
    window, polyorder, skip, onset_fraction, n_boot, seed
        As in :func:`fit_charge`.
    tail_fraction : float, optional
        The near-zero tail is excluded: the fit stops where the smoothed pressure first falls
        below ``tail_fraction`` times the pressure at the edge (default 5 %, about 0.04 bar
        from 0.84 bar).

    Returns
    -------
    DischargeFit

    Raises
    ------
    IdentificationError
        No run, the valve never closes, the pressure does not fall, or too few usable points.
    ValueError
        For invalid settings.

    Notes
    -----
    Eq. 1, ``dP/dt = -sqrt(P)/c1``. The paper first fits the free power law
    ``dP/dt = -a*P**b`` (reported with its R², ``b`` close to 0.5); here by nonlinear least
    squares in the ``(P, dP/dt)`` plane, started from a log–log line. ``c1`` is then ``1/a``
    of the fit with ``b`` fixed at 0.5, a linear least-squares fit of ``dP/dt`` on
    ``sqrt(P)`` through the origin.

    *Tail threshold.* Near 0 bar the rate ``sqrt(P)/c1`` vanishes while the derivative noise
    does not, and the actuator empties in finite time, a kink that the smoothing window would
    blur: below ``tail_fraction`` of the starting pressure (5 %: about 0.04 bar, a rate of
    0.4 bar/s at the nominal ``c1``) noise and that kink dominate. The window start is chosen
    as in :func:`fit_charge`; the interval comes from the same block bootstrap with the
    closed-form discharge ``(sqrt(P0) - t/(2*c1))**2`` as reference.
    """
    _check_common(window, polyorder, skip, n_boot)
    onset_fraction = _check_fraction("onset_fraction", onset_fraction)
    tail_fraction = _check_fraction("tail_fraction", tail_fraction)
    items = _as_runs(runs, "discharge")
    if not items:
        raise IdentificationError(
            "no discharge run: c1 needs experiment 2 (valve closed from the supply pressure "
            "down to 0 bar)"
        )
    segs = [
        _segment(rid, tab, "discharge", window, polyorder, skip, onset_fraction, tail_fraction)
        for rid, tab in items
    ]
    x = np.concatenate([s.ps[s.used] for s in segs])
    y = np.concatenate([s.d[s.used] for s in segs])
    if np.any(x <= 0) or np.any(y >= 0):
        raise IdentificationError(
            f"discharge runs {[s.rid for s in segs]}: the used points must have P > 0 and "
            "dP/dt < 0; the pressure is not exhausting"
        )
    if x.max() < 2.0 * x.min():
        raise IdentificationError(
            f"discharge runs {[s.rid for s in segs]}: the used pressure only spans "
            f"{x.min():.3g}-{x.max():.3g} bar; the power law needs the pressure to fall at least "
            "by half (run the discharge longer)"
        )
    c1 = float(_c1_stat(x, y)[0])
    r2 = _r2(y, -np.sqrt(x) / c1)
    # Free power law, started from the log-log line.
    b0, la0 = np.polyfit(np.log(x), np.log(-y), 1)
    try:
        (a, b), _ = curve_fit(
            lambda xx, aa, bb: -aa * xx**bb, x, y, p0=(math.exp(la0), b0), maxfev=2000
        )
    except RuntimeError:  # pragma: no cover - the log-log start is already close
        a, b = math.exp(la0), b0
    r2_power = _r2(y, -a * x**b)
    for s in segs:
        tau = s.t - s.t[0]
        root = np.sqrt(np.maximum(s.p, 0.0)) + tau / (2.0 * c1)
        s0 = float(root[s.used].mean())
        s.ref = np.square(np.maximum(s0 - tau / (2.0 * c1), 0.0))
        s.resid = s.p - s.ref
    reps = _bootstrap(segs, _c1_stat, polyorder, n_boot, np.random.default_rng([seed, 2]))
    lo, hi = _interval(c1, reps[:, 0])
    rids = tuple(s.rid for s in segs)
    method = (
        "fit of dP/dt = -sqrt(P)/c1 (Savitzky-Golay, b fixed at 0.5); "
        "95% moving-block residual bootstrap"
    )
    return DischargeFit(
        c1=Estimate(c1, lo, hi, UNITS["c1"], rids, method),
        a=float(a),
        b=float(b),
        r2_power=r2_power,
        r2=r2,
        n_points=int(x.size),
        points=pd.concat([s.points for s in segs], ignore_index=True),
    )


# --------------------------------------------------------------------------------------------
# Experiment 3: switching delays
# --------------------------------------------------------------------------------------------


class _Fast:
    """Minimal stand-in for ValveParams inside the optimiser (no validation per call)."""

    __slots__ = ("c1", "k2", "t_off", "t_on", "tau2")

    def __init__(self, c1: float, k2: float, tau2: float, t_on: float, t_off: float) -> None:
        self.c1, self.k2, self.tau2, self.t_on, self.t_off = c1, k2, tau2, t_on, t_off


@dataclass
class _PulseRun:
    rid: str
    t: FloatArray  # times relative to the first sample
    t0: float
    p: FloatArray
    valve: np.ndarray
    starts: FloatArray  # run starts (first sample, then every edge)
    level: npt.NDArray[np.bool_]
    sigma: float  # robust noise estimate, bar
    dt: float

    def model(self, prm: _Fast, p0: float) -> FloatArray:
        hold = np.where(self.level, prm.t_on, prm.t_off)
        hold[0] = 0.0
        return _evaluate(self.t, self.starts, self.level, hold, p0, prm)  # type: ignore[arg-type]


def _noise_sd(p: FloatArray) -> float:
    """Robust sensor-noise estimate from second differences (MAD), bar."""
    d2 = np.diff(p, 2)
    mad = float(np.median(np.abs(d2 - np.median(d2))))
    return max(1.4826 * mad / math.sqrt(6.0), _NOISE_FLOOR)


def _pulse_run(rid: str, table: pd.DataFrame) -> _PulseRun:
    t, p, valve = _arrays(table, rid)
    if valve is None:
        raise IdentificationError(f"pulse run {rid!r} has no 'valve' column (the command)")
    k = np.concatenate(([0], _edges(valve)))
    tt = t - t[0]
    return _PulseRun(
        rid=rid,
        t=tt,
        t0=float(t[0]),
        p=p,
        valve=valve,
        starts=tt[k],
        level=valve[k].astype(bool),
        sigma=_noise_sd(p),
        dt=float(np.median(np.diff(t))),
    )


def _responding_edges(runs: Sequence[_PulseRun], t_on: float, t_off: float) -> tuple[int, int]:
    """Numbers of rising and falling edges followed by a response (segment > hold + 2 dt)."""
    n_on = n_off = 0
    for r in runs:
        seg = np.diff(np.append(r.starts, r.t[-1]))[1:]
        lev = r.level[1:]
        n_on += int(np.sum(lev & (seg > t_on + 2 * r.dt)))
        n_off += int(np.sum(~lev & (seg > t_off + 2 * r.dt)))
    return n_on, n_off


def _hac_factor(e: FloatArray, lag: int) -> float:
    """Long-run variance factor ``1 + 2*sum_k w_k*rho_k`` (Bartlett weights), floored at 1."""
    e = e - e.mean()
    den = float(np.dot(e, e))
    if den <= 0 or lag < 1:
        return 1.0
    n = e.size
    lag = min(lag, n - 1)
    # Autocorrelation by FFT (no per-lag Python loop).
    m = 1 << (2 * n - 1).bit_length()
    f = np.fft.rfft(e, m)
    acf = np.fft.irfft(f * np.conj(f), m)[1 : lag + 1] / den
    weights = 1.0 - np.arange(1, lag + 1) / (lag + 1.0)
    return max(1.0, 1.0 + 2.0 * float(np.dot(weights, acf)))


def _respond(on: bool, p: float, elapsed: FloatArray, prm: _Fast) -> FloatArray:
    """Closed-form pressure after ``elapsed`` s (clipped at 0) of charging or exhausting."""
    elapsed = np.maximum(elapsed, 0.0)
    if on:
        return prm.k2 + (p - prm.k2) * np.exp(-elapsed / prm.tau2)
    return np.square(np.maximum(math.sqrt(p) - elapsed / (2.0 * prm.c1), 0.0))


def _edge_delays(
    runs: Sequence[_PulseRun],
    prm: _Fast,
    models: Sequence[FloatArray],
    max_delay: float,
    post: float,
) -> pd.DataFrame:
    """Delay of every edge: 1-D fit of the closed-form response after it, with free delay.

    The pressure at the edge is that of the global fit; the segment after the edge (up to
    ``post`` s, never past the next edge) is fitted with ``P_e`` held for ``d`` then the
    closed form of the new state. Grid search at ``dt/20`` then parabolic refinement. An edge
    is censored when its segment ends within the hold, or when the response the model expects
    over the window has less energy than a single 3-sigma sample (e.g. exhausting at 0 bar).
    """
    rows = []
    for r, m in zip(runs, models, strict=True):
        k_edges = np.flatnonzero(np.r_[False, r.valve[1:] != r.valve[:-1]])
        bounds = np.append(k_edges, r.t.size - 1)
        for j, k in enumerate(k_edges):
            on = bool(r.valve[k])
            e = r.t[k]
            k_next = int(bounds[j + 1])
            seg = r.t[k_next] - e if j + 1 < k_edges.size else r.t[-1] - e
            hold = prm.t_on if on else prm.t_off
            p_e = float(m[k])
            row = {
                "run": r.rid,
                "t": e + r.t0,
                "direction": "on" if on else "off",
                "segment": seg,
                "p_edge": p_e,
                "delay": math.nan,
                "censored": True,
            }
            stop = int(np.searchsorted(r.t, min(e + post, r.t[k_next]), side="right"))
            tt = r.t[k:stop] - e
            pp = r.p[k:stop]
            step = r.dt / 20.0
            grid = np.arange(0.0, min(seg, max_delay) + 0.5 * step, step)
            mod = _respond(on, p_e, tt[None, :] - grid[:, None], prm)
            # The response after the fitted hold must stand out of the noise: its energy over
            # the window must exceed that of a 3-sigma step at a single sample.
            expected = _respond(on, p_e, tt - hold, prm) - p_e
            visible = float(np.sum(expected * expected)) > 9.0 * r.sigma**2
            if seg > hold + 2 * r.dt and visible:
                sse = np.sum((pp[None, :] - mod) ** 2, axis=1)
                i = int(np.argmin(sse))
                d = float(grid[i])
                if 0 < i < grid.size - 1:
                    y0, y1, y2 = sse[i - 1], sse[i], sse[i + 1]
                    den = y0 - 2 * y1 + y2
                    if den > 0:
                        d += 0.5 * step * (y0 - y2) / den
                row["delay"] = d
                row["censored"] = False
            rows.append(row)
    return pd.DataFrame(
        rows, columns=["run", "t", "direction", "segment", "p_edge", "delay", "censored"]
    )


def fit_delays(
    runs: Runs,
    params: ValveParams,
    *,
    prior_sd: Mapping[str, float] | None = None,
    max_delay: float = 0.05,
    min_edges: int = 3,
    post: float = 0.03,
    hac_lag: float = 0.02,
) -> DelayFit:
    """Identify ``t_on`` and ``t_off`` from pulse runs (experiment 3, Fig. 2c).

    Parameters
    ----------
    runs : mapping of run id to table, or sequence of tables
        Pulse runs with a ``valve`` column (the command) and ``t``, ``p``.
    params : ValveParams
        ``c1``, ``k2``, ``tau2`` from experiments 1–2 (the prior means of the nuisance
        parameters). Its ``t_on``, ``t_off`` are not used: the fit starts from a grid search
        over ``[0, max_delay]``.
    prior_sd : mapping, optional
        Standard deviations of ``c1``, ``k2``, ``tau2`` (same units); by default 20 % of each
        value (a weak tie). :func:`identify` passes the bootstrap standard errors.
    max_delay : float, optional
        Largest delay searched, s.
    min_edges : int, optional
        Rising and falling edges followed by a response needed for each delay.
    post : float, optional
        Length in s of the response fitted after each edge for the per-edge delays.
    hac_lag : float, optional
        Largest lag in s of the residual autocorrelation used to inflate the covariance.

    Returns
    -------
    DelayFit

    Raises
    ------
    IdentificationError
        No pulse run, a run without a ``valve`` column, or fewer than ``min_edges`` responding
        rising (for ``t_on``) or falling (for ``t_off``) edges.
    ValueError
        For invalid settings.

    Notes
    -----
    *Why a fit of the whole run.* At 1 kHz with 5 mbar noise a single edge pins its delay to
    about a millisecond only: the hold lasts a few samples and a local line through them is
    noisy. Every sample after an edge, however, carries the delay (the whole later trajectory
    is shifted by it), so a least-squares fit of the exact model (:func:`model_response`) over
    the whole run estimates ``t_on`` and ``t_off`` to a fraction of a sample step. The fit uses
    the continuous delays, never a threshold crossing, so it is not limited to the sample
    step. A delay error and an error in ``c1``, ``k2`` or ``tau2`` trade off (0.5 % in
    ``tau2`` moves ``t_on`` by about 0.3 ms), so those three are re-fitted as nuisance
    parameters, each tied to its experiment 1–2 value by a Gaussian prior of width
    ``prior_sd``: the pulse run cannot drag them far from what experiments 1–2 measured, and
    their uncertainty is propagated into the delays. Low pulses shorter than ``t_off`` (and
    high pulses shorter than ``t_on``) are handled by the model itself (the hold restarts).

    *Intervals* come from the Gauss–Newton covariance of the fit, with the residuals scaled
    by their RMS and the variance inflated by the residual autocorrelation up to ``hac_lag``
    (Bartlett weights), which is 1 for white sensor noise and grows with ringing. A bootstrap
    would need hundreds of nonlinear refits; the covariance is accurate here because the
    residuals of the pressure itself (unlike those of a derivative) are nearly white.

    *Spread.* The delay of every single edge comes from a 1-D fit of the response after it
    (pressure at the edge from the global fit, free delay); edges whose segment ends before
    any response (e.g. a 5 ms low pulse with ``t_off = 10 ms``) are marked censored. Their
    standard deviation, median and range are reported as ``spread``.
    """
    if not (math.isfinite(max_delay) and max_delay > 0):
        raise ValueError(f"max_delay must be finite and > 0 s, got {max_delay!r}")
    if not (isinstance(min_edges, int | np.integer) and min_edges >= 1):
        raise ValueError(f"min_edges must be an integer >= 1, got {min_edges!r}")
    if not (math.isfinite(post) and post > 0):
        raise ValueError(f"post must be finite and > 0 s, got {post!r}")
    items = _as_runs(runs, "pulse")
    if not items:
        raise IdentificationError(
            "no pulse run: t_on and t_off need experiment 3 (a pulse train with several "
            "low-state durations)"
        )
    pr = [_pulse_run(rid, tab) for rid, tab in items]
    mean = np.array([params.c1, params.k2, params.tau2])
    sd = _FALLBACK_PRIOR_REL_SD * mean
    if prior_sd is not None:
        for i, name in enumerate(("c1", "k2", "tau2")):
            if name in prior_sd:
                v = float(prior_sd[name])
                if not (math.isfinite(v) and v > 0):
                    raise ValueError(f"prior_sd[{name!r}] must be finite and > 0, got {v!r}")
                sd[i] = v
    q0 = np.array([math.sqrt(max(float(np.mean(r.p[:10])), 1e-4)) for r in pr])
    dt = float(np.median([r.dt for r in pr]))

    def sse(t_on: float, t_off: float) -> float:
        prm = _Fast(params.c1, params.k2, params.tau2, t_on, t_off)
        return sum(
            float(np.sum(((r.model(prm, q * q) - r.p) / r.sigma) ** 2))
            for r, q in zip(pr, q0, strict=True)
        )

    # Start: the best point of a coarse 2-D grid over [0, max_delay]^2 (about 26 x 26 points:
    # t_on and t_off trade off along a diagonal valley, so 1-D searches would stall), then one
    # 1-D pass at the sample step.
    coarse = np.arange(0.0, max_delay + 1e-12, max(dt, max_delay / 25.0))
    coarse[0] = 1e-6
    cost = np.array([[sse(a, b) for b in coarse] for a in coarse])
    i_on, i_off = np.unravel_index(int(np.argmin(cost)), cost.shape)
    t_on, t_off = float(coarse[i_on]), float(coarse[i_off])
    fine = np.arange(0.0, max_delay + 0.5 * dt, dt)
    fine[0] = 1e-6
    t_on = float(fine[np.argmin([sse(g, t_off) for g in fine])])
    t_off = float(fine[np.argmin([sse(t_on, g) for g in fine])])
    n_on, n_off = _responding_edges(pr, t_on, t_off)
    _require_edges(n_on, n_off, min_edges, [r.rid for r in pr])

    n_run = len(pr)

    def residuals(x: FloatArray) -> FloatArray:
        prm = _Fast(*x[:5])
        parts = [(r.model(prm, x[5 + i] ** 2) - r.p) / r.sigma for i, r in enumerate(pr)]
        parts.append((x[:3] - mean) / sd)
        return np.concatenate(parts)

    x0 = np.concatenate([mean, [max(t_on, 1e-6), max(t_off, 1e-6)], q0])
    lb = np.concatenate([1e-6 * np.ones(5), np.zeros(n_run)])
    ub = np.concatenate([np.full(3, np.inf), [max_delay, max_delay], np.full(n_run, np.inf)])
    x0 = np.clip(x0, lb, ub)
    scale = np.concatenate([sd, [1e-3, 1e-3], np.full(n_run, 0.01)])
    sol = least_squares(residuals, x0, bounds=(lb, ub), x_scale=scale, method="trf")
    x = sol.x
    prm = _Fast(*x[:5])
    p0s = [float(x[5 + i] ** 2) for i in range(n_run)]
    models = [r.model(prm, p0) for r, p0 in zip(pr, p0s, strict=True)]
    n_on, n_off = _responding_edges(pr, prm.t_on, prm.t_off)
    _require_edges(n_on, n_off, min_edges, [r.rid for r in pr])

    # Covariance: rescale the data rows to the residual RMS inflated for autocorrelation.
    jac = np.array(sol.jac, dtype=np.float64, copy=True)
    row = 0
    infl_all, sq = [], []
    for r, m in zip(pr, models, strict=True):
        e = r.p - m
        rms = max(float(np.sqrt(np.mean(e * e))), _NOISE_FLOOR)
        infl = _hac_factor(e, round(hac_lag / r.dt))
        jac[row : row + r.t.size] *= r.sigma / (rms * math.sqrt(infl))
        row += r.t.size
        infl_all.append(infl)
        sq.append(e * e)
    cov = np.linalg.pinv(jac.T @ jac)
    se = np.sqrt(np.maximum(np.diag(cov), 0.0))

    edges = _edge_delays(pr, prm, models, max_delay, post)
    rids = tuple(r.rid for r in pr)
    method = (
        "least-squares fit of the exact model over the pulse runs (c1, k2, tau2 re-fitted "
        "within their experiment 1-2 uncertainty); 95% from the fit covariance"
    )
    ests = {}
    for i, name in ((3, "t_on"), (4, "t_off")):
        d = edges.loc[(edges["direction"] == name[2:]) & ~edges["censored"], "delay"]
        spread = {
            "n": float(d.size),
            "sd": float(d.std(ddof=1)) if d.size > 1 else math.nan,
            "median": float(d.median()),
            "min": float(d.min()),
            "max": float(d.max()),
        }
        v = float(x[i])
        ests[name] = Estimate(
            v,
            max(v - _Z95 * float(se[i]), 0.0),
            v + _Z95 * float(se[i]),
            UNITS[name],
            rids,
            method,
            spread=spread,
        )
    nuisance = {name: float(x[i]) for i, name in enumerate(("c1", "k2", "tau2"))}
    nuisance.update(
        {
            f"z_{name}": float((x[i] - mean[i]) / sd[i])
            for i, name in enumerate(("c1", "k2", "tau2"))
        }
    )
    traces = {
        r.rid: pd.DataFrame({"t": r.t + r.t0, "p": r.p, "valve": r.valve, "p_model": m})
        for r, m in zip(pr, models, strict=True)
    }
    return DelayFit(
        t_on=ests["t_on"],
        t_off=ests["t_off"],
        nuisance=nuisance,
        rmse=float(np.sqrt(np.mean(np.concatenate(sq)))),
        inflation=float(max(infl_all)),
        converged=bool(sol.status > 0),
        edges=edges,
        traces=traces,
    )


def _require_edges(n_on: int, n_off: int, min_edges: int, rids: list[str]) -> None:
    for n, name, what in ((n_on, "t_on", "rising"), (n_off, "t_off", "falling")):
        if n < min_edges:
            raise IdentificationError(
                f"pulse runs {rids}: only {n} {what} edge(s) followed by a pressure response; "
                f"{name} needs at least {min_edges}"
            )


# --------------------------------------------------------------------------------------------
# The whole identification
# --------------------------------------------------------------------------------------------


def identify(
    charge: Runs | None,
    discharge: Runs | None,
    pulse: Runs | None,
    *,
    window: float = 0.1,
    polyorder: int = 3,
    skip: float = 0.03,
    onset_fraction: float = 0.02,
    tail_fraction: float = 0.05,
    supply_fraction: float = 0.9,
    max_delay: float = 0.05,
    min_edges: int = 3,
    n_boot: int = 200,
    seed: int = 0,
    fallback: ValveParams | None = None,
) -> IdentificationResult:
    """Identify ``c1``, ``k2``, ``tau2``, ``t_on``, ``t_off`` from the three experiments.

    Parameters
    ----------
    charge, discharge, pulse : mapping of run id to table, sequence of tables, or None
        The runs of experiments 1, 2 and 3 (see :func:`fit_charge`, :func:`fit_discharge`,
        :func:`fit_delays`).
    window, polyorder : float, int, optional
        Savitzky–Golay window (s) and order for the derivatives.
    skip, onset_fraction, tail_fraction, supply_fraction : float, optional
        Window choices of the derivative fits (see :func:`fit_charge`, :func:`fit_discharge`).
    max_delay : float, optional
        Largest ``t_on``/``t_off`` searched, s.
    min_edges : int, optional
        Responding rising/falling edges needed for ``t_on``/``t_off``.
    n_boot : int, optional
        Bootstrap replicates.
    seed : int, optional
        Seed of the bootstrap's :class:`numpy.random.Generator`; the result is deterministic
        for a given seed.
    fallback : ValveParams, optional
        Nominal parameters. Without it any experiment that cannot support its fit raises
        :class:`IdentificationError`. With it, the parameters of that experiment take the
        nominal values instead, and ``result.fallback`` records which and why.

    Returns
    -------
    IdentificationResult

    Raises
    ------
    IdentificationError
        When data are missing or insufficient and no ``fallback`` is given; the message names
        the experiment and what is missing.

    Notes
    -----
    ``t_on``/``t_off`` come last: their fit re-fits ``c1``, ``k2``, ``tau2`` as nuisance
    parameters tied to the experiment 1–2 values by their bootstrap standard errors (20 %
    for a fallback value).
    """
    settings: dict[str, Any] = {
        "window": float(window),
        "polyorder": int(polyorder),
        "skip": float(skip),
        "onset_fraction": float(onset_fraction),
        "tail_fraction": float(tail_fraction),
        "supply_fraction": float(supply_fraction),
        "max_delay": float(max_delay),
        "min_edges": int(min_edges),
        "n_boot": int(n_boot),
        "seed": int(seed),
    }
    common = {"window": window, "polyorder": polyorder, "skip": skip, "n_boot": n_boot}
    reasons: dict[str, str] = {}

    def nominal(name: str, reason: str) -> Estimate:
        assert fallback is not None
        reasons[name] = reason
        return Estimate(
            getattr(fallback, name), None, None, UNITS[name], (), "fallback", fallback=reason
        )

    cf: ChargeFit | None = None
    try:
        cf = fit_charge(
            charge or {},
            onset_fraction=onset_fraction,
            supply_fraction=supply_fraction,
            seed=seed,
            **common,
        )
        k2, tau2 = cf.k2, cf.tau2
    except IdentificationError as err:
        if fallback is None:
            raise
        k2, tau2 = nominal("k2", str(err)), nominal("tau2", str(err))
    df: DischargeFit | None = None
    try:
        df = fit_discharge(
            discharge or {},
            onset_fraction=onset_fraction,
            tail_fraction=tail_fraction,
            seed=seed,
            **common,
        )
        c1 = df.c1
    except IdentificationError as err:
        if fallback is None:
            raise
        c1 = nominal("c1", str(err))

    prior_sd = {}
    for name, est in (("c1", c1), ("k2", k2), ("tau2", tau2)):
        if est.lo is not None and est.hi is not None and est.hi > est.lo:
            prior_sd[name] = (est.hi - est.lo) / (2 * _Z95)
        else:
            prior_sd[name] = _FALLBACK_PRIOR_REL_SD * est.value
    start = ValveParams(c1.value, k2.value, tau2.value)  # t_on, t_off: found by grid search
    dfit: DelayFit | None = None
    try:
        dfit = fit_delays(
            pulse or {}, start, prior_sd=prior_sd, max_delay=max_delay, min_edges=min_edges
        )
        t_on, t_off = dfit.t_on, dfit.t_off
    except IdentificationError as err:
        if fallback is None:
            raise
        t_on, t_off = nominal("t_on", str(err)), nominal("t_off", str(err))
    return IdentificationResult(
        c1=c1,
        k2=k2,
        tau2=tau2,
        t_on=t_on,
        t_off=t_off,
        charge=cf,
        discharge=df,
        delays=dfit,
        fallback=reasons,
        settings=settings,
    )


def identify_runs(
    runs: Mapping[str, pd.DataFrame], kinds: Mapping[str, str], **kwargs: Any
) -> IdentificationResult:
    """:func:`identify` on a collection of runs of mixed kinds.

    Parameters
    ----------
    runs : mapping of run id to table
        All runs; those whose kind is not ``charge``, ``discharge`` or ``pulse`` are ignored.
    kinds : mapping of run id to kind
        Kind of every run.
    **kwargs
        Passed on to :func:`identify`.

    Returns
    -------
    IdentificationResult

    Raises
    ------
    ValueError
        If a run has no kind.
    """
    missing = sorted(set(runs) - set(kinds))
    if missing:
        raise ValueError(f"kinds has no entry for run(s) {missing}")
    groups: dict[str, dict[str, pd.DataFrame]] = {"charge": {}, "discharge": {}, "pulse": {}}
    for rid, table in runs.items():
        if kinds[rid] in groups:
            groups[kinds[rid]][rid] = table
    return identify(groups["charge"], groups["discharge"], groups["pulse"], **kwargs)


# --------------------------------------------------------------------------------------------
# Experiment design
# --------------------------------------------------------------------------------------------


def _steps(duration: float, dt: float, name: str) -> int:
    if not (math.isfinite(duration) and duration > 0):
        raise ValueError(f"{name} must be finite and > 0 s, got {duration!r}")
    n = math.floor(duration / dt + 0.5)
    if n < 1:
        raise ValueError(f"{name} = {duration:g} s is shorter than dt = {dt:g} s")
    return n


def identification_commands(
    dt: float,
    *,
    lead: float = 0.1,
    charge_duration: float = 5.0,
    discharge_duration: float = 6.0,
    fill: float = 0.3,
    lows: Sequence[float] = (0.005, 0.01, 0.02, 0.05, 0.1),
    highs: Sequence[float] = (0.04, 0.08),
    repeats: int = 2,
) -> dict[str, npt.NDArray[np.int8]]:
    """Valve commands of the three identification experiments (Section 3.2).

    Parameters
    ----------
    dt : float
        Step of the command, s. Every duration is rounded to whole steps.
    lead : float, optional
        Time before the first edge of every experiment, s (lets the recording see the
        initial level and puts the edge inside the record).
    charge_duration : float, optional
        Total length of the charge experiment, s; about 6 ``tau2`` reaches the supply.
    discharge_duration : float, optional
        Total length of the discharge experiment, s.
    fill : float, optional
        Pulse experiment: the valve first stays open this long from 0 bar, bringing the
        pressure to mid range, where both the charging and the exhausting rates are large.
    lows, highs : sequence of float, optional
        Pulse experiment: low-state and high-state durations, s. Every combination is
        applied (for each high duration, each low duration followed by that high).
    repeats : int, optional
        How many times the pulse pattern is repeated.

    Returns
    -------
    dict of str to numpy.ndarray of int8
        ``"charge"``: ``lead`` closed, then open (start from 0 bar);
        ``"discharge"``: ``lead`` open, then closed (start from the supply: ``p0 = k2``, the
        valve settled open); ``"pulse"``: ``lead`` closed, ``fill`` open, then the pulses
        (start from 0 bar). ``u[k]`` is the command over ``[k*dt, (k+1)*dt)``.

    Raises
    ------
    ValueError
        If ``dt`` or a duration is not positive, or a duration is shorter than ``dt``.

    Notes
    -----
    The default pulse pattern (about 2.4 s, 20 rising and 20 falling edges) mixes low
    pulses shorter than the nominal ``t_off`` (5 ms: no exhaust at all, the dead-zone; 10 ms:
    at the edge) with longer ones that show the exhaust, and high pulses long enough to show
    the charge after ``t_on``. :func:`simulate_identification` runs them through the model.

    Examples
    --------
    >>> cmds = identification_commands(0.001)
    >>> sorted(cmds)
    ['charge', 'discharge', 'pulse']
    >>> cmds["charge"].size, int(cmds["charge"][:100].sum()), int(cmds["charge"][100:].min())
    (5000, 0, 1)
    """
    if not (isinstance(dt, int | float | np.floating) and math.isfinite(dt) and dt > 0):
        raise ValueError(f"dt must be finite and > 0 s, got {dt!r}")
    if not (isinstance(repeats, int | np.integer) and repeats >= 1):
        raise ValueError(f"repeats must be an integer >= 1, got {repeats!r}")
    if len(lows) == 0 or len(highs) == 0:
        raise ValueError("lows and highs must each hold at least one duration")
    n_lead = _steps(lead, dt, "lead")
    n_charge = _steps(charge_duration, dt, "charge_duration")
    n_dis = _steps(discharge_duration, dt, "discharge_duration")
    if n_charge <= n_lead or n_dis <= n_lead:
        raise ValueError("charge_duration and discharge_duration must be longer than lead")
    charge = np.ones(n_charge, dtype=np.int8)
    charge[:n_lead] = 0
    dis = np.zeros(n_dis, dtype=np.int8)
    dis[:n_lead] = 1
    n_lows = [_steps(v, dt, "lows") for v in lows]
    n_highs = [_steps(v, dt, "highs") for v in highs]
    levels = [0, 1]
    counts = [n_lead, _steps(fill, dt, "fill")]
    for _ in range(int(repeats)):
        for nh in n_highs:
            for nl in n_lows:
                levels += [0, 1]
                counts += [nl, nh]
    pulse = np.repeat(np.array(levels, dtype=np.int8), counts)
    return {"charge": charge, "discharge": dis, "pulse": pulse}


def simulate_identification(
    params: ValveParams, dt: float = 0.001, **durations: Any
) -> dict[str, pd.DataFrame]:
    """Noise-free run tables of the three identification experiments.

    Parameters
    ----------
    params : ValveParams
        True parameters.
    dt : float, optional
        Sample step, s.
    **durations
        Passed to :func:`identification_commands`.

    Returns
    -------
    dict of str to pandas.DataFrame
        ``"charge"``, ``"discharge"``, ``"pulse"``: tables with ``t`` (s), ``p`` (bar),
        ``valve`` (int8), from :func:`spa.simulate` (exact at the sample times; the discharge
        starts at ``p0 = k2``, the others at 0 bar). Add a sensor model to mimic data.

    Examples
    --------
    >>> runs = simulate_identification(ValveParams())
    >>> round(float(runs["discharge"]["p"].iloc[0]), 3)
    0.837
    """
    cmds = identification_commands(dt, **durations)
    out = {}
    for name, u in cmds.items():
        p0 = params.k2 if name == "discharge" else 0.0
        out[name] = pd.DataFrame(
            {"t": dt * np.arange(u.size), "p": simulate(u, dt, params, p0), "valve": u}
        )
    return out
