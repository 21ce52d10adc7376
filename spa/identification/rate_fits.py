"""Experiments 1 and 2: ``k2``, ``tau2`` from the charging line and ``c1`` from the discharging
power law, with block-bootstrap 95 % intervals."""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace

import numpy as np
import pandas as pd
from scipy.optimize import curve_fit

from spa._docs import fill_doc
from spa._signal import fftconvolve, savgol_coeffs
from spa.identification.rates import _as_runs, _line, _r2, _Segment, _segment
from spa.identification.results import (
    UNITS,
    ChargeFit,
    DischargeFit,
    Estimate,
    FloatArray,
    IdentificationError,
    Runs,
)

__all__ = ["fit_charge", "fit_discharge"]

# Replicates per chunk of the bootstrap are limited to about this many samples in memory.
_CHUNK_SAMPLES = 2_000_000


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
            savgol_coeffs(s.w, polyorder, deriv=0, delta=s.dt)[None, :],
            savgol_coeffs(s.w, polyorder, deriv=1, delta=s.dt)[None, :],
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


@fill_doc
@dataclass(frozen=True)
class _DerivativeFit:
    """Settings shared by :func:`fit_charge` and :func:`fit_discharge` (checked by :meth:`checked`).

    Parameters
    ----------
    %(derivative_fit)s
    """

    window: float
    polyorder: int
    skip: float
    onset_fraction: float
    n_boot: int
    seed: int

    @classmethod
    def checked(
        cls,
        window: float,
        polyorder: int,
        skip: float,
        onset_fraction: float,
        n_boot: int,
        seed: int,
    ) -> _DerivativeFit:
        """The settings, checked in this order (the public functions hold the defaults).

        Returns
        -------
        _DerivativeFit

        Raises
        ------
        ValueError
            For an invalid setting (the message names it).
        """
        opts = cls(window, polyorder, skip, onset_fraction, n_boot, seed)
        window, polyorder, skip, n_boot = opts.window, opts.polyorder, opts.skip, opts.n_boot
        if not (math.isfinite(window) and window > 0):
            raise ValueError(f"window must be finite and > 0 s, got {window!r}")
        if not (isinstance(polyorder, int | np.integer) and polyorder >= 1):
            raise ValueError(f"polyorder must be an integer >= 1, got {polyorder!r}")
        if not (math.isfinite(skip) and skip >= 0):
            raise ValueError(f"skip must be finite and >= 0 s, got {skip!r}")
        if not (isinstance(n_boot, int | np.integer) and n_boot >= 20):
            raise ValueError(f"n_boot must be an integer >= 20, got {n_boot!r}")
        return replace(opts, onset_fraction=_check_fraction("onset_fraction", opts.onset_fraction))

    def pooled(
        self, runs: Runs, kind: str, tail_fraction: float, missing: str
    ) -> tuple[list[_Segment], FloatArray, FloatArray]:
        """The segments of the ``kind`` runs and their used points ``(P, dP/dt)``, pooled.

        Parameters
        ----------
        runs : mapping of run id to table, or sequence of tables
            The runs.
        kind : {"charge", "discharge"}
            The experiment.
        tail_fraction : float
            As in :func:`fit_discharge` (0 for a charge).
        missing : str
            Message of the :class:`IdentificationError` raised when there is no run.

        Returns
        -------
        segments : list of _Segment
            One per run.
        x, y : numpy.ndarray
            Smoothed pressure and its derivative at the used points of all runs.
        """
        items = _as_runs(runs, kind)
        if not items:
            raise IdentificationError(missing)
        window = self.window, self.polyorder, self.skip, self.onset_fraction
        segs = [_segment(rid, tab, kind, *window, tail_fraction) for rid, tab in items]
        x = np.concatenate([s.ps[s.used] for s in segs])
        y = np.concatenate([s.d[s.used] for s in segs])
        return segs, x, y

    def bootstrap(
        self,
        segments: Sequence[_Segment],
        stat: Callable[[FloatArray, FloatArray], FloatArray],
        stream: int,
    ) -> FloatArray:
        """:func:`_bootstrap` with these settings, from the generator ``[seed, stream]``."""
        rng = np.random.default_rng([self.seed, stream])
        return _bootstrap(segments, stat, self.polyorder, self.n_boot, rng)


@fill_doc
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
    supply_fraction : float, default 0.9
        The run must end above this fraction of the fitted ``k2``, otherwise ``k2`` is an
        extrapolation and :class:`IdentificationError` is raised.
    %(derivative_fit)s

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
    opts = _DerivativeFit.checked(window, polyorder, skip, onset_fraction, n_boot, seed)
    supply_fraction = _check_fraction("supply_fraction", supply_fraction)
    segs, x, y = opts.pooled(
        runs,
        "charge",
        0.0,
        "no charge run: k2 and tau2 need experiment 1 (valve open from 0 bar until the "
        "supply pressure)",
    )
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
    reps = opts.bootstrap(segs, _charge_stats, 1)
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


@fill_doc
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
    tail_fraction : float, default 0.05
        The near-zero tail is excluded: the fit stops where the smoothed pressure first falls
        below ``tail_fraction`` times the pressure at the edge (default 5 %, about 0.04 bar
        from 0.84 bar).
    %(derivative_fit)s

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
    opts = _DerivativeFit.checked(window, polyorder, skip, onset_fraction, n_boot, seed)
    tail_fraction = _check_fraction("tail_fraction", tail_fraction)
    segs, x, y = opts.pooled(
        runs,
        "discharge",
        tail_fraction,
        "no discharge run: c1 needs experiment 2 (valve closed from the supply pressure "
        "down to 0 bar)",
    )
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
    reps = opts.bootstrap(segs, _c1_stat, 2)
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
