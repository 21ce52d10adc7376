"""Experiments 1 and 2: ``k2``, ``tau2`` from the charging line and ``c1`` from the discharging
power law, each from the exact solution fitted to the pressure, with 95 % intervals from the
fit covariance."""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
import pandas as pd
from scipy.optimize import curve_fit

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

__all__ = ["DerivativeFit", "fit_charge", "fit_discharge"]


def _sqrt_law(taus: Sequence[FloatArray], ps: Sequence[FloatArray], iters: int = 30) -> FloatArray:
    """``c1`` per replicate from the closed form of state 1 fitted to the pressure itself.

    Least squares of ``P = (s_j - tau/(2*c1))**2`` (Eq. A1; ``s_j = sqrt(P)`` at the start of
    run ``j``, one per run, ``c1`` shared) by Gauss–Newton, started from the straight line of
    ``sqrt(P)`` against ``tau``. ``ps[j]`` has shape ``(nb, n_j)``; returns ``(nb,)``.
    """
    n_runs, nb = len(ps), ps[0].shape[0]
    # Start: the common slope of sqrt(P) on tau (within-run regression), each run's intercept.
    sxy = sxx = 0.0
    qs = [np.sqrt(np.maximum(p, 0.0)) for p in ps]
    for tau, q in zip(taus, qs, strict=True):
        tc = tau - tau.mean()
        sxy = sxy + (q * tc).sum(axis=-1)
        sxx = sxx + float(np.dot(tc, tc))
    beta = np.maximum(-sxy / sxx, 1e-9)
    s0 = np.stack([q.mean(axis=-1) + beta * tau.mean() for tau, q in zip(taus, qs, strict=True)], 1)
    for _ in range(iters):
        a = np.zeros((nb, n_runs + 1, n_runs + 1))
        g = np.zeros((nb, n_runs + 1))
        for j, (tau, p) in enumerate(zip(taus, ps, strict=True)):
            m = s0[:, j : j + 1] - beta[:, None] * tau
            r = p - m * m
            js, jb = 2.0 * m, -2.0 * m * tau
            a[:, j, j] = (js * js).sum(-1)
            a[:, j, -1] = a[:, -1, j] = (js * jb).sum(-1)
            a[:, -1, -1] += (jb * jb).sum(-1)
            g[:, j] = (js * r).sum(-1)
            g[:, -1] += (jb * r).sum(-1)
        step = np.linalg.solve(a, g[..., None])[..., 0]
        s0 = s0 + step[:, :n_runs]
        beta = beta + step[:, -1]
        if np.all(np.abs(step[:, -1]) <= 1e-12 * np.abs(beta)):
            break
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(beta > 0, 0.5 / beta, np.nan)


def _exp_law(
    segments: Sequence[_Segment], k2: float, tau2: float, iters: int = 50
) -> tuple[float, float, FloatArray, list[FloatArray], list[FloatArray]]:
    """``k2`` and ``tau2`` from the closed form of state 2 fitted to the pressure itself.

    Least squares of ``P = k2 - A_j*exp(-tau/tau2)`` (Eq. A2; ``A_j`` one per run, ``k2`` and
    ``tau2`` shared) over each run's fit span by Gauss–Newton (step halved while the sum of
    squares grows), from the derivative line's ``(k2, tau2)``. Returns ``k2``, ``tau2``, the
    amplitudes, and per run the Jacobian (columns ``A_1..A_R, k2, tau2``) and the residuals.
    """
    taus = [s.tf - s.tf[0] for s in segments]
    n_runs = len(segments)

    def amps(k: float, tc: float) -> FloatArray:
        return np.array(
            [
                float(np.dot(k - s.pf, e) / np.dot(e, e))
                for s, e in ((s, np.exp(-tau / tc)) for s, tau in zip(segments, taus, strict=True))
            ]
        )

    def parts(x: FloatArray) -> tuple[list[FloatArray], list[FloatArray]]:
        k, tc = x[n_runs], x[n_runs + 1]
        jacs, res = [], []
        for j, (s, tau) in enumerate(zip(segments, taus, strict=True)):
            e = np.exp(-tau / tc)
            jac = np.zeros((tau.size, n_runs + 2))
            jac[:, j], jac[:, n_runs], jac[:, n_runs + 1] = -e, 1.0, -x[j] * e * tau / tc**2
            jacs.append(jac)
            res.append(s.pf - (k - x[j] * e))
        return jacs, res

    x = np.concatenate([amps(k2, tau2), [k2, tau2]])
    jacs, res = parts(x)
    sse = sum(float(np.dot(r, r)) for r in res)
    for _ in range(iters):
        jac, r = np.concatenate(jacs), np.concatenate(res)
        step = np.linalg.lstsq(jac, r, rcond=None)[0]
        for _half in range(30):
            trial = x + step
            if trial[-1] > 0:
                t_jacs, t_res = parts(trial)
                t_sse = sum(float(np.dot(rr, rr)) for rr in t_res)
                if t_sse <= sse:
                    break
            step = 0.5 * step
        else:
            break
        done = abs(step[-1]) <= 1e-10 * trial[-1] and abs(step[-2]) <= 1e-10 * abs(trial[-2])
        x, jacs, res, sse = trial, t_jacs, t_res, t_sse
        if done:
            break
    return float(x[n_runs]), float(x[n_runs + 1]), x[:n_runs], jacs, res


