"""Simultaneous bands of the identified laws, by a bootstrap over runs, and the pressures the
data visited in each mode (docs/model.md, "The general two-mode model").

The laws are identified from the runs that carry the valve command
(:func:`spa.identification.laws_fit.fit_laws`); how far they can be trusted is a property of
those runs, which are the independent units (the samples within a run are autocorrelated).
:func:`law_bands` resamples the runs with replacement, refits the laws on each resample by
one Gauss–Newton step from the full fit (the linearisation
:attr:`~spa.identification.laws_fit.LawsFit.heldout` uses), and turns the refitted rates on
a pressure grid into simultaneous 95 % bands of ``f_open(p)`` and ``f_closed(p)``: the band's
half-width in ``log|f|`` is ``c*s(p)``, ``s`` the bootstrap standard deviation at ``p`` and
``c`` the 95 % quantile of the largest studentised deviation over the grid points the data
visited in that mode (the sup-t calibration), so the whole curve lies inside with 95 %
probability, not each point alone. :func:`visited_pressures` gives those pressures.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from spa.identification.laws_fit import LawsFit, law_model
from spa.identification.refine import RefineRun
from spa.identification.results import FloatArray
from spa.model.laws import Laws
from spa.model.laws.rates import closed_rate, open_rate
from spa.model.params import ValveParams

__all__ = [
    "MODES",
    "LawBands",
    "band_envelope",
    "law_bands",
    "outside_visited_clause",
    "sup_t_quantile",
    "visited_pressures",
]

#: The two modes, in the record's order.
MODES: tuple[str, ...] = ("open", "closed")
_NOISE_FLOOR = 1e-6  # bar, as the laws' fit
_M_BOUNDS = (0.5, 1.0)
_LOG_BOUND = 6.0  # the laws' fit's bound of the log-rates


def visited_pressures(
    runs: Sequence[RefineRun], params: ValveParams, delay: str | None = None
) -> dict[str, tuple[float, float]]:
    """The lowest and highest measured pressure of the runs in each mode.

    Parameters
    ----------
    runs : sequence of RefineRun
        The runs with the command (:func:`spa.identification.refine.prepare_runs`).
    params : ValveParams
        The valve: its delays say when each command run's mode begins.
    delay : {"hold", "transport"}, optional
        ``params.delay`` when omitted.

    Returns
    -------
    dict
        ``{"open": (lo, hi), "closed": (lo, hi)}`` in bar (clipped at 0), over the samples
        that lie after their command run's delay (``t_on`` after a rising edge, ``t_off``
        after a falling one): under either convention the valve is then in the commanded
        mode. A mode no sample lies in gets ``(nan, nan)``.

    Examples
    --------
    >>> from spa.identification.refine import RefineRun
    >>> t = np.arange(6) * 0.1
    >>> run = RefineRun("r", "pulse", "", t, np.array([0, .1, .3, .4, .2, .1]),
    ...                 np.array([0.0, 0.25]), np.array([True, False]), 0.0, 1, 1,
    ...                 np.zeros(6), 0.0, 0.1, 0.0, 1, 1)
    >>> visited_pressures([run], ValveParams(t_on=0.0, t_off=0.0))
    {'open': (0.0, 0.3), 'closed': (0.1, 0.4)}
    """
    _ = params.delay if delay is None else delay  # both conventions: after the delay
    found: dict[bool, list[FloatArray]] = {True: [], False: []}
    for r in runs:
        hold = np.where(r.level, params.t_on, params.t_off)
        hold[0] = 0.0
        j = np.maximum(np.searchsorted(r.starts, r.t, side="right") - 1, 0)
        settled = r.t >= r.starts[j] + hold[j]
        mode = np.asarray(r.level, dtype=bool)[j]
        for state in (True, False):
            found[state].append(r.p[settled & (mode == state)])
    out = {}
    for name, state in zip(MODES, (True, False), strict=True):
        p = np.concatenate(found[state]) if found[state] else np.zeros(0)
        p = p[np.isfinite(p)]
        out[name] = (
            (max(float(p.min()), 0.0), max(float(p.max()), 0.0)) if p.size else (math.nan,) * 2
        )
    return out


def sup_t_quantile(
    deviations: FloatArray, spread: FloatArray, mask: FloatArray, level: float = 0.95
) -> float:
    """The sup-t critical value: the ``level`` quantile of ``max_p |d_b(p)|/s(p)``.

    Parameters
    ----------
    deviations : numpy.ndarray
        ``(draws, points)``: each draw's deviation from the estimate (NaN where undefined).
    spread : numpy.ndarray
        ``(points,)``: the draws' standard deviation at each point.
    mask : numpy.ndarray of bool
        ``(points,)``: the points the maximum runs over (all points when none is set).
    level : float, optional
        Simultaneous coverage.

    Returns
    -------
    float
        ``c`` such that ``|d_b(p)| <= c*s(p)`` at every masked point for a ``level`` share of
        the draws; NaN without a finite draw.

    Examples
    --------
    >>> d = np.array([[1.0, -2.0], [0.5, 0.5], [-3.0, 1.0]])
    >>> float(sup_t_quantile(d, np.ones(2), np.array([True, True]), level=0.5))
    2.0
    """
    use = np.asarray(mask, dtype=bool)
    if not use.any():
        use = np.ones(spread.shape, dtype=bool)
    use = use & np.isfinite(spread) & (spread > 0)
    if not use.any():
        return math.nan
    with np.errstate(invalid="ignore"):
        t = np.abs(deviations[:, use]) / spread[use]
    t = np.where(np.isfinite(t), t, np.nan)
    worst = np.nanmax(np.where(np.isnan(t), -np.inf, t), axis=1)
    worst = worst[np.isfinite(worst)]
    return float(np.quantile(worst, level)) if worst.size else math.nan


@dataclass(frozen=True)
class LawBands:
    """Simultaneous bands of ``f_open`` and ``f_closed`` on a pressure grid.

    Attributes
    ----------
    grid : numpy.ndarray
        Pressures, bar.
    rate : dict
        Mode → the identified law's rate on the grid, bar/s (``f_open > 0``,
        ``f_closed < 0``).
    lo, hi : dict
        Mode → the band's lower and upper edge on the grid, bar/s (NaN where the rate is 0
        in some draw: at and beyond ``k2`` when charging).
    critical : dict
        Mode → the sup-t critical value ``c``.
    visited : dict
        Mode → the pressures the data visited in it, ``(lo, hi)`` in bar.
    level : float
        Simultaneous coverage.
    draws : int
        Bootstrap resamples.
    """

    grid: FloatArray
    rate: Mapping[str, FloatArray]
    lo: Mapping[str, FloatArray]
    hi: Mapping[str, FloatArray]
    critical: Mapping[str, float]
    visited: Mapping[str, tuple[float, float]]
    level: float
    draws: int

    def envelope(self) -> dict[str, float]:
        """Mode → ``delta``: the band's largest relative half-width over the visited range,
        as ``log(1 + delta)``: the band lies within ``f*exp(±log(1 + delta))`` there
        (:func:`band_envelope`)."""
        return band_envelope(self.to_dict())

    def visited_dict(self) -> dict[str, list[float | None]]:
        """The ``laws: visited:`` record: mode → ``[lo, hi]`` in bar (null: not visited)."""
        return {m: [float(v) if math.isfinite(v) else None for v in self.visited[m]] for m in MODES}

    def to_dict(self) -> dict[str, Any]:
        """The ``laws: bands:`` record of ``params.yaml`` (NaN written as null)."""

        def lst(x: FloatArray) -> list[float | None]:
            return [float(f"{v:.6g}") if math.isfinite(v) else None for v in np.asarray(x)]

        return {
            "level": float(self.level),
            "draws": int(self.draws),
            "grid": lst(self.grid),
            **{
                m: {
                    "rate": lst(self.rate[m]),
                    "lo": lst(self.lo[m]),
                    "hi": lst(self.hi[m]),
                    "critical": float(f"{self.critical[m]:.6g}")
                    if math.isfinite(self.critical[m])
                    else None,
                }
                for m in MODES
            },
        }


#: Share of ``k2`` next to each law's zero left out of the envelope: the charge's above
#: ``(1 - NEAR_ZERO)*k2`` and the discharge's below ``NEAR_ZERO*k2``, where the rate and its
#: band both go to 0 and their ratio says nothing the stages use (the levels there are the
#: dead zone and the saturation, which no stage regulates).
NEAR_ZERO = 0.1


def band_envelope(
    bands: Mapping[str, Any],
    visited: Mapping[str, Any] | None = None,
    k2: float | None = None,
    near_zero: float = NEAR_ZERO,
) -> dict:
    """Mode → ``delta``, the bands' largest relative half-width over the visited pressures.

    Parameters
    ----------
    bands : mapping
        ``params.yaml``'s ``laws: bands:`` (:meth:`LawBands.to_dict`).
    visited : mapping, optional
        ``laws: visited:`` (mode → ``[lo, hi]``, bar); the whole grid when absent.
    k2 : float, optional
        The laws' supply (bar): with it, the pressures within ``near_zero*k2`` of each law's
        zero are left out (:data:`NEAR_ZERO`); without it, none.
    near_zero : float, optional
        That share of ``k2``, in [0, 0.5).

    Returns
    -------
    dict
        ``{"open": delta, "closed": delta}`` with ``log(1 + delta)`` the largest of
        ``|log(edge/rate)|`` over both edges and the visited grid points kept: every such
        point of the band lies within ``rate*(1 + delta)**(±1)``. NaN for a mode without a
        finite band point.

    Examples
    --------
    >>> b = {"grid": [0.1, 0.2, 0.3], "open": {"rate": [2, 1, 1], "lo": [1, .8, .5],
    ...      "hi": [4, 1.25, 2]}, "closed": {"rate": [-1, -1, -1], "lo": [-1.1, -1.1, -1.1],
    ...      "hi": [-.9, -.9, -.9]}}
    >>> {k: round(v, 3) for k, v in band_envelope(b, {"open": [0.15, 0.25]}).items()}
    {'open': 0.25, 'closed': 0.111}
    >>> round(band_envelope(b, k2=0.3, near_zero=0.2)["open"], 3)  # 0.3 is next to k2
    1.0
    """
    grid = np.asarray(bands["grid"], dtype=np.float64)
    if not 0.0 <= near_zero < 0.5:
        raise ValueError(f"near_zero must be in [0, 0.5), got {near_zero!r}")
    kept = {m: np.ones(grid.shape, dtype=bool) for m in MODES}
    if k2 is not None and math.isfinite(k2) and k2 > 0.0:
        kept = {"open": grid <= (1.0 - near_zero) * k2, "closed": grid >= near_zero * k2}
    out = {}
    for mode in MODES:
        rec = bands[mode]
        rate, lo, hi = (np.asarray(rec[k], dtype=np.float64) for k in ("rate", "lo", "hi"))
        span = (visited or {}).get(mode)
        use = np.ones(grid.shape, dtype=bool)
        if span is not None and all(v is not None and math.isfinite(v) for v in span):
            inside = (grid >= span[0]) & (grid <= span[1])
            if inside.any():
                use = inside
        if (use & kept[mode]).any():
            use = use & kept[mode]
        with np.errstate(invalid="ignore", divide="ignore"):
            dev = np.maximum(np.abs(np.log(lo / rate)), np.abs(np.log(hi / rate)))
        dev = dev[use & np.isfinite(dev)]
        out[mode] = float(math.expm1(dev.max())) if dev.size else math.nan
    return out


def _vector_valve(start: ValveParams, x: FloatArray, knots: tuple[float, ...]) -> ValveParams:
    """``start`` with the laws, ``k2`` and delays of a fit vector (:func:`law_names` order)."""
    n = len(knots)
    im = 2 * n
    laws = Laws(log_g=tuple(x[:n]), log_h=tuple(x[n:im]), m=float(x[im]), knots=knots)
    return dataclasses.replace(
        start, k2=math.exp(x[im + 1]), t_on=float(x[im + 2]), t_off=float(x[im + 3]), laws=laws
    )


def _run_terms(
    runs: Sequence[RefineRun], fit: LawsFit, delay: str, step: float = 1e-3
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Per-run Gauss–Newton terms at the full fit: ``H_r = J_r'J_r``, ``g_r = J_r'e_r``,
    with each run's residuals weighted by ``1/RMS`` of its own residuals (at least the noise
    of a block mean), by forward differences over the free entries of the fit vector."""
    kn = fit.laws.knots
    free = np.array([i for i, n in enumerate(fit.names) if n not in fit.fixed])
    im = 2 * len(kn)
    hi = np.full(fit.x.size, _LOG_BOUND)
    hi[im] = _M_BOUNDS[1]
    hi[im + 1] = np.inf
    hi[im + 2 :] = np.inf
    base = [law_model(r, _vector_valve(fit.start, fit.x, kn), delay) for r in runs]
    resid = [mo - r.y for mo, r in zip(base, runs, strict=True)]
    weight = np.array(
        [
            1.0 / max(float(np.sqrt(np.mean(e**2))), r.noise / math.sqrt(r.block), _NOISE_FLOOR)
            for e, r in zip(resid, runs, strict=True)
        ]
    )
    cols: list[list[FloatArray]] = [[] for _ in runs]
    for i in free:
        h = (1e-4 if i >= im + 2 else step) * (-1.0 if fit.x[i] + step > hi[i] else 1.0)
        xs = fit.x.copy()
        xs[i] += h
        prm = _vector_valve(fit.start, xs, kn)
        for j, r in enumerate(runs):
            cols[j].append((law_model(r, prm, delay) - base[j]) * weight[j] / h)
    hess = np.stack([np.column_stack(c).T @ np.column_stack(c) for c in cols])
    grad = np.stack(
        [np.column_stack(c).T @ (e * w) for c, e, w in zip(cols, resid, weight, strict=True)]
    )
    return hess, grad, free


