"""Experiment 3: the valve delays ``t_on`` and ``t_off`` from an exact-model fit of the pulse
runs, with the spread of single edges."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace

import numpy as np
import numpy.typing as npt
import pandas as pd
from scipy.optimize import least_squares

from spa.identification.diagnostics import second_difference_sd
from spa.identification.rates import _arrays, _as_runs
from spa.identification.results import (
    _Z95,
    UNITS,
    DelayFit,
    Estimate,
    FloatArray,
    IdentificationError,
    Runs,
)
from spa.model.params import ValveParams
from spa.model.plant import edge_indices, replay, segment_pressure

__all__ = ["fit_delays"]

# Relative prior standard deviation given to c1, k2, tau2 in the pulse fit when they come from
# a fallback rather than from experiments 1-2 (weak: the pulse run then pins them itself).
_FALLBACK_PRIOR_REL_SD = 0.2


# Noise floor (bar) for residual scaling, so that noise-free synthetic data stay well posed.
_NOISE_FLOOR = 1e-5


# --------------------------------------------------------------------------------------------
# Experiment 3: switching delays
# --------------------------------------------------------------------------------------------


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
    keep: FloatArray  # 1 for the samples the fit uses, 0 within the guard after an edge

    def guarded(self, guard: float) -> _PulseRun:
        """This run with the samples within ``guard`` s after each command edge left out."""
        keep = np.ones(self.t.size)
        if guard > 0:
            edges = self.starts[1:]
            j = np.searchsorted(edges, self.t, side="right") - 1
            since = self.t - edges[np.maximum(j, 0)]
            keep[(j >= 0) & (since < guard - 1e-9 * self.dt)] = 0.0
        return replace(self, keep=keep)

    def model(self, prm: ValveParams, p0: float) -> FloatArray:
        hold = np.where(self.level, prm.t_on, prm.t_off)
        hold[0] = 0.0
        return replay(self.t, self.starts, self.level, hold, p0, prm)


def _noise_sd(p: FloatArray) -> float:
    """Robust sensor-noise estimate from second differences (MAD), bar, at least the floor."""
    return max(second_difference_sd(p), _NOISE_FLOOR)


def _pulse_run(rid: str, table: pd.DataFrame) -> _PulseRun:
    t, p, valve = _arrays(table, rid)
    if valve is None:
        raise IdentificationError(f"pulse run {rid!r} has no 'valve' column (the command)")
    k = np.concatenate(([0], edge_indices(valve)))
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
        keep=np.ones(t.size),
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


def _edge_delays(
    runs: Sequence[_PulseRun],
    prm: ValveParams,
    models: Sequence[FloatArray],
    max_delay: float,
    post: float,
) -> pd.DataFrame:
    """Delay of every edge: 1-D fit of the closed-form response after it, with free delay.

    The pressure at the edge is that of the global fit; the segment after the edge (up to
    ``post`` s past the global fit's hold, never past the next edge) is fitted with ``P_e``
    held for ``d`` then the closed form of the new state. Grid search at ``dt/20`` then
    parabolic refinement. An edge is censored when its segment ends within the hold, or when
    the response the model expects over the window has less energy than a single 3-sigma
    sample (e.g. exhausting at 0 bar).
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
            # the response is fitted over ``post`` s after the hold: a window that ended
            # within a long hold (a delay over ``post``) would censor every edge
            stop = int(np.searchsorted(r.t, min(e + hold + post, r.t[k_next]), side="right"))
            tt = r.t[k:stop] - e
            pp = r.p[k:stop]
            step = r.dt / 20.0
            grid = np.arange(0.0, min(seg, max_delay) + 0.5 * step, step)
            mod = segment_pressure(on, p_e, tt[None, :] - grid[:, None], prm)
            # The response after the fitted hold must stand out of the noise: its energy over
            # the window must exceed that of a 3-sigma step at a single sample.
            expected = segment_pressure(on, p_e, tt - hold, prm) - p_e
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
    guard: float = 0.03,
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
        value (a weak tie). :func:`identify` passes the standard errors of experiments 1–2.
    max_delay : float, optional
        Largest delay searched, s.
    min_edges : int, optional
        Rising and falling edges followed by a response needed for each delay.
    post : float, optional
        Length in s of the response fitted after each edge's hold (the global fit's delay) for
        the per-edge delays.
    hac_lag : float, optional
        Largest lag in s of the residual autocorrelation used to inflate the covariance.
    guard : float, optional
        Samples within ``guard`` s after every command edge are left out of the fit (default
        30 ms; 0 keeps them all). See Notes.

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

    *Guard after the edges.* A sensor or line that rings after each valve edge (the paper
    saw a short damped oscillation) repeats the same residual at every edge, so it does not
    average out: it shifts the delays by a fraction of a millisecond, far outside their
    intervals (the coverage benchmark, ``benchmarks/identification_coverage.py``, found 60 %
    instead of 95 % with 10 mbar of 60 Hz ringing). With the first ``guard`` s after every
    edge left out, the delays are read from the later trajectory: a delay shifts the whole
    response that follows the edge (and the pressure every later edge starts from), so the
    information is kept while the ringing is not; the interval widths hardly change. A delay
    longer than ``guard`` also shows its onset directly.

    *Intervals* come from the Gauss–Newton covariance of the fit, with the residuals scaled
    by their RMS and the variance inflated by the residual autocorrelation up to ``hac_lag``
    (Bartlett weights), which is 1 for white sensor noise and grows with ringing. An interval
    is clipped to the searched domain ``[0, max_delay]``: a valve that opens at once gives
    ``lo = 0`` (the physical bound, a valid result), the estimate always inside. A bootstrap
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
    pr = [_pulse_run(rid, tab).guarded(guard) for rid, tab in items]
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
        prm = ValveParams(params.c1, params.k2, params.tau2, t_on, t_off)
        return sum(
            float(np.sum(((r.model(prm, q * q) - r.p) * r.keep / r.sigma) ** 2))
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
        prm = ValveParams(*x[:5])
        parts = [(r.model(prm, x[5 + i] ** 2) - r.p) * r.keep / r.sigma for i, r in enumerate(pr)]
        parts.append((x[:3] - mean) / sd)
        return np.concatenate(parts)

    x0 = np.concatenate([mean, [max(t_on, 1e-6), max(t_off, 1e-6)], q0])
    lb = np.concatenate([1e-6 * np.ones(5), np.zeros(n_run)])
    ub = np.concatenate([np.full(3, np.inf), [max_delay, max_delay], np.full(n_run, np.inf)])
    x0 = np.clip(x0, lb, ub)
    scale = np.concatenate([sd, [1e-3, 1e-3], np.full(n_run, 0.01)])
    sol = least_squares(residuals, x0, bounds=(lb, ub), x_scale=scale, method="trf")
    x = sol.x
    prm = ValveParams(*x[:5])
    p0s = [float(x[5 + i] ** 2) for i in range(n_run)]
    models = [r.model(prm, p0) for r, p0 in zip(pr, p0s, strict=True)]
    n_on, n_off = _responding_edges(pr, prm.t_on, prm.t_off)
    _require_edges(n_on, n_off, min_edges, [r.rid for r in pr])

    # Covariance: rescale the data rows to the residual RMS inflated for autocorrelation.
    jac = np.array(sol.jac, dtype=np.float64, copy=True)
    row = 0
    infl_all, sq = [], []
    for r, m in zip(pr, models, strict=True):
        e = (r.p - m)[r.keep > 0]
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
        lo, hi = v - _Z95 * float(se[i]), v + _Z95 * float(se[i])
        note = ""
        if lo < 0.0 or hi > max_delay:
            note = f"; interval clipped to the domain [0, max_delay = {max_delay:g} s]" + (
                " (it reaches the physical bound 0: a valid result)" if lo < 0.0 else ""
            )
        ests[name] = Estimate(
            v,
            max(lo, 0.0),
            min(hi, max_delay),
            UNITS[name],
            rids,
            method + note,
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