def _covariance_se(
    segments: Sequence[_Segment],
    jacs: Sequence[FloatArray],
    resid: Sequence[FloatArray],
    hac_lag: float = 0.02,
) -> tuple[FloatArray, float]:
    """Standard errors of a closed-form fit from its Gauss–Newton covariance, and the 95 %
    quantile.

    The residuals of the pressure itself (unlike those of a derivative) are the sensor noise:
    their variance is ``RSS/(N - p)``, inflated for autocorrelation up to ``hac_lag`` s
    (Bartlett weights, as the delay fit); the quantile is Student's t with ``N - p`` degrees
    of freedom (a run of a few dozen samples).
    """
    from scipy.special import stdtrit  # Student's t quantile, without importing scipy.stats

    from spa.identification.delays import _hac_factor

    jac = np.concatenate(jacs)
    r = np.concatenate(resid)
    infl = max(_hac_factor(e, round(hac_lag / s.dt)) for s, e in zip(segments, resid, strict=True))
    dof = max(r.size - jac.shape[1], 1)
    var = float(np.dot(r, r)) / dof * infl
    cov = var * np.linalg.pinv(jac.T @ jac)
    return np.sqrt(np.maximum(np.diag(cov), 0.0)), float(stdtrit(dof, 0.975))


def _sqrt_law_interval(
    segments: Sequence[_Segment], c1: float
) -> tuple[float, float, list[FloatArray]]:
    """95 % interval of the closed-form ``c1`` (:func:`_covariance_se`): that of
    ``1/(2*c1)``, the slope of ``sqrt(P)``, mapped to ``c1`` (so ``lo > 0``); and each run's
    residuals."""
    beta = 0.5 / c1
    n_runs = len(segments)
    jacs, resid = [], []
    for j, s in enumerate(segments):
        tau = s.tf - s.tf[0]
        s0 = float(np.mean(np.sqrt(np.maximum(s.pf, 0.0)) + beta * tau))
        for _ in range(3):  # the start that minimises the residuals, given c1
            m = s0 - beta * tau
            s0 += float(np.dot(2 * m, s.pf - m * m) / np.dot(2 * m, 2 * m))
        m = s0 - beta * tau
        jac = np.zeros((tau.size, n_runs + 1))
        jac[:, j], jac[:, -1] = 2.0 * m, -2.0 * m * tau
        jacs.append(jac)
        resid.append(s.pf - m * m)
    se, z = _covariance_se(segments, jacs, resid)
    q = z * float(se[-1])
    return 0.5 / (beta + q), (0.5 / (beta - q) if beta > q else math.inf), resid


def _check_fraction(name: str, value: float) -> float:
    if not (math.isfinite(value) and 0.0 < value < 1.0):
        raise ValueError(f"{name} must be in (0, 1), got {value!r}")
    return float(value)