def law_bands(
    runs: Sequence[RefineRun],
    fit: LawsFit,
    *,
    delay: str | None = None,
    draws: int = 400,
    level: float = 0.95,
    points: int = 41,
    seed: int = 0,
) -> LawBands:
    """Simultaneous bands of the fitted laws by a bootstrap over the runs.

    Parameters
    ----------
    runs : sequence of RefineRun
        The runs the laws were fitted to (:func:`~spa.identification.laws_fit.fit_laws`).
    fit : LawsFit
        The fit on all of them.
    delay : {"hold", "transport"}, optional
        ``fit.params.delay`` when omitted.
    draws : int, optional
        Bootstrap resamples.
    level : float, optional
        Simultaneous coverage of each mode's band.
    points : int, optional
        Grid points, evenly spaced over ``(0, k2)`` without its ends (where a law's rate is
        0 and its relative error undefined).
    seed : int, optional
        Seed of the resampling: the bands are deterministic.

    Returns
    -------
    LawBands

    Raises
    ------
    ValueError
        If ``runs`` is empty, ``draws < 20``, ``points < 3`` or ``level`` is not in (0, 1).

    Notes
    -----
    Each resample weighs the ``n`` runs by ``w = n*Dirichlet(1, ..., 1)`` (the Bayesian
    bootstrap over runs: the weights of a resample with replacement, made continuous) and
    moves the fit vector by one Gauss–Newton step,
    ``x_b = x - (sum_r w_r H_r)^+ (sum_r w_r g_r - sum_r g_r)``, with ``H_r`` and ``g_r`` the
    run's terms at the full fit, scaled by ``sqrt((n + 1)/(n - 1))``; the score is recentred
    (``- sum_r g_r``) so that a fit held at a bound or stopped before the optimum is not
    read as a bias. Its cost is one
    Jacobian (one simulation of every run per free coefficient); the resamples are linear
    algebra. Draws are clipped to the fit's bounds.

    Resampling with replacement (integer multiplicities) leaves a given run out of a third
    of the resamples (``(1 - 1/n)**n``); with the one discharge run among nine of the
    0.6 bar balloon left out, the exhaust law is not identified and a one-step refit runs
    away (2.5 % quantile of the ``log_h[0]`` step: -31, its sandwich standard error
    0.47). The continuous weights keep every run in and give standard deviations that match
    the sandwich's (``log_h[0]``: 0.40 against 0.47; ``m``: 0.12 against 0.14).

    The Dirichlet weights' variance of a mean over ``n`` runs is ``(n - 1)/(n + 1)`` of its
    unbiased estimate (a resample with replacement's, ``(n - 1)/n``): with the six to ten
    runs of a dataset the bands would be 10–20 % too narrow, hence the scale factor. On a
    bench made with known laws (six runs) the unscaled bands missed the true ``f_open`` on
    3 of 6 seeds, each time by 3–6 % of the band's half-width.
    """
    if not runs:
        raise ValueError("law_bands needs the runs the laws were fitted to; got none")
    if draws < 20 or points < 3 or not 0.0 < level < 1.0:
        raise ValueError(
            f"law_bands: draws must be >= 20, points >= 3 and level in (0, 1); got draws="
            f"{draws}, points={points}, level={level}"
        )
    dl = fit.params.delay if delay is None else delay
    kn = fit.laws.knots
    im = 2 * len(kn)
    hess, grad, free = _run_terms(runs, fit, dl)
    rng = np.random.default_rng(seed)
    n = len(runs)
    w = n * rng.dirichlet(np.ones(n), size=draws)
    hb = np.einsum("br,rij->bij", w, hess)
    gb = w @ grad - grad.sum(axis=0)
    inflate = math.sqrt((n + 1) / (n - 1)) if n > 1 else 1.0
    step = inflate * np.einsum("bij,bj->bi", np.linalg.pinv(hb, rcond=1e-10), gb)
    x = np.tile(fit.x, (draws, 1))
    x[:, free] -= step
    x[:, :im] = np.clip(x[:, :im], -_LOG_BOUND, _LOG_BOUND)
    x[:, im] = np.clip(x[:, im], *_M_BOUNDS)
    x[:, im + 2 :] = np.maximum(x[:, im + 2 :], 0.0)
    prm = _vector_valve(fit.start, fit.x, kn)
    grid = np.linspace(0.0, prm.k2, points + 2)[1:-1]
    visited = visited_pressures(runs, prm, dl)
    rate = {"open": open_rate(grid, prm), "closed": closed_rate(grid, prm)}
    curves = {m: np.empty((draws, grid.size)) for m in MODES}
    for b in range(draws):  # one valve per resample, each curve vectorised over the grid
        vb = _vector_valve(fit.start, x[b], kn)
        curves["open"][b] = open_rate(grid, vb)
        curves["closed"][b] = closed_rate(grid, vb)
    lo, hi, crit = {}, {}, {}
    for mode in MODES:
        sign = 1.0 if mode == "open" else -1.0
        with np.errstate(invalid="ignore", divide="ignore"):
            dev = np.log(sign * curves[mode]) - np.log(sign * rate[mode])
        dev[~np.isfinite(dev)] = np.nan
        defined = np.all(np.isfinite(dev), axis=0)
        spread = np.where(defined, np.nanstd(np.where(defined, dev, 0.0), axis=0), np.nan)
        a, b = visited[mode]
        mask = defined & (grid >= a) & (grid <= b) if math.isfinite(a) else defined
        c = sup_t_quantile(dev, spread, mask, level)
        crit[mode] = c
        edges = rate[mode] * np.exp(np.outer((-1.0, 1.0), c * spread))
        lo[mode] = np.where(defined, np.min(edges, axis=0), np.nan)
        hi[mode] = np.where(defined, np.max(edges, axis=0), np.nan)
    return LawBands(grid, rate, lo, hi, crit, visited, level, draws)


