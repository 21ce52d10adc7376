"""Output-error refinement: the exact model fitted to the pressure of every run that carries the
valve command (docs/explanation/identification.md).

The charge, discharge and pulse fits identify each parameter from the experiment made for it.
A valve that is not exactly the model then gets parameters that describe those experiments and
not the modulated operation the model exists to predict. :func:`refine` starts from those
estimates and fits all five parameters to every run with a ``valve`` column at once (pulse,
staircase, sine, chirp and closed-loop runs, charge and discharge too), comparing *cycle means*:
model output and data are averaged over the same blocks (one modulator cycle on a modulated
run, ``window`` s on the others), which removes the ripple's phase and the sensor's ringing
without throwing away the samples after an edge (a delay shifts every later cycle mean).

The fit is a Gauss–Newton (trust-region) least squares with a forward-difference Jacobian by
parameter (six simulations of the exact model per iteration, no ODE solver); the intervals
come from the fit's sandwich covariance with a Newey–West long-run variance of each run's
scores (Bartlett kernel, bandwidth chosen from the run's residual autocorrelation by Andrews'
AR(1) rule), widened to the run-jackknife variance (leave one run out: the spread between
runs) where that is larger, and, for the delays, by the log's clock (an edge logged off the
log's ticks lies uniformly within its step: it is taken at the step's middle, and
``w**2/12`` is added; :mod:`spa.identification.edges`). The same leave-one-run-out
estimates give each run's held-out FIT (:mod:`spa.identification.adequacy`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np
import pandas as pd
from numba import njit
from scipy.optimize import least_squares

from spa.identification.diagnostics import second_difference_sd
from spa.identification.edges import EdgeTiming, edge_timing
from spa.identification.longrun import andrews_bandwidth, block_means, correlation, newey_west
from spa.identification.rates import _arrays
from spa.identification.results import FloatArray
from spa.model.params import ValveParams
from spa.model.plant import edge_indices, segment_pressure_scalar, transport_runs
from spa.validation import fit_percent, initial_pressure

__all__ = ["RefineFit", "RefineRun", "block_means", "prepare_runs", "refine"]

#: The five refined parameters, in the order of the fit vector.
NAMES = ("c1", "k2", "tau2", "t_on", "t_off")

# A run informs a parameter when it carries at least this share of the parameter's
# information (its squared Jacobian column).
_INFORM_SHARE = 0.01
# The rule of a run nothing decided (:mod:`spa.identification.edges`).
_UNDECIDED = EdgeTiming("undecided", "not decidable", 0.0)

# Noise floor (bar) so that noise-free synthetic data stay well posed.
_NOISE_FLOOR = 1e-6


@dataclass(frozen=True)
class RefineRun:
    """One run prepared for the refinement.

    Attributes
    ----------
    rid, kind, modulator : str
        Run id, kind and modulator type (``""`` when the run has none).
    t, p : numpy.ndarray
        Times from the run's first sample (s) and measured pressure (bar), every
        ``stride``-th sample of the record.
    starts, level : numpy.ndarray
        Command runs: start times (s) and levels.
    p0 : float
        Measured initial pressure, bar.
    block : int
        Samples (of ``t``) per block of the cycle mean.
    stride : int
        Samples of the record per sample of ``t`` (long runs are thinned so that a run has
        at most ``max_samples``; model and data are thinned alike).
    y : numpy.ndarray
        The measured pressure's block means, bar.
    noise : float
        Sensor noise standard deviation of one sample, bar.
    dt : float
        Median logging step, s.
    edge_width : float
        Width of the interval in which each logged edge lies, s (the logging step less the
        command's own step when it is known; 0 for edges logged on the command's tick).
    n_on, n_off : int
        Rising and falling command edges.
    timing : EdgeTiming
        The run's edge-timing rule (:mod:`spa.identification.edges`).
    edge_shift : numpy.ndarray
        How much earlier than logged each command run starts, s (0 for the first; half the
        logging step for an edge that lies off the log's ticks).
    """

    rid: str
    kind: str
    modulator: str
    t: FloatArray
    p: FloatArray
    starts: FloatArray
    level: np.ndarray
    p0: float
    block: int
    stride: int
    y: FloatArray
    noise: float
    dt: float
    edge_width: float
    n_on: int
    n_off: int
    timing: EdgeTiming = field(default_factory=lambda: EdgeTiming("undecided", "", 0.0))
    edge_shift: FloatArray = field(default_factory=lambda: np.zeros(0), repr=False)

    @cached_property
    def command_starts(self) -> FloatArray:
        """:attr:`starts` less :attr:`edge_shift`: the runs either laws' model replays."""
        shifted = self.edge_shift.size == self.starts.size and self.edge_shift.any()
        return self.starts - self.edge_shift if shifted else self.starts

    @cached_property
    def samples_per_command(self) -> np.ndarray:
        """Samples of :attr:`t` in each command run (the first takes those before it)."""
        j = np.searchsorted(self.command_starts, self.t, side="right") - 1
        return np.bincount(np.maximum(j, 0), minlength=self.starts.size)

    def model(self, prm: ValveParams, delay: str = "hold") -> FloatArray:
        """Block means of the exact model's pressure at the run's sample times."""
        hold = np.where(self.level, prm.t_on, prm.t_off)
        hold[0] = 0.0
        starts, level = self.command_starts, self.level
        if delay == "transport":
            starts, level = transport_runs(starts, level, hold)
            hold = np.zeros(starts.size)
        p = replay_kernel(starts, level, hold, self.p0, prm.c1, prm.k2, prm.tau2, self.t)
        return block_means(p, self.block)

    @property
    def noise_ceiling(self) -> float:
        """FIT % of a perfect model on the block means, the sensor noise alone left."""
        den = float(np.linalg.norm(self.y - self.y.mean()))
        if den == 0.0:
            return math.nan
        return 100.0 * (1.0 - self.noise * math.sqrt(self.y.size / self.block) / den)


#: The plant's closed form for one sample (:func:`spa.model.plant.segment_pressure_scalar`),
#: compiled for the kernels below.
_segment = njit(cache=True)(segment_pressure_scalar)


@njit(cache=True)
def replay_kernel(
    starts: np.ndarray,
    level: np.ndarray,
    hold: np.ndarray,
    p0: float,
    c1: float,
    k2: float,
    tau2: float,
    t: np.ndarray,
) -> np.ndarray:  # pragma: no cover (compiled; checked against spa.model.plant.replay)
    """:func:`spa.model.plant.replay` (hold convention) at sorted times ``t`` in one pass:
    the runs chained and each sample's closed form, O(runs + samples)."""
    n = t.size
    m = starts.size
    out = np.empty(n)
    p = p0
    i = 0
    for j in range(m):
        end = starts[j + 1] if j + 1 < m else np.inf
        on = level[j]
        while i < n and t[i] < end:
            out[i] = _segment(on, p, t[i] - starts[j] - hold[j], c1, k2, tau2)
            i += 1
        if j + 1 < m:
            p = _segment(on, p, end - starts[j] - hold[j], c1, k2, tau2)
    return out


@njit(cache=True)
def chain_runs(
    level: np.ndarray, active: np.ndarray, p0: float, c1: float, k2: float, tau2: float
) -> np.ndarray:  # pragma: no cover (compiled; checked against plant.run_start_pressures)
    """Pressure at the start of every run (compiled twin of
    :func:`spa.model.plant.run_start_pressures`)."""
    out = np.empty(level.size)
    p = p0
    for j in range(level.size):
        out[j] = p
        p = _segment(level[j], p, active[j], c1, k2, tau2)
    return out


def _noise_sd(p: FloatArray) -> float:
    """Robust sensor-noise estimate from second differences (MAD), bar, at least the floor."""
    return max(second_difference_sd(p), _NOISE_FLOOR)


def prepare_runs(
    runs: Mapping[str, pd.DataFrame],
    kinds: Mapping[str, str],
    modulators: Mapping[str, str] | None = None,
    command_dt: Mapping[str, float] | None = None,
    window: float = 0.01,
    max_samples: int = 5000,
    total_samples: int = 150_000,
    edges: Mapping[str, EdgeTiming] | None = None,
) -> list[RefineRun]:
    """The runs with a ``valve`` column, with their blocks, noise and edge uncertainty.

    Parameters
    ----------
    runs, kinds : mapping
        Run tables and their kinds.
    modulators : mapping, optional
        Run id → modulator type, for the per-modulator adequacy.
    command_dt : mapping, optional
        Run id → the command's own step (the controller's), s: at or above the logging step
        the logged edges are the true ones (:func:`spa.identification.edges.edge_timing`).
    window : float, optional
        Block length in s on runs without a modulator (pulse, charge, discharge).
    max_samples : int, optional
        Longest run kept whole; a longer one is thinned to every ``stride``-th sample (the
        model is evaluated at the same samples, so the comparison stays exact).
    total_samples : int, optional
        Samples over all runs: with many runs each keeps ``total_samples / runs`` (at least
        1 000, at most ``max_samples``).
    edges : mapping, optional
        Run id → its edge-timing rule (:func:`spa.identification.edges.dataset_edge_timing`);
        a run without one is decided from ``command_dt`` alone, else ``undecided``.

    Returns
    -------
    list of RefineRun
        In run-id order. A modulated run's block is one modulator cycle, measured as the
        median spacing of its rising edges (at least ``window``).
    """
    out = []
    usable = [r for r in sorted(runs) if "valve" in runs[r].columns and len(runs[r]) >= 10]
    # A run whose valve never switches shows no edge. Only a log on the command's tick starts
    # where its command did (a simulated run, a controller that logs itself from the command
    # on); any other (a charge logged from some time after the command) cannot be replayed
    # from its first sample, and the closed-form fits take its onset as a nuisance instead.
    usable = [
        r
        for r in usable
        if runs[r]["valve"].nunique() > 1
        or (edges or {}).get(r, _UNDECIDED).rule == "on_tick"
        or (command_dt or {}).get(r)
    ]
    cap = max(1000, min(max_samples, total_samples // max(len(usable), 1)))
    for rid in usable:
        table = runs[rid]
        t, p, valve = _arrays(table, rid)
        assert valve is not None
        tt = t - t[0]
        dt = float(np.median(np.diff(tt)))
        k = np.concatenate(([0], edge_indices(valve)))
        level = valve[k].astype(bool)
        rises = tt[k[1:][level[1:]]]
        mod = (modulators or {}).get(rid) or ""
        span = window
        if mod and rises.size >= 3:
            span = max(window, float(np.median(np.diff(rises))))
        stride = max(1, math.ceil(tt.size / cap))
        block = max(1, round(span / (dt * stride)))
        ts, ps = tt[::stride], p[::stride]
        timing = (edges or {}).get(rid)
        if timing is None:
            cdt = (command_dt or {}).get(rid)
            timing = edge_timing(table, {"controller_dt": cdt} if cdt else {}, dt)
        shift = np.concatenate(([0.0], timing.shifts(k.size - 1)))
        out.append(
            RefineRun(
                rid=rid,
                kind=str(kinds.get(rid, "")),
                modulator=str(mod),
                t=ts,
                p=ps,
                starts=tt[k],
                level=level,
                p0=initial_pressure(tt, p),
                block=block,
                stride=stride,
                y=block_means(ps, block),
                noise=_noise_sd(p[:50_000]),
                dt=dt,
                edge_width=timing.width,
                n_on=int(np.sum(level[1:])),
                n_off=int(np.sum(~level[1:])),
                timing=timing,
                edge_shift=shift,
            )
        )
    return out


@dataclass(frozen=True)
class RefineFit:
    """The refinement of one delay convention.

    Attributes
    ----------
    delay : str
        ``"hold"`` or ``"transport"``.
    start, params : ValveParams
        Where the fit started (today's estimates) and where it ended.
    se : dict
        Standard error of each parameter (sandwich/jackknife, before the logging-step term).
    correlation : tuple of tuple of float
        The parameters' correlation matrix (in :data:`NAMES`' order) from the sandwich
        covariance: the joint uncertainty the verification's draws keep
        (:func:`spa.plan.bands.parameter_draws`); empty when it was not computed.
    se_difference : float
        Standard error of ``t_off - t_on`` (the same, with the two delays' covariance): the
        delays move together with a lag the data cannot tell from a delay, their difference
        much less.
    informed : dict
        Parameter → ids of the runs that inform it.
    fit_before, fit_after, fit_heldout : dict
        Run id → FIT % of the cycle means with the starting, the refined and the
        leave-this-run-out parameters.
    noise_ceiling : dict
        Run id → FIT % the sensor noise alone allows on that run's cycle means.
    bandwidth : dict
        Run id → Newey–West bandwidth in blocks.
    nfev : int
        Simulations of the whole dataset the fit took.
    converged : bool
        Whether the least squares met its tolerance.
    """

    delay: str
    start: ValveParams
    params: ValveParams
    se: Mapping[str, float]
    informed: Mapping[str, tuple[str, ...]]
    fit_before: Mapping[str, float]
    fit_after: Mapping[str, float]
    fit_heldout: Mapping[str, float]
    noise_ceiling: Mapping[str, float]
    bandwidth: Mapping[str, int]
    nfev: int
    converged: bool
    runs: tuple[RefineRun, ...] = field(repr=False, default=())
    se_difference: float = math.nan
    correlation: tuple[tuple[float, ...], ...] = ()

    def final_models(self) -> list[FloatArray]:
        """Each run's model block means at the fitted parameters (residuals: ``y - model``)."""
        return [r.model(self.params, self.delay) for r in self.runs]

    def heldout_median(self) -> float:
        """Median held-out FIT over the runs (NaN when none is finite)."""
        vals = [v for v in self.fit_heldout.values() if math.isfinite(v)]
        return float(np.median(vals)) if vals else math.nan


def _to_x(prm: ValveParams) -> FloatArray:
    return np.array([math.log(prm.c1), math.log(prm.k2), math.log(prm.tau2), prm.t_on, prm.t_off])


def _to_params(x: FloatArray) -> ValveParams:
    return ValveParams(
        math.exp(x[0]), math.exp(x[1]), math.exp(x[2]), max(x[3], 0.0), max(x[4], 0.0)
    )


def _fd_jacobian(
    runs: Sequence[RefineRun],
    x: FloatArray,
    base: list[FloatArray],
    delay: str,
    upper: float,
    free: Sequence[int] = range(5),
) -> list[FloatArray]:
    """Per-run forward-difference Jacobian of the block means by the ``free`` parameters
    (one simulation each)."""
    steps = np.array([1e-5, 1e-5, 1e-5, 2e-6, 2e-6])
    cols: list[list[FloatArray]] = [[] for _ in runs]
    for i in free:
        h = steps[i]
        if i >= 3 and x[i] + h > upper:
            h = -h
        xi = x.copy()
        xi[i] += h
        prm = _to_params(xi)
        for j, r in enumerate(runs):
            cols[j].append((r.model(prm, delay) - base[j]) / h)
    return [np.column_stack(c) for c in cols]


def refine(
    runs: Sequence[RefineRun],
    start: ValveParams,
    *,
    delay: str = "hold",
    max_delay: float = 0.05,
    max_nfev: int = 30,
    delay_prior: Mapping[str, tuple[float, float]] | None = None,
) -> RefineFit:
    """Fit the exact model's five parameters to the cycle means of ``runs``.

    Parameters
    ----------
    runs : sequence of RefineRun
        From :func:`prepare_runs`.
    start : ValveParams
        Today's estimates (charge, discharge and pulse fits): where the fit starts.
    delay : {"hold", "transport"}, optional
        Delay convention of the model fitted.
    max_delay : float, optional
        Upper bound of ``t_on`` and ``t_off``, s.
    max_nfev : int, optional
        Largest number of least-squares iterations.
    delay_prior : mapping, optional
        ``{"t_on": (value, se), "t_off": (value, se)}``: the delays read at the command
        edges (:meth:`spa.identification.edge_local.EdgeDelays.prior`). They are held at
        ``value`` and only ``c1``, ``k2``, ``tau2`` are fitted; each delay's variance is
        ``se**2``, uncorrelated with the others.

    Returns
    -------
    RefineFit

    Notes
    -----
    Each run's block residuals are weighted by ``1/s_r``, ``s_r`` the RMS of that run's
    residuals at the start (at least the noise of a block mean), so that a run the model
    misses does not drown the others. ``log c1``, ``log k2``, ``log tau2``, ``t_on`` and
    ``t_off`` are the fit variables (delays bounded to ``[0, max_delay]``).
    """
    if not runs:
        raise ValueError("refine needs at least one run with a 'valve' column")
    x0 = _to_x(start)
    x0[3:] = np.clip(x0[3:], 0.0, max_delay)
    if delay_prior is not None:
        x0[3:] = [min(max(float(delay_prior[n][0]), 0.0), max_delay) for n in ("t_on", "t_off")]
    free = np.arange(3 if delay_prior is not None else 5)
    models0 = [r.model(_to_params(x0), delay) for r in runs]
    weight = np.array(
        [
            1.0
            / max(
                float(np.sqrt(np.mean((m - r.y) ** 2))),
                r.noise / math.sqrt(r.block),
                _NOISE_FLOOR,
            )
            for r, m in zip(runs, models0, strict=True)
        ]
    )
    sizes = np.array([r.y.size for r in runs])
    offsets = np.concatenate(([0], np.cumsum(sizes)))
    cache: dict[bytes, list[FloatArray]] = {}

    def whole(xf: FloatArray) -> FloatArray:
        x = x0.copy()
        x[free] = xf
        return x

    def models(x: FloatArray) -> list[FloatArray]:
        key = x.tobytes()
        if key not in cache:
            prm = _to_params(x)
            cache.clear()
            cache[key] = [r.model(prm, delay) for r in runs]
        return cache[key]

    def fun(xf: FloatArray) -> FloatArray:
        return np.concatenate(
            [(m - r.y) * w for m, r, w in zip(models(whole(xf)), runs, weight, strict=True)]
        )

    def jac(xf: FloatArray) -> FloatArray:
        x = whole(xf)
        blocks = _fd_jacobian(runs, x, models(x), delay, max_delay, free)
        return np.vstack([b * w for b, w in zip(blocks, weight, strict=True)])

    lb = np.array([-np.inf, -np.inf, -np.inf, 0.0, 0.0])
    ub = np.array([np.inf, np.inf, np.inf, max_delay, max_delay])
    sol = least_squares(
        fun,
        x0[free],
        jac=jac,
        bounds=(lb[free], ub[free]),
        x_scale=np.array([0.01, 0.01, 0.01, 1e-4, 1e-4])[free],
        method="trf",
        max_nfev=max_nfev,
        xtol=1e-8,
        ftol=1e-10,
    )
    x = whole(sol.x)
    prm = _to_params(x)
    final = models(x)
    jf = jac(sol.x)
    jx = np.zeros((jf.shape[0], 5))
    jx[:, free] = jf
    nfev = int(sol.nfev) + free.size * (int(sol.njev) + 1) + 1

    # Per-run pieces of the normal equations at the optimum (in the variables of x).
    blocks = [jx[offsets[j] : offsets[j + 1]] for j in range(len(runs))]
    resid = [(m - r.y) * w for m, r, w in zip(final, runs, weight, strict=True)]
    h_run = [b.T @ b for b in blocks]
    g_run = [b.T @ e for b, e in zip(blocks, resid, strict=True)]
    hess = np.sum(h_run, axis=0)
    hinv = np.linalg.pinv(hess)  # held delays: zero rows and columns, zero steps
    omega = np.zeros((5, 5))
    bandwidth = {}
    for r, b, e in zip(runs, blocks, resid, strict=True):
        lag = andrews_bandwidth(e)
        bandwidth[r.rid] = lag
        omega += newey_west(b * e[:, None], lag)
    cov = hinv @ omega @ hinv
    if delay_prior is not None:
        cov[3, 3], cov[4, 4] = (float(delay_prior[n][1]) ** 2 for n in ("t_on", "t_off"))

    # Which runs inform which parameter.
    info = np.array([np.diag(h) for h in h_run])  # (runs, 5)
    share = info / np.maximum(info.sum(axis=0), 1e-300)
    informed = {
        name: tuple(r.rid for j, r in enumerate(runs) if share[j, i] >= _INFORM_SHARE)
        for i, name in enumerate(NAMES)
    }
    if delay_prior is not None:  # read at the edges: the runs that have them
        informed["t_on"] = tuple(r.rid for r in runs if r.n_on > 0)
        informed["t_off"] = tuple(r.rid for r in runs if r.n_off > 0)

    # Leave one run out: one Gauss-Newton step from the full fit without that run.
    g_all = np.sum(g_run, axis=0)
    loo = []
    for j in range(len(runs)):
        step = -np.linalg.pinv(hess - h_run[j]) @ (g_all - g_run[j])
        xj = x + step
        xj[3:] = np.clip(xj[3:], 0.0, max_delay)
        loo.append(xj)
    loo_x = np.array(loo)
    var = np.maximum(np.diag(cov), 0.0)
    for i, name in enumerate(NAMES[: free.size]):
        members = [j for j, r in enumerate(runs) if r.rid in informed[name]]
        # The jackknife needs the parameter informed without each run in turn.
        members = [j for j in members if (info[:, i].sum() - info[j, i]) > 0.1 * info[:, i].sum()]
        if len(members) >= 3:
            v = loo_x[members, i]
            jack = (len(members) - 1) / len(members) * float(np.sum((v - v.mean()) ** 2))
            var[i] = max(var[i], jack)
    # The delays' difference: its sandwich variance with their covariance, and the jackknife
    # over the runs that inform both.
    contrast = np.array([0.0, 0.0, 0.0, -1.0, 1.0])
    var_diff = max(float(contrast @ cov @ contrast), 0.0)
    both = [
        j
        for j, r in enumerate(runs)
        if r.rid in informed["t_on"]
        and r.rid in informed["t_off"]
        and all((info[:, i].sum() - info[j, i]) > 0.1 * info[:, i].sum() for i in (3, 4))
    ]
    if len(both) >= 3 and delay_prior is None:
        v = loo_x[both, 4] - loo_x[both, 3]
        var_diff = max(var_diff, (len(both) - 1) / len(both) * float(np.sum((v - v.mean()) ** 2)))
    # Back to the parameters' own units (delta method for the log-parameters).
    values = np.array([getattr(prm, n) for n in NAMES])
    scale = np.array([values[0], values[1], values[2], 1.0, 1.0])
    se = {name: float(scale[i] * math.sqrt(var[i])) for i, name in enumerate(NAMES)}

    before = {r.rid: fit_percent(r.y, m) for r, m in zip(runs, models0, strict=True)}
    after = {r.rid: fit_percent(r.y, m) for r, m in zip(runs, final, strict=True)}
    heldout = {
        r.rid: fit_percent(r.y, r.model(_to_params(loo_x[j]), delay)) for j, r in enumerate(runs)
    }
    return RefineFit(
        delay=delay,
        start=start,
        params=prm,
        se=se,
        informed=informed,
        fit_before=before,
        fit_after=after,
        fit_heldout=heldout,
        noise_ceiling={r.rid: r.noise_ceiling for r in runs},
        bandwidth=bandwidth,
        nfev=nfev + 1,  # the held-out runs: one simulation of each
        converged=bool(sol.status > 0),
        runs=tuple(runs),
        se_difference=math.sqrt(var_diff),
        correlation=correlation(cov),
    )