@dataclass(frozen=True)
class DerivativeFit:
    """Settings shared by :func:`fit_charge` and :func:`fit_discharge`, checked on construction.

    Parameters
    ----------
    window : float, default 0.1
        Savitzky–Golay window in s for the smoothed pressure and its derivative. A run whose
        fit span is shorter than about three windows gets the largest odd window of about a
        third of its span instead (at least ``polyorder + 2`` samples); the fit's ``window``
        and method say so.
    polyorder : int, default 3
        Savitzky–Golay polynomial order.
    skip : float, default 0.03
        Time in s after the edge that is never used: covers the opening delay ``t_on`` and
        the ringing after the edge.
    onset_fraction : float, default 0.02
        The response has started once the smoothed pressure has covered this fraction of the
        total rise.

    Raises
    ------
    ValueError
        For an invalid setting (the message names it), checked in the order above.

    Examples
    --------
    >>> DerivativeFit(window=0.05).polyorder
    3
    """

    window: float = 0.1
    polyorder: int = 3
    skip: float = 0.03
    onset_fraction: float = 0.02

    def __post_init__(self) -> None:
        window, polyorder, skip = self.window, self.polyorder, self.skip
        if not (math.isfinite(window) and window > 0):
            raise ValueError(f"window must be finite and > 0 s, got {window!r}")
        if not (isinstance(polyorder, int | np.integer) and polyorder >= 1):
            raise ValueError(f"polyorder must be an integer >= 1, got {polyorder!r}")
        if not (math.isfinite(skip) and skip >= 0):
            raise ValueError(f"skip must be finite and >= 0 s, got {skip!r}")
        onset = _check_fraction("onset_fraction", self.onset_fraction)
        object.__setattr__(self, "onset_fraction", onset)

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

    def estimator(
        self, segments: Sequence[_Segment], method: str
    ) -> Callable[[str, float, float, float], Estimate]:
        """The maker of a fit's estimates, all from the runs of ``segments`` by ``method``.

        Parameters
        ----------
        segments : sequence of _Segment
            The fitted runs (from :meth:`pooled`).
        method : str
            How the estimates were found; a note is added when a short run got a shorter
            derivative window than :attr:`window`.

        Returns
        -------
        callable
            ``(name, value, lo, hi) -> Estimate`` in the units of ``name``.
        """
        rids = tuple(s.rid for s in segments)
        short = [s.w * s.dt for s in segments if s.shortened and not s.raw]
        if short:
            method += (
                f"; Savitzky-Golay window shortened from {self.window:g} s to {min(short):.3g} s "
                "for a short run"
            )
        raw = [s.rid for s in segments if s.raw]
        if raw:
            method += (
                f"; run(s) {', '.join(raw)} too short for a Savitzky-Golay derivative: the "
                "closed form fitted to their samples alone, finite differences for the line's "
                "start and Fig. 2"
            )
        return lambda name, value, lo, hi: Estimate(value, lo, hi, UNITS[name], rids, method)


