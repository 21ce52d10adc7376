"""The actuator's own laws, fitted by output error and chosen only where the data demand them
(docs/model.md, "The general two-mode model").

A single charge curve cannot tell laws apart: some ``f_open`` fits any monotone charge. The
runs that carry the valve command (pulse trains, staircases, sines, chirps) hold partial
charges and discharges started from many pressures, and those pin the laws down.
:func:`fit_laws` fits the log-rate values at the knots and the exhaust exponent ``m`` to the
cycle means of every such run (:class:`~spa.identification.refine.RefineRun`), the valve's
other parameters and its delays held where the refinement left them; :func:`choose_laws`
keeps the paper's laws unless the fitted ones predict held-out modulated runs better by
more than two FIT points and by a one-sided t-test at the level of two normal standard errors.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.optimize import least_squares

from spa.identification.laws_heldout import LeaveOneOutState
from spa.identification.laws_model import (
    _laws,
    _valve,
    law_model,
    law_model_sensitivity,
    law_names,
)
from spa.identification.longrun import andrews_bandwidth, newey_west
from spa.identification.refine import RefineRun
from spa.identification.results import FloatArray
from spa.model.laws import DEFAULT_KNOTS, Laws
from spa.model.params import ValveParams
from spa.validation import fit_percent

__all__ = [
    "LawsChoice",
    "LawsFit",
    "choose_laws",
    "fit_laws",
    "gain_quantile",
    "law_model",
    "law_names",
]

_NOISE_FLOOR = 1e-6  # bar, as the refinement's
_STEP = 1e-3  # forward-difference step of the log-rates and of m
_BROYDEN = 4  # Broyden updates of the Jacobian between finite-difference ones
_M_BOUNDS = (0.5, 1.0)
#: Bound of the log-rates: rates within a factor e**6 (about 400) of the paper's scales.
_LOG_BOUND = 6.0
#: The choice rule: the mean held-out gain over the one-sided ``GAIN_LEVEL`` quantile of
#: Student's t with n - 1 degrees of freedom times its standard error (2 standard errors of a
#: normal, kept at the same level on few runs), and over ``GAIN_POINTS`` FIT points.
GAIN_SE = 2.0
GAIN_LEVEL = 0.5 * (1.0 + math.erf(GAIN_SE / math.sqrt(2.0)))  # the normal's cdf at 2
GAIN_POINTS = 2.0


@dataclass(frozen=True)
class LawsFit:
    """An output-error fit of the laws (:func:`fit_laws`).

    Attributes
    ----------
    start : ValveParams
        The valve the fit started from (its scales ``c1`` and ``tau2`` are held).
    params : ValveParams
        ``start`` with the fitted laws (``laws`` None if they landed on the paper's), and
        the refitted ``k2``, ``t_on``, ``t_off``.
    laws : Laws
        The fitted laws.
    names : tuple of str
        The fit vector's names (:func:`law_names`).
    x : numpy.ndarray
        The fit vector: log-rate values at the knots, ``m``, ``log k2``, ``t_on``,
        ``t_off``.
    cov : numpy.ndarray
        Its covariance: sandwich, with each run's scores' Newey–West long-run variance
        (Bartlett kernel, Andrews' bandwidth), as the refinement's; rows and columns of
        held entries are 0.
    fit : dict
        Run id → FIT % of the cycle means under the fitted laws.
    heldout : dict
        Run id → the fit vector without that run: one Gauss–Newton step from the full fit
        (as the refinement's held-out FIT), bounds enforced.
    fixed : tuple of str
        The entries of the fit vector that were held.
    nfev : int
        Model evaluations.
    converged : bool
        Whether the least squares met its tolerance.
    state : LeaveOneOutState or None
        The weights, Jacobian and residuals at the fit, for the held-out refits.
    """

    start: ValveParams
    params: ValveParams
    laws: Laws
    names: tuple[str, ...]
    x: FloatArray
    cov: FloatArray
    fit: Mapping[str, float]
    heldout: Mapping[str, FloatArray]
    fixed: tuple[str, ...]
    nfev: int
    converged: bool
    state: LeaveOneOutState | None = field(default=None, repr=False, compare=False)

    @property
    def se(self) -> dict[str, float]:
        """Standard error of each entry of the fit vector."""
        return {
            n: float(math.sqrt(max(v, 0.0)))
            for n, v in zip(self.names, np.diag(self.cov), strict=True)
        }


def fit_laws(
    runs: Sequence[RefineRun],
    start: ValveParams,
    *,
    delay: str | None = None,
    knots: Sequence[float] = DEFAULT_KNOTS,
    m: float | None = None,
    valve: bool = True,
    max_delay: float = 0.05,
    x0: FloatArray | None = None,
    max_nfev: int = 30,
    held_delays: Mapping[str, tuple[float, float]] | None = None,
) -> LawsFit:
    """Fit the charge and discharge laws to the cycle means of every run with the command.

    Parameters
    ----------
    runs : sequence of RefineRun
        From :func:`spa.identification.refine.prepare_runs`: every run with a ``valve``
        column (charge, discharge, pulse, modulated).
    start : ValveParams
        The identified valve (after :func:`~spa.identification.refine.refine`): where the
        fit starts (its laws, if any, else the paper's). ``c1`` and ``tau2`` are held (the
        log-rates' constant terms take their place).
    delay : {"hold", "transport"}, optional
        Delay convention; ``start.delay`` when omitted.
    knots : sequence of float, optional
        Knots of the log-rates, fractions of ``k2``.
    m : float, optional
        Hold the exhaust exponent at this value instead of fitting it.
    valve : bool, optional
        Refit ``k2``, ``t_on`` and ``t_off`` with the laws (default): the delays the
        paper's laws were identified with absorb part of their error.
    max_delay : float, optional
        Upper bound of the refitted delays, s.
    x0 : numpy.ndarray, optional
        Starting fit vector (a previous fit's :attr:`LawsFit.x`, for a leave-one-out
        refit); overrides ``start``'s laws.
    max_nfev : int, optional
        Largest number of least-squares iterations.
    held_delays : mapping, optional
        ``{"t_on": (value, se), "t_off": (value, se)}``, the delays read at the command
        edges: held at ``start``'s (the refinement held them too), each with variance
        ``se**2`` in :attr:`LawsFit.cov`; ``k2`` is still refitted when ``valve``.

    Returns
    -------
    LawsFit

    Raises
    ------
    ValueError
        If ``runs`` is empty, or ``m`` or ``x0`` is out of range (named).

    Notes
    -----
    The residuals are each run's block means, model minus data, weighted by ``1/s_r`` with
    ``s_r`` the RMS of the run's residuals under the starting laws (at least the noise of
    a block mean), as in the refinement, so that no run drowns the others. The Jacobian is
    exact, carried through the time maps in one pass
    (:func:`~spa.identification.laws_model.law_model_sensitivity`); under the transport
    convention, or when a run starts above ``k2``, it is a forward difference (one
    simulation per coefficient, time maps of :data:`~spa.model.laws.timemap.FIT_NODES`
    nodes). It is updated by Broyden's rank-one rule for up to four steps in
    between (one simulation a step); the covariance's is the same Jacobian at the optimum.
    """
    if not runs:
        raise ValueError("fit_laws needs at least one run with a 'valve' column")
    dl = start.delay if delay is None else delay
    kn = tuple(float(k) for k in knots)
    nk = len(kn)
    im = 2 * nk  # index of m; then log k2, t_on, t_off
    names = law_names(kn)
    if x0 is None:
        lw = start.laws if start.laws is not None and start.laws.knots == kn else None
        x = np.zeros(len(names))
        x[im] = 0.5
        if lw is not None:
            x[: im + 1] = (*lw.log_g, *lw.log_h, lw.m)
        x[im + 1 :] = (math.log(start.k2), start.t_on, start.t_off)
    else:
        x = np.array(x0, dtype=np.float64)
        if x.shape != (len(names),):
            raise ValueError(f"x0 must hold {len(names)} values ({names}), got {x.shape}")
    if m is not None:
        if not _M_BOUNDS[0] <= m <= _M_BOUNDS[1]:
            raise ValueError(f"m must be in [0.5, 1], got {m!r}")
        x[im] = m
    x[im] = np.clip(x[im], _M_BOUNDS[0] + 1e-9, _M_BOUNDS[1])
    x[im + 2 :] = np.clip(x[im + 2 :], 0.0, max_delay)
    held = ([] if m is None else [im]) + ([] if valve else [im + 1, im + 2, im + 3])
    if held_delays is not None:
        held = sorted({*held, im + 2, im + 3})
    free = np.array([i for i in range(len(names)) if i not in held])
    lo = np.full(len(names), -np.inf)
    hi = np.full(len(names), np.inf)
    lo[:im], hi[:im] = -_LOG_BOUND, _LOG_BOUND
    lo[im], hi[im] = _M_BOUNDS
    lo[im + 2 :], hi[im + 2 :] = 0.0, max_delay
    scale = np.full(len(names), 0.1)
    scale[im + 1], scale[im + 2 :] = 0.01, 1e-3
    steps = np.full(len(names), _STEP)
    steps[im + 2 :] = 1e-4

    def params(xf: FloatArray) -> ValveParams:
        full = x.copy()
        full[free] = xf
        return _valve(start, np.clip(full, lo, hi), kn)

    def models(xf: FloatArray) -> list[FloatArray]:
        prm = params(xf)
        return [law_model(r, prm, dl) for r in runs]

    m0 = models(x[free])
    weight = np.array(
        [
            1.0
            / max(
                float(np.sqrt(np.mean((mo - r.y) ** 2))),
                r.noise / math.sqrt(r.block),
                _NOISE_FLOOR,
            )
            for r, mo in zip(runs, m0, strict=True)
        ]
    )
    cache: dict[bytes, list[FloatArray]] = {x[free].tobytes(): m0}
    jacs: dict[bytes, FloatArray] = {}
    last: list[Any] = []  # x, residuals, Jacobian, updates since the last finite difference
    count = [1]

    def cached(xf: FloatArray) -> list[FloatArray]:
        key = xf.tobytes()
        if key not in cache:
            if len(cache) > 4:
                cache.clear()
            cache[key] = models(xf)
            count[0] += 1
        return cache[key]

    def resid(mods: list[FloatArray]) -> FloatArray:
        return np.concatenate([(mo - r.y) * w for mo, r, w in zip(mods, runs, weight, strict=True)])

    def fun(xf: FloatArray) -> FloatArray:
        return resid(cached(xf))

    def jac(xf: FloatArray) -> FloatArray:
        # a finite-difference Jacobian, then _BROYDEN rank-one updates from it (one
        # simulation a step instead of one per coefficient)
        key = xf.tobytes()
        if key not in jacs:
            f1 = fun(xf)
            if last and last[3] < _BROYDEN:
                dx = (xf - last[0]) / scale[free]
                j1 = last[2] + np.outer(f1 - last[1] - last[2] @ (dx * scale[free]),
                                        dx / scale[free]) / float(dx @ dx)  # fmt: skip
                last[:] = [xf.copy(), f1, j1, last[3] + 1]
            else:
                last[:] = [xf.copy(), f1, _jac(xf), 0]
            jacs.clear()  # the last one only: the fit ends where it last took one
            jacs[key] = last[2]
        return jacs[key]

    def _jac(xf: FloatArray) -> FloatArray:
        f0 = fun(xf)
        exact = _exact_jac(xf)
        cols = []
        for i in range(xf.size):
            if exact is not None:
                cols.append(exact[:, free[i]])
                continue
            xs = xf.copy()
            step = steps[free[i]]
            if xs[i] + step > hi[free[i]]:
                step = -step
            xs[i] += step
            count[0] += 1
            cols.append((resid(models(xs)) - f0) / step)
        return np.column_stack(cols)

    def _exact_jac(xf: FloatArray) -> FloatArray | None:
        # every column from the time maps' sensitivities, in one pass
        prm = params(xf)
        sens = [law_model_sensitivity(r, prm, dl) for r in runs]
        if any(sn is None for sn in sens):
            return None
        count[0] += 1
        return np.concatenate([sn[1] * w for sn, w in zip(sens, weight, strict=True)])  # type: ignore[index]

    sol = least_squares(
        fun,
        x[free],
        jac=jac,
        bounds=(lo[free], hi[free]),
        method="trf",
        max_nfev=max_nfev,
        x_scale=scale[free],
        tr_solver="lsmr",  # not an SVD of the tall Jacobian at every step
        xtol=1e-8,
        ftol=1e-6,  # a weighted cost of about 2000 moves by 0.002: no FIT's last digit
    )
    xf = sol.x
    final = cached(xf)
    jx = jac(xf) if last and last[3] == 0 and last[0].tobytes() == xf.tobytes() else _jac(xf)
    sizes = np.array([r.y.size for r in runs])
    offsets = np.concatenate(([0], np.cumsum(sizes)))
    hess = jx.T @ jx
    hinv = np.linalg.pinv(hess)
    omega = np.zeros((free.size, free.size))
    h_run, g_run = [], []
    for j, (r, mo, w) in enumerate(zip(runs, final, weight, strict=True)):
        b = jx[offsets[j] : offsets[j + 1]]
        e = (mo - r.y) * w
        omega += newey_west(b * e[:, None], andrews_bandwidth(e))
        h_run.append(b.T @ b)
        g_run.append(b.T @ e)
    g_all = np.sum(g_run, axis=0)
    cov = np.zeros((len(names), len(names)))
    cov[np.ix_(free, free)] = hinv @ omega @ hinv
    if held_delays is not None:
        cov[im + 2, im + 2], cov[im + 3, im + 3] = (
            float(held_delays[n][1]) ** 2 for n in ("t_on", "t_off")
        )
    full = x.copy()
    full[free] = xf
    full = np.clip(full, lo, hi)
    prm = params(xf)
    heldout = {}
    for j, r in enumerate(runs):
        xj = full.copy()
        xj[free] = xf - np.linalg.pinv(hess - h_run[j]) @ (g_all - g_run[j])
        heldout[r.rid] = np.clip(xj, lo, hi)
    return LawsFit(
        start=start,
        params=prm,
        laws=_laws(full, kn),
        names=names,
        x=full,
        cov=cov,
        fit={r.rid: fit_percent(r.y, mo) for r, mo in zip(runs, final, strict=True)},
        heldout=heldout,
        fixed=tuple(names[i] for i in held),
        nfev=count[0],
        converged=bool(sol.success),
        state=LeaveOneOutState(dl, free, lo, hi, weight, jx, fun(xf), offsets),
    )


@dataclass(frozen=True)
class LawsChoice:
    """The paper's laws or the identified ones, by held-out FIT on the modulated runs.

    Attributes
    ----------
    laws : {"paper", "identified"}
        The choice.
    params : ValveParams
        The valve to use: the start's, or with the identified laws.
    gain, se : float
        Mean paired held-out FIT gain of the identified laws over the paper's (points),
        and its standard error; NaN with fewer than two modulated runs.
    fit_paper, fit_identified : dict
        Modulated run id → held-out FIT % under each.
    fit : LawsFit or None
        The fit on every run (None when there were too few modulated runs to fit for).
    reason : str
        The rule's outcome in a sentence.
    """

    laws: str
    params: ValveParams
    gain: float
    se: float
    fit_paper: Mapping[str, float]
    fit_identified: Mapping[str, float]
    fit: LawsFit | None = field(repr=False)
    reason: str


def gain_quantile(n: int) -> float:
    """The standard errors a mean paired gain over ``n`` runs must exceed to choose the laws.

    Parameters
    ----------
    n : int
        Modulated runs held out, at least 2.

    Returns
    -------
    float
        The one-sided :data:`GAIN_LEVEL` quantile of Student's t with ``n - 1`` degrees of
        freedom: a mean of ``n`` normal gains with no true gain passes it with probability
        ``1 - GAIN_LEVEL`` (2.3 %), whatever ``n``.

    Raises
    ------
    ValueError
        If ``n < 2``: one run has no spread to test against.

    Examples
    --------
    >>> round(gain_quantile(2), 2), round(gain_quantile(6), 2), round(gain_quantile(10), 2)
    (13.97, 2.65, 2.32)
    """
    from scipy.stats import t as student_t  # scipy.stats stays out of the stages' imports

    if n < 2:
        raise ValueError(f"gain_quantile: n = {n} held-out runs, expected at least 2")
    return float(student_t.ppf(GAIN_LEVEL, n - 1))


def choose_laws(
    runs: Sequence[RefineRun],
    start: ValveParams,
    *,
    fit: LawsFit | None = None,
    paper_heldout: Mapping[str, float] | None = None,
    delay: str | None = None,
    knots: Sequence[float] = DEFAULT_KNOTS,
    max_nfev: int = 30,
    refit: bool = True,
    max_nfev_heldout: int = 8,
    held_delays: Mapping[str, tuple[float, float]] | None = None,
) -> LawsChoice:
    """Keep the paper's laws unless the identified ones predict held-out modulated runs
    better, by a one-sided t-test at the level of 2 normal standard errors and by 2 FIT points.

    Parameters
    ----------
    runs : sequence of RefineRun
        Every run with the command; those with a modulator are the held-out runs.
    start : ValveParams
        The identified valve under the paper's laws (its ``laws`` are ignored).
    fit : LawsFit, optional
        :func:`fit_laws` on every run, when already made.
    paper_heldout : mapping, optional
        Run id → the paper's laws' held-out FIT (the refinement's
        :attr:`~spa.identification.refine.RefineFit.fit_heldout`). Without it the paper's
        FIT of ``start`` on the run is used, in-sample and so favouring the paper's laws.
    delay : {"hold", "transport"}, optional
        ``start.delay`` when omitted.
    knots : sequence of float, optional
        Knots of the identified laws.
    refit : bool, optional
        Refit the laws without each modulated run (default): damped Gauss–Newton from the
        full fit, at most ``max_nfev_heldout`` simulations
        (:func:`~spa.identification.laws_heldout.refit_without`). False uses the one
        undamped step of :attr:`LawsFit.heldout` instead; on the compliant balloons that
        step is too far from the refit (gain -3.3 points against +6.8) to be the default.
    max_nfev, max_nfev_heldout : int, optional
        Iterations of the fit on every run and of each leave-one-out refit.
    held_delays : mapping, optional
        The delays read at the command edges, held in the fit (:func:`fit_laws`).

    Returns
    -------
    LawsChoice

    Notes
    -----
    For each modulated run ``r`` the laws fitted without ``r`` predict it; ``d_r`` is that
    FIT minus the paper's on ``r``. The identified laws are chosen when
    ``mean(d) > q*sd(d)/sqrt(n)`` and ``mean(d) > 2`` points, ``q`` the one-sided 97.7 %
    (:data:`GAIN_LEVEL`, a normal's 2 standard errors) quantile of Student's t with ``n - 1``
    degrees of freedom: 13.97 at ``n = 2``, 2.65 at 6, 2.32 at 10, where a fixed 2 would be a
    15 % test at ``n = 2``. AIC and BIC do not apply:
    output-error residuals are autocorrelated and the degrees of freedom of the log-rate
    polynomials are only effective.
    """
    from spa.identification.laws_heldout import refit_without

    paper = dataclasses.replace(start, laws=None)
    dl = paper.delay if delay is None else delay
    held = [r for r in runs if r.modulator]
    if len(held) < 2:
        return LawsChoice(
            "paper",
            paper,
            math.nan,
            math.nan,
            {},
            {},
            fit,
            f"{len(held)} modulated run(s): too few to compare the laws; the paper's are kept",
        )
    full = (
        fit
        if fit is not None
        else fit_laws(
            runs, paper, delay=dl, knots=knots, max_nfev=max_nfev, held_delays=held_delays
        )
    )
    fit_p: dict[str, float] = {}
    fit_i: dict[str, float] = {}
    for r in held:
        if paper_heldout is not None and r.rid in paper_heldout:
            fit_p[r.rid] = float(paper_heldout[r.rid])
        else:
            fit_p[r.rid] = fit_percent(r.y, law_model(r, paper, dl))
        if refit:
            prm = refit_without(full, runs, r.rid, max_nfev=max_nfev_heldout)
        else:
            prm = _valve(paper, full.heldout[r.rid], full.laws.knots)
        fit_i[r.rid] = fit_percent(r.y, law_model(r, prm, dl))
    d = np.array([fit_i[k] - fit_p[k] for k in fit_p])
    gain = float(d.mean())
    se = float(d.std(ddof=1) / math.sqrt(d.size))
    q = gain_quantile(d.size)
    chosen = gain > q * se and gain > GAIN_POINTS
    why = (
        f"held-out FIT gain {gain:+.1f} points over {d.size} modulated runs "
        f"(standard error {se:.1f}; t({d.size - 1}) threshold {q * se:.1f})"
    )
    if chosen:
        return LawsChoice(
            "identified",
            full.params,
            gain,
            se,
            fit_p,
            fit_i,
            full,
            f"{why}: above it and 2 points, the identified laws are used",
        )
    return LawsChoice(
        "paper",
        paper,
        gain,
        se,
        fit_p,
        fit_i,
        full,
        f"{why}: not above it and 2 points, the paper's laws are kept",
    )
