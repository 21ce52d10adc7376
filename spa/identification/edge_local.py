"""The valve's delays read at each command edge on its own, in both delay conventions.

The refinement (:mod:`spa.identification.refine`) fits the delays to the runs' cycle means.
Cycle means show the difference ``t_off - t_on`` well (the time a pulse gains) and their
common part hardly: a lag the model lacks (a sensor's, a tube's, a bouncing seat) then pulls
both delays anywhere in ``[0, max_delay]``, and two sessions on one plant disagree beyond
their intervals. The pressure right at an edge shows the delay itself: nothing happens (the
hold convention) or the old state goes on (transport), then the new state's closed form
starts. :func:`edge_delays` fits that, edge by edge, and :meth:`EdgeDelays.prior` gives the
delays common to the edges, which the refinement holds.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pandas as pd
from scipy.stats import t as student_t
from scipy.stats import wilcoxon

from spa.identification.results import FloatArray
from spa.model.params import ValveParams
from spa.model.plant import segment_pressure

__all__ = ["FORM_LEVEL", "EdgeDelays", "edge_delays", "edge_priors", "edges_convention"]

#: Significance of the edges' form test below which the edges' form and delays are used.
FORM_LEVEL = 0.01

#: Longest window before an edge, s.
_PRE = 0.015
#: Response fitted after the longest delay searched, s.
_POST = 0.03
#: Edges kept per direction and run (evenly spaced), so that long modulated runs stay cheap.
_PER_RUN = 120
#: Largest standard error of one edge's delay, in logging steps, for the edge to count.
_RESOLVED = 5.0
#: Fewest uncensored edges per direction for a delay.
_MIN_EDGES = 6

_FORMS = ("hold", "transport")
_COLUMNS = [
    "run",
    "t",
    "direction",
    "p_edge",
    "noise",
    "samples",
    "censored",
    *(f"{w}_{f}" for f in _FORMS for w in ("delay", "sse")),
]


@dataclass(frozen=True)
class EdgeDelays:
    """Every command edge's delay in both conventions (:func:`edge_delays`).

    Attributes
    ----------
    table : pandas.DataFrame
        One row per edge: ``run``, ``t`` (s from the run's start), ``direction`` (``on`` or
        ``off``), ``p_edge`` (bar), ``noise`` (bar, the run's sensor noise), ``samples`` (in
        the edge's window), ``censored`` and,
        for each form, ``delay_<form>`` (s, the edge's own best delay) and ``sse_<form>``
        (bar², the edge window's squared residual there).
    dt : float
        Median logging step of the runs, s.
    grid : numpy.ndarray
        The delays every edge was fitted at, s.
    profiles : mapping
        Form → array (edges × ``grid``): each edge's squared residual at each delay of the
        grid, its other parameters fitted (the rows of ``table``).
    """

    table: pd.DataFrame
    dt: float
    grid: FloatArray = field(default_factory=lambda: np.zeros(0))
    profiles: Mapping[str, FloatArray] = field(default_factory=dict)

    def used(self) -> pd.DataFrame:
        """The uncensored edges."""
        return self.table[~self.table["censored"].to_numpy(bool)]

    def _pooled(self, form: str, rows: np.ndarray) -> tuple[float, float]:
        """The common delay of the edges ``rows`` (positions in ``table``) in ``form`` and its
        standard error: the minimum of their summed squared residuals weighted by each run's
        noise (a Gaussian likelihood's profile), refined by a parabola through the grid
        points within a logging step; the standard error from that parabola's curvature
        (``sqrt(2/curvature)``), scaled up by the fit's reduced chi-square where it exceeds 1
        (a misfit or a noise the run's estimate understates: Birge's ratio)."""
        w = 1.0 / self.table["noise"].to_numpy(float)[rows] ** 2
        total = w @ np.asarray(self.profiles[form])[rows]
        i = int(np.argmin(total))
        near = np.abs(self.grid - self.grid[i]) <= self.dt + 1e-12
        x, y = self.grid[near] - self.grid[i], total[near]
        if x.size >= 3:
            a2, a1, _ = np.polyfit(x, y, 2)
            if a2 > 0:
                shift = float(np.clip(-a1 / (2 * a2), x.min(), x.max()))
                dof = float(self.table["samples"].to_numpy(float)[rows].sum()) - 3 * rows.size - 1
                birge = math.sqrt(max(float(total[i]) / dof, 1.0)) if dof > 0 else math.inf
                return float(self.grid[i] + shift), birge * math.sqrt(1.0 / a2)
        return float(self.grid[i]), math.inf

    def _rows(self, direction: str) -> np.ndarray:
        """Positions in ``table`` of the uncensored edges of ``direction``."""
        keep = ~self.table["censored"].to_numpy(bool) & (
            self.table["direction"].to_numpy(str) == direction
        )
        return np.flatnonzero(keep)

    def form_p(self) -> float:
        """Wilcoxon signed-rank p-value of the edges' paired residuals, hold against transport,
        each form at its own common delays (:meth:`prior`'s).

        NaN with fewer than :data:`_MIN_EDGES` edges or no difference at all.
        """
        d = self._paired()
        d = d[np.isfinite(d) & (d != 0.0)]
        if d.size < _MIN_EDGES:
            return math.nan
        return float(wilcoxon(d).pvalue)

    def _paired(self) -> FloatArray:
        """Per uncensored edge, its squared residual in hold less that in transport, each at
        the form's common delay of the edge's direction (weighted by the run's noise)."""
        out = []
        for direction in ("on", "off"):
            rows = self._rows(direction)
            if rows.size < _MIN_EDGES:
                continue
            at = {}
            for form in _FORMS:
                d, _ = self._pooled(form, rows)
                at[form] = [
                    np.interp(d, self.grid, np.asarray(self.profiles[form])[j]) for j in rows
                ]
            noise2 = self.table["noise"].to_numpy(float)[rows] ** 2
            out.append((np.asarray(at["hold"]) - np.asarray(at["transport"])) / noise2)
        return np.concatenate(out) if out else np.zeros(0)

    def form(self) -> str:
        """The convention whose edge residuals are the smaller (median of the paired ones)."""
        d = self._paired()
        d = d[np.isfinite(d)]
        return "transport" if d.size and float(np.median(d)) > 0.0 else "hold"

    def prior(self, form: str) -> dict[str, tuple[float, float]] | None:
        """``{"t_on": (delay, se), "t_off": (delay, se)}``: each direction's common delay in
        ``form`` (:meth:`_pooled`, over its uncensored edges).

        The standard error is the larger of two: the pooled fit's, and over the runs (edges
        of one run share its setting, and a model error repeats at every edge of it) the
        standard deviation of the runs' own common delays over the square root of their
        number, with the runs of at least :data:`_MIN_EDGES` edges (three runs or more),
        scaled by Student's
        ``t(0.975, n - 1) / 1.96`` so that ``1.96 se`` is the t interval; and, in quadrature,
        the runs' spread beyond their own standard errors (``tau``, by moments, scaled
        alike): where the effective delay moves with the pulses (a valve's bounce, a tube's
        transit, a sensor's lag) runs of other settings show other delays, and the one
        delay that stands for them is the runs' random-effects mean (weights ``1/(se_r**2 +
        tau**2)``) and holds that spread (a random-effects prediction interval;
        on an unseen plant, the full session's and the verification's intervals were 0.1-0.2
        ms wide and 0.05-0.44 ms apart). At least a hundredth of the logging step. None when
        a direction has fewer than :data:`_MIN_EDGES` edges.
        """
        out = {}
        runs = self.table["run"].to_numpy(str)
        for name, direction in (("t_on", "on"), ("t_off", "off")):
            rows = self._rows(direction)
            if rows.size < _MIN_EDGES:
                return None
            value, se = self._pooled(form, rows)
            fits = [
                self._pooled(form, rows[runs[rows] == rid])
                for rid in np.unique(runs[rows])
                if np.sum(runs[rows] == rid) >= _MIN_EDGES
            ]
            per_run = [v for v, _ in fits]
            if len(per_run) >= 3:  # one or two runs' spread is no estimate of it
                # Student's t on the runs' few degrees of freedom, as a standard error that
                # the normal 95 % interval (1.96 se) reads right
                n = len(per_run)
                t_ratio = float(student_t.ppf(0.975, n - 1)) / 1.959964
                sd = float(np.std(per_run, ddof=1))
                se = max(se, t_ratio * sd / math.sqrt(n))
                # the runs' delays spread beyond their own errors where the effective delay
                # moves with the pulses (bounce, transit, a sensor's lag): one delay stands
                # for all of them, and its interval holds the spread a run of another
                # setting shows (a random-effects prediction interval; by moments)
                var = np.array([s * s for _, s in fits])
                ok = np.isfinite(var)
                tau2 = max(sd * sd - (float(np.mean(var[ok])) if ok.any() else 0.0), 0.0)
                if tau2 > 0.0 and ok.all():
                    # and its centre the runs' random-effects mean: the edges' pooled
                    # minimum weighs the runs by their edges and leans to one setting's
                    w = 1.0 / (var + tau2)
                    value = float(np.sum(w * np.asarray(per_run)) / np.sum(w))
                    se = max(se, t_ratio / math.sqrt(float(np.sum(w))))
                se = math.sqrt(se * se + t_ratio * t_ratio * tau2)
            out[name] = (value, max(se, 0.01 * self.dt))
        return out

    def record(self) -> dict[str, Any]:
        """``delay_convention.edges`` of ``params.yaml``: edges, form test and delays."""
        u = self.used()
        p = self.form_p()
        rec: dict[str, Any] = {
            "edges_on": int(np.sum(u["direction"] == "on")),
            "edges_off": int(np.sum(u["direction"] == "off")),
            "censored": int(self.table["censored"].sum()),
            "form": self.form(),
            "form_p": None if not math.isfinite(p) else float(f"{p:.3g}"),
            "level": FORM_LEVEL,
        }
        for form in _FORMS:
            pr = self.prior(form)
            if pr is not None:
                rec[form] = {n: {"value": v, "se": s} for n, (v, s) in pr.items()}
        return rec


def _frame(rows: Sequence[Mapping[str, Any]]) -> pd.DataFrame:
    """The edges' table, its numbers as floats even when it is empty."""
    table = pd.DataFrame(list(rows), columns=_COLUMNS)
    numeric = [c for c in _COLUMNS if c not in ("run", "direction", "censored")]
    table[numeric] = table[numeric].astype(float)
    table["censored"] = table["censored"].astype(bool)
    return table


@dataclass(frozen=True)
class _OldState:
    """The old state's closed form fitted to the samples before an edge (:func:`_old_state`):
    ``c + sc*basis(t)``, times from the edge."""

    c: float
    sc: float
    basis: Callable[[FloatArray], FloatArray]

    def __call__(
        self, t: FloatArray, c: float | None = None, sc: float | None = None
    ) -> FloatArray:
        """The pressure had the old state gone on, with ``c`` and ``sc`` replaced when given."""
        c = self.c if c is None else c
        sc = self.sc if sc is None else sc
        return c + sc * self.basis(np.asarray(t, float))


def _old_state(tw: FloatArray, pw: FloatArray, on: bool, prm: ValveParams) -> _OldState:
    """The old state's closed form through the samples ``(tw, pw)`` before an edge (times
    from the edge), its start and scale fitted: the pressure had the old state gone on.

    ``c + s*(C(t - tw[0]) - p_w)``, ``C`` the old state's closed form from ``p_w`` (the
    window's first sample, floored at 0), ``c`` and ``s`` by least squares; a line where the
    old state does not move (an empty actuator venting, a full one charging).
    """
    p_w = max(float(pw[0]), 0.0)
    t0 = float(tw[0])
    g = segment_pressure(not on, p_w, tw - t0, prm) - p_w
    if float(np.ptp(g)) < 1e-9:

        def basis(t: FloatArray) -> FloatArray:
            return t

    else:

        def basis(t: FloatArray) -> FloatArray:
            return segment_pressure(not on, p_w, t - t0, prm) - p_w

    x = np.column_stack([np.ones(tw.size), basis(tw)])
    coef, *_ = np.linalg.lstsq(x, pw, rcond=None)
    return _OldState(float(coef[0]), float(coef[1]), basis)


def _edge_fit(
    tw: FloatArray,
    pw: FloatArray,
    tt: FloatArray,
    pp: FloatArray,
    on: bool,
    old_state: _OldState,
    grid: FloatArray,
    prm: ValveParams,
) -> dict[str, Any]:
    """One edge's squared residual at each delay of ``grid``, in both forms, and the best.

    ``(tw, pw)`` are the samples before the edge and ``(tt, pp)`` those after it (times from
    the edge); ``old_state`` the old state's closed form fitted before it
    (:func:`_old_state`), whose shape (its basis) is kept. At each delay ``d`` the whole
    window is fitted by least squares in three coefficients: the old state's start ``c``
    and scale ``sc`` (``c + sc*basis(t)`` before the edge), and the new state's scale
    ``s``. Hold: the pressure stays at the old state's value at the edge until ``d``;
    transport: the old state goes on until ``d``. Then ``s`` times the new state's closed
    form's excursion from there (its shape from the old state's fit before the edge). The
    samples after the edge thus refit the old state too: an old state extrapolated from
    before the edge alone biases the delay (a too steep one meets the new state early).

    Returns ``profile_<form>`` (the squared residuals on the grid) and, at the best grid
    point (refined by a parabola), ``delay_<form>`` and ``sse_<form>``.
    """
    out: dict[str, Any] = {}
    y = np.concatenate([pw, pp])
    lag = tt[None, :] - grid[:, None]
    after = lag > 0
    n_pre, n_grid = tw.size, grid.size
    for form in _FORMS:
        knee = np.zeros(n_grid) if form == "hold" else grid
        p0 = np.maximum(old_state(knee), 0.0)  # an old state extrapolated below 0 bar
        g = np.where(after, segment_pressure(on, p0[:, None], lag, prm) - p0[:, None], 0.0)
        if form == "hold":  # at the old state's value at the edge, before and after ``d``
            b_post = np.full((n_grid, tt.size), float(old_state.basis(np.zeros(1))[0]))
        else:
            b_post = np.where(after, old_state.basis(knee)[:, None], old_state.basis(tt)[None, :])
        x = np.empty((n_grid, n_pre + tt.size, 3))
        x[:, :, 0] = 1.0
        x[:, :n_pre, 1] = old_state.basis(tw)[None, :]
        x[:, n_pre:, 1] = b_post
        x[:, :n_pre, 2] = 0.0
        x[:, n_pre:, 2] = g
        xtx = np.einsum("gni,gnj->gij", x, x)
        xty = np.einsum("gni,n->gi", x, y)
        ridge = 1e-12 * np.trace(xtx, axis1=1, axis2=2)[:, None, None] * np.eye(3)
        beta = np.linalg.solve(xtx + ridge, xty[:, :, None])[:, :, 0]
        sse = np.sum((y[None, :] - np.einsum("gni,gi->gn", x, beta)) ** 2, axis=1)
        i = int(np.argmin(sse))
        d = float(grid[i])
        if 0 < i < n_grid - 1:
            y0, y1, y2 = sse[i - 1], sse[i], sse[i + 1]
            den = y0 - 2 * y1 + y2
            if den > 0:
                d += 0.5 * (grid[1] - grid[0]) * (y0 - y2) / den
        out[f"profile_{form}"] = sse
        out[f"delay_{form}"] = d
        out[f"sse_{form}"] = float(sse[i])
    return out


def _profile_se(profile: FloatArray, grid: FloatArray, noise: float, dt: float) -> float:
    """Standard error of a delay from its squared-residual profile: ``sqrt(2/curvature)``
    of ``profile/noise²`` (a Gaussian likelihood's), the curvature of a parabola through the
    grid points within a logging step of the minimum; infinite where it is not a minimum."""
    i = int(np.argmin(profile))
    near = np.abs(grid - grid[i]) <= dt + 1e-12
    if near.sum() < 3:
        return math.inf
    a2 = float(np.polyfit(grid[near] - grid[i], profile[near] / noise**2, 2)[0])
    return math.sqrt(1.0 / a2) if a2 > 0 else math.inf


def _spaced(k: np.ndarray, n: int) -> np.ndarray:
    """At most ``n`` entries of ``k``, evenly spaced."""
    if k.size <= n:
        return k
    return k[np.unique(np.linspace(0, k.size - 1, n).round().astype(int))]


def _fit_edges(
    runs: Sequence[Any],
    tables: Mapping[str, pd.DataFrame],
    prm: ValveParams,
    max_delay: float,
    per_run: int,
    settled: Mapping[str, float],
    grid: FloatArray,
) -> list[dict[str, Any]]:
    """Fit the edges whose segments show them: ``settled[direction]`` is the delay after
    which the edge's own state acts (the window before an edge starts once the previous edge's
    state acts; the window after it holds that delay and ``_POST`` s more), each at the
    delays of ``grid``."""
    rows: list[dict[str, Any]] = []
    for r in runs:
        starts = np.asarray(r.command_starts, float)
        if starts.size < 2 or r.rid not in tables:
            continue
        t = tables[r.rid]["t"].to_numpy(float)
        p = tables[r.rid]["p"].to_numpy(float)
        t = t - t[0]
        dt = float(np.median(np.diff(t)))
        lev = np.asarray(r.level, bool)
        ends = np.append(starts[1:], t[-1])
        for direction, on in (("on", True), ("off", False)):
            own, other = settled[direction], settled["off" if on else "on"]
            prev_len = np.diff(starts)[lev[1:] == on]
            ks = np.flatnonzero(lev[1:] == on) + 1
            seg_len = ends[ks] - starts[ks]
            ok = (prev_len >= other + 3 * dt) & (seg_len >= own + _POST)
            for j in _spaced(ks[ok], per_run):
                e, nxt = starts[j], ends[j]
                pre = (t >= max(starts[j - 1] + other, e - _PRE)) & (t < e)
                post = (t >= e) & (t <= min(nxt, e + own + _POST))
                if pre.sum() < 3 or post.sum() < 3:
                    continue
                tw, pw = t[pre] - e, p[pre]
                old_state = _old_state(tw, pw, on, prm)
                a = float(old_state(np.zeros(1))[0])
                fit = _edge_fit(tw, pw, t[post] - e, p[post], on, old_state, grid, prm)
                se = max(_profile_se(fit[f"profile_{f}"], grid, float(r.noise), dt) for f in _FORMS)
                rows.append(
                    {
                        "run": r.rid,
                        "t": float(e),
                        "direction": direction,
                        "p_edge": a,
                        "noise": float(r.noise),
                        "samples": int(pre.sum() + post.sum()),
                        "censored": not se <= _RESOLVED * dt,
                        **fit,
                    }
                )
    return rows


def edge_delays(
    runs: Sequence[Any],
    tables: Mapping[str, pd.DataFrame],
    prm: ValveParams,
    *,
    max_delay: float = 0.05,
    per_run: int = _PER_RUN,
) -> EdgeDelays:
    """Fit every command edge of ``runs`` that shows its delay on its own, in the hold and
    transport forms.

    Parameters
    ----------
    runs : sequence of RefineRun
        From :func:`spa.identification.refine.prepare_runs`: each run's command
        (``command_starts``, the logged edges with their timing rule's shift, and ``level``)
        and its sensor ``noise``.
    tables : mapping
        Run id → its canonical table (``t``, ``p``): every sample, where the refinement's
        runs may be thinned.
    prm : ValveParams
        The closed forms' ``c1``, ``k2``, ``tau2`` (the charge and discharge fits'); the new
        state's excursion is scaled freely, so a valve whose own laws differ is still read.
    max_delay : float, optional
        Largest delay searched, s.
    per_run : int, optional
        Edges per direction and run at most (evenly spaced).

    Returns
    -------
    EdgeDelays

    Notes
    -----
    Per edge at ``e``: the old state's closed form through the samples before it, from the
    time the previous edge's state acts (at most 15 ms; :func:`_old_state`); then, for each
    delay ``d`` on a grid of a quarter logging step over ``[0, max_delay]``, the window after
    ``e`` is fitted with the pressure held at the old state's value at the edge (hold) or
    following the old state (transport) until ``e + d``, then the new state's closed form
    from there with a free scale. Each direction's delay is the one common to its edges: the
    minimum of their squared residuals summed over the edges (each weighted by its run's
    noise), not the median of each edge's own best delay, which a noisy edge biases (its own
    minimum is skewed by the free scale and the grid's bounds).

    Only edges whose segments show the delay are fitted: a modulated run's short pulses end
    before the new state has acted for long, and a free scale then fits any delay. A first
    pass takes the edges whose segment before is longer than ``max_delay`` and whose own
    segment is longer than ``max_delay + 30 ms``; a second pass replaces ``max_delay`` by
    each direction's delay from the first (in the form the first pass favours), so that
    shorter pulses count. An edge that cannot resolve its delay on its own is censored: its
    delay's standard error, with the old state's start and scale and the new state's scale
    fitted with it (:func:`_profile_se`), exceeds two logging steps (a vent from near 0 bar, a
    charge near the supply, a short segment before the edge).
    """
    steps = [
        float(np.median(np.diff(tables[r.rid]["t"].to_numpy(float))))
        for r in runs
        if r.rid in tables and len(tables[r.rid]) > 1
    ]
    dt = float(np.median(steps)) if steps else math.nan
    step = 0.25 * dt if steps else 1.0
    grid = np.arange(0.0, max_delay + 0.5 * step, step)

    def edges(settled: Mapping[str, float]) -> EdgeDelays:
        rows = _fit_edges(runs, tables, prm, max_delay, per_run, settled, grid)
        profiles = {
            f: np.array([r.pop(f"profile_{f}") for r in rows]).reshape(len(rows), grid.size)
            for f in _FORMS
        }
        return EdgeDelays(_frame(rows), dt, grid, profiles)

    rough = edges({"on": max_delay, "off": max_delay})
    pr = rough.prior(rough.form())
    if pr is None:
        return rough
    return edges({"on": pr["t_on"][0], "off": pr["t_off"][0]})


def edge_priors(at_edges: EdgeDelays) -> dict[str, dict[str, tuple[float, float]]]:
    """Convention → the delays its refinement holds: the edges' common delays in the edges'
    own form, when the form test resolves it (p below :data:`FORM_LEVEL`) and both delays
    are at least a logging step; none otherwise."""
    p = at_edges.form_p()
    if not (math.isfinite(p) and p < FORM_LEVEL):
        return {}
    form = at_edges.form()
    prior = at_edges.prior(form)
    if prior is None or min(v for v, _ in prior.values()) < at_edges.dt:
        # a delay under one logging step shows only in the first sample's amplitude, where
        # the sample's timing and the closed form's shape at the knee confound it: the cycle
        # means read it better (measured: 0.69 ms for 0.8 ms at a 2 ms step)
        return {}
    return {form: prior}


def edges_convention(
    by_fit: str,
    priors: Mapping[str, Any],
    setting: str,
    at_edges: EdgeDelays,
) -> tuple[str, str, list[str]]:
    """The convention, what chose it, and a warning when the edges overrule the held-out
    FIT: with ``setting`` auto and the edges' form resolved, the edges' form."""
    if setting != "auto":
        return by_fit, "identification.delay_convention", []
    if not priors:
        return by_fit, "held-out FIT", []
    form = next(iter(priors))
    if form == by_fit:
        return by_fit, "the command edges and held-out FIT", []
    p = at_edges.form_p()
    return (
        form,
        "the command edges",
        [
            f"the command edges show the {form} convention (Wilcoxon p = {p:.2g} over "
            f"{len(at_edges.used())} edges) where the cycle means' held-out FIT prefers "
            f"{by_fit}; the edges' form and delays are used"
        ],
    )