def fit_charge(
    runs: Runs, *, settings: DerivativeFit | None = None, supply_fraction: float = 0.9
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
    settings : DerivativeFit, optional
        The derivative window and the span's start (``window``, ``polyorder``, ``skip``,
        ``onset_fraction``); the defaults when omitted.

    Returns
    -------
    ChargeFit

    Raises
    ------
    IdentificationError
        No run, the valve never opens, the pressure does not rise, too few usable points, or
        the pressure never gets near the fitted supply.
    ValueError
        For an invalid ``supply_fraction``.

    Notes
    -----
    Eq. 2, ``dP/dt = (k2 - P)/tau2``, is a straight line in the ``(P, dP/dt)`` plane with slope
    ``-1/tau2`` and intercept ``k2/tau2``. The paper fits that line to the smoothed pressure
    and its Savitzky–Golay derivative; here the line (pooling all runs) gives the start and
    Fig. 2a's points, and the estimate is the least-squares fit of its exact solution, Eq. A2
    ``P = k2 - A_j*exp(-t/tau2)`` (one ``A_j`` per run), to the measured pressure over the
    same span (Gauss–Newton). That fit needs no derivative: no filter bias, no lost half
    windows, and white residuals, so a run of a few dozen samples still gives an honest
    interval. ``slope`` and ``intercept`` are ``-1/tau2`` and ``k2/tau2`` of that estimate (the
    line Fig. 2a draws); ``r2`` is its R² on the derivative points.

    *Window.* The span starts at ``max(edge + skip, onset)`` (onset: the smoothed pressure has
    covered ``onset_fraction`` of the rise), so the hold ``t_on`` and the ringing after the
    edge stay out, and ends with the open command; the settled tail near the supply stays in:
    it pins ``k2``. A derivative point enters the line fit when its whole window lies inside
    the span. When the span holds fewer than about three windows (a run of a few hundred
    samples), the window shrinks to a third of the span, never below ``polyorder + 2``
    samples, and is logged (``window`` and the method record it); a span too short even for
    that raises :class:`IdentificationError`.

    *Intervals* come from the Gauss–Newton covariance of the closed-form fit: the residual
    variance ``RSS/(N - p)`` inflated for residual autocorrelation up to 20 ms (Bartlett
    weights: 1 for white sensor noise, more with ringing), with Student's t quantile at
    ``N - p`` degrees of freedom. ``benchmarks/identification_coverage.py`` checks their
    coverage across the valve range.
    """
    opts = settings or DerivativeFit()
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
    # The estimate: the closed form fitted to the pressure, from the derivative line's start.
    k2, tau2, _amps, jacs, resid = _exp_law(segs, k2, tau2)
    se, z = _covariance_se(segs, jacs, resid)
    estimate = opts.estimator(
        segs,
        "least-squares fit of the closed form P = k2 - A*exp(-t/tau2) (Eq. A2) to the "
        "pressure, started from the line fit of dP/dt against P (Savitzky-Golay); 95% from "
        "the fit covariance",
    )
    k2_lo, k2_hi = k2 - z * float(se[-2]), k2 + z * float(se[-2])
    t_lo, t_hi = tau2 - z * float(se[-1]), tau2 + z * float(se[-1])
    slope, icept = -1.0 / tau2, k2 / tau2
    return ChargeFit(
        k2=estimate("k2", k2, k2_lo, k2_hi),
        tau2=estimate("tau2", tau2, t_lo, t_hi),
        slope=slope,
        intercept=icept,
        r2=_r2(y, slope * x + icept),
        n_points=int(x.size),
        window=min(s.w * s.dt for s in segs),
        points=pd.concat([s.points for s in segs], ignore_index=True),
        residuals={s.rid: e for s, e in zip(segs, resid, strict=True)},
    )


def fit_discharge(
    runs: Runs, *, settings: DerivativeFit | None = None, tail_fraction: float = 0.05
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
    settings : DerivativeFit, optional
        As in :func:`fit_charge`.

    Returns
    -------
    DischargeFit

    Raises
    ------
    IdentificationError
        No run, the valve never closes, the pressure does not fall, or too few usable points.
    ValueError
        For an invalid ``tail_fraction``.

    Notes
    -----
    Eq. 1, ``dP/dt = -sqrt(P)/c1``. The paper first fits the free power law
    ``dP/dt = -a*P**b`` (reported with its R², ``b`` close to 0.5); here by nonlinear least
    squares in the ``(P, dP/dt)`` plane (Savitzky–Golay derivative), started from a log–log
    line. ``c1`` is then the paper's fit with ``b`` fixed at 0.5, done on the exact solution
    instead of the derivative: Eq. A1, ``P = (s_j - t/(2*c1))**2`` (one ``s_j = sqrt(P)`` per
    run), fitted to the measured pressure by Gauss–Newton from the straight line of
    ``sqrt(P)`` against ``t``. No derivative means no lost half windows: a small actuator
    that empties in 0.1 s (a few dozen samples) still gives ``c1`` and an honest interval.
    ``r2`` is the R² of ``-sqrt(P)/c1`` on the derivative points (Fig. 2b's curve).

    *Span.* From ``max(edge + skip, onset)`` (as in :func:`fit_charge`) to where the smoothed
    pressure first falls below ``tail_fraction`` of the starting pressure: near 0 bar the
    actuator empties in finite time, a kink the smoothing would blur, and the rate vanishes
    while the noise does not. The derivative window adapts to a short span as in
    :func:`fit_charge`.

    *Interval.* From the Gauss–Newton covariance of ``1/(2*c1)`` (the slope of ``sqrt(P)``),
    as in :func:`fit_charge`, mapped to ``c1``.
    """
    opts = settings or DerivativeFit()
    tail_fraction = _check_fraction("tail_fraction", tail_fraction)
    segs, x, y = opts.pooled(
        runs,
        "discharge",
        tail_fraction,
        "no discharge run: c1 needs experiment 2 (valve closed from the supply pressure "
        "down to 0 bar)",
    )
    # A short run needs a short window, whose derivative is noisy: near the tail a few points
    # may show dP/dt >= 0. They stay in the c1 fit (unbiased); only the log-log start of the
    # free power law needs P > 0 and dP/dt < 0.
    exhausting = (x > 0) & (y < 0)
    # Finite differences of a few raw samples (a coarse log, a short run) are too noisy for
    # the sign test: there the pressure's own trend over the span must fall.
    falling = all(s.pf[-1] < s.pf[0] for s in segs if s.raw)
    raw_only = all(s.raw for s in segs)
    if (not raw_only and (exhausting.mean() < 0.8 or np.median(y) >= 0)) or not falling:
        raise IdentificationError(
            f"discharge runs {[s.rid for s in segs]}: only {100 * exhausting.mean():.0f} % of "
            "the used points have P > 0 and dP/dt < 0 (need 80 %); the pressure is not "
            "exhausting"
        )
    if x.max() < 2.0 * max(x.min(), 0.0) or x.max() <= 0:
        raise IdentificationError(
            f"discharge runs {[s.rid for s in segs]}: the used pressure only spans "
            f"{x.min():.3g}-{x.max():.3g} bar; the power law needs the pressure to fall at least "
            "by half (run the discharge longer)"
        )
    c1 = float(_sqrt_law([s.tf - s.tf[0] for s in segs], [s.pf[None, :] for s in segs])[0])
    if not (math.isfinite(c1) and c1 > 0):
        raise IdentificationError(
            f"discharge runs {[s.rid for s in segs]}: sqrt(P) does not fall with time; the "
            "pressure is not exhausting"
        )
    r2 = _r2(y, -np.sqrt(np.maximum(x, 0.0)) / c1)
    # Free power law, started from the log-log line.
    xe, ye = x[exhausting], y[exhausting]
    if xe.size < 2:
        raise IdentificationError(
            f"discharge runs {[s.rid for s in segs]}: fewer than 2 points where the pressure "
            "is positive and falling; the pressure is not exhausting"
        )
    b0, la0 = np.polyfit(np.log(xe), np.log(-ye), 1)
    xp, yp = x[x > 0], y[x > 0]
    try:
        (a, b), _ = curve_fit(
            lambda xx, aa, bb: -aa * xx**bb, xp, yp, p0=(math.exp(la0), b0), maxfev=2000
        )
    except RuntimeError:  # pragma: no cover - the log-log start is already close
        a, b = math.exp(la0), b0
    r2_power = _r2(yp, -a * xp**b)
    lo, hi, resid = _sqrt_law_interval(segs, c1)
    estimate = opts.estimator(
        segs,
        "least-squares fit of the closed form P = (sqrt(P0) - t/(2*c1))**2 (Eq. A1) to the "
        "pressure; 95% from the fit covariance; the free power law from dP/dt "
        "(Savitzky-Golay)",
    )
    return DischargeFit(
        c1=estimate("c1", c1, lo, hi),
        a=float(a),
        b=float(b),
        r2_power=r2_power,
        r2=r2,
        n_points=int(x.size),
        window=min(s.w * s.dt for s in segs),
        points=pd.concat([s.points for s in segs], ignore_index=True),
        residuals={s.rid: e for s, e in zip(segs, resid, strict=True)},
    )