def outside_visited_clause(
    pressures: Sequence[float], visited: Mapping[str, Any] | None, use: str
) -> str:
    """A clause naming the pressures of a use that lie outside those the laws were seen at.

    A pressure held by modulation alternates both modes around it, so it is supported by the
    data when it lies within the pressures visited with the valve open and with it closed.

    Parameters
    ----------
    pressures : sequence of float
        The use's pressures, bar (a recommendation's levels, a loop's set-points).
    visited : mapping or None
        ``params.yaml``'s ``laws: visited:`` (mode → ``[lo, hi]``); None or empty: no laws
        were identified and nothing is said.
    use : str
        What the pressures are, for the sentence ("the recommended setting's levels").

    Returns
    -------
    str
        ``""`` when every pressure lies inside (or nothing is known), else a sentence.

    Examples
    --------
    >>> v = {"open": [0.0, 0.55], "closed": [0.02, 0.6]}
    >>> outside_visited_clause([0.1, 0.3], v, "the set-points")
    ''
    >>> outside_visited_clause([0.01, 0.3, 0.58], v, "the set-points")[:73]
    'The set-points at 0.01 and 0.58 bar lie outside the pressures the identif'
    """
    if not visited:
        return ""
    spans = []
    for mode in MODES:
        span = visited.get(mode) or (None, None)
        if any(v is None or not math.isfinite(float(v)) for v in span):
            return ""
        spans.append((float(span[0]), float(span[1])))
    lo, hi = max(a for a, _ in spans), min(b for _, b in spans)
    out = [float(p) for p in pressures if math.isfinite(float(p)) and not lo <= p <= hi]
    if not out:
        return ""
    words = [f"{p:.3g}" for p in out]
    said = words[0] if len(words) == 1 else ", ".join(words[:-1]) + " and " + words[-1]
    return (
        f"{use[:1].upper()}{use[1:]} at {said} bar lie outside the pressures the "
        f"identification's runs visited in both valve modes ({lo:.3g}–{hi:.3g} bar): there "
        "the actuator's laws are extrapolated, not measured."
    )
