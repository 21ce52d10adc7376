"""Whether the pressure's rate depends on history: a second state, told from wrong laws.

A single-state two-mode plant has ``dp/dt = f_open(p)`` or ``f_closed(p)``: in a given mode,
the rate at a given pressure does not depend on when the valve last switched. A second state
(the gas's temperature relaxing to the wall's, a wall creeping after each change, a supply
hose's own pressure) makes it depend on the time since the last edge: just after an edge the
gas is hot or cold, the wall still moving. Laws other than the plant's make the rate's error
a function of the pressure in each mode, which richer laws absorb.

:func:`history_test` therefore regresses the derivative residuals ``dp/dt - f_mode(p)`` of
the chosen model (on a smoothed signal) on a flexible basis in the pressure per mode, and
tests whether a basis in the time since the last edge per mode explains them beyond it
(nested regression, a Wald test with a covariance robust to the residuals' correlation
within blocks of time). Only that test names a second state; Ljung's test of the closed
forms (:func:`spa.identification.diagnostics.whiteness`) cannot tell the two apart.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from functools import lru_cache
from typing import Any, Protocol

import numpy as np
import numpy.typing as npt
import pandas as pd
from scipy.signal import savgol_coeffs
from scipy.special import fdtrc

from spa.model.laws.rates import closed_rate, open_rate
from spa.model.params import ValveParams

__all__ = [
    "HistoryTest",
    "Record",
    "derivative_residuals",
    "edge_history",
    "full_rate_records",
    "history_test",
    "nested_wald",
]

FloatArray = npt.NDArray[np.float64]

#: Time constants of the history basis, s: exp(-s/tau) per mode (a thermal state or a
#: creeping wall relaxes in 0.3-5 s).
TAUS = (0.1, 0.3, 1.0, 3.0)

#: Time constants of the fast transients taken as known nuisances, s: a sensor's lag or
#: ringing, a tube, a regulator's recovery, a valve's bounce (tens of ms).
FAST = (0.03,)


class CommandRun(Protocol):
    """What the test reads of a run: a :class:`Record`, or a
    :class:`spa.identification.refine.RefineRun` that is not thinned (``stride`` 1)."""

    rid: str
    t: FloatArray
    p: FloatArray
    level: np.ndarray

    @property
    def command_starts(self) -> FloatArray: ...  # pragma: no cover


@dataclass(frozen=True)
class Record:
    """A stretch of a run at the log's full rate, with its run's command.

    Attributes
    ----------
    rid : str
        The run's id.
    t, p : numpy.ndarray
        Times from the run's first sample (s) and pressure (bar) of the stretch.
    command_starts, level : numpy.ndarray
        The run's command runs: start times (s, on the same clock) and levels.
    """

    rid: str
    t: FloatArray
    p: FloatArray
    command_starts: FloatArray
    level: np.ndarray


def full_rate_records(
    tables: Mapping[str, pd.DataFrame],
    prepared: Sequence[Any],
    budget: int = 40_000,
    stretch: float = 1.0,
) -> list[Record]:
    """Stretches of each run with the valve command at the log's full rate, within a budget.

    The refinement thins long runs (every ``stride``-th sample), which a derivative cannot
    use: here each run keeps evenly spaced stretches of at most ``stretch`` s at its full
    rate (at least four, the first at its start, the last at its end), ``budget / runs``
    samples each (at least 400, at most the run).

    Parameters
    ----------
    tables : mapping
        Run id → the run's table (``t``, ``p``).
    prepared : sequence of RefineRun
        The runs with the valve command (:func:`spa.identification.refine.prepare_runs`):
        their command runs.
    budget : int, optional
        Samples over all runs.
    stretch : float, optional
        Length of each stretch, s.

    Returns
    -------
    list of Record
    """
    out: list[Record] = []
    if not prepared:
        return out
    per = max(400, budget // len(prepared))
    for run in prepared:
        table = tables[run.rid]
        t = table["t"].to_numpy(dtype=np.float64)
        p = table["p"].to_numpy(dtype=np.float64)
        t = t - t[0]
        n = t.size
        if n <= per:
            out.append(Record(run.rid, t, p, run.command_starts, run.level))
            continue
        dt = float(np.median(np.diff(t)))
        size = max(100, min(round(stretch / dt), per // 4))
        count = max(2, per // size)
        for a in np.unique(np.linspace(0, n - size, count).round().astype(np.int64)):
            sl = slice(int(a), int(a) + size)
            out.append(Record(run.rid, t[sl], p[sl], run.command_starts, run.level))
    return out


@dataclass(frozen=True)
class HistoryTest:
    """The nested test of a history term beyond a pressure term.

    Attributes
    ----------
    samples : int
        Samples used (away from the edges' dead times and the smoothing's reach).
    blocks : int
        Blocks of time the covariance treats as independent.
    p_history : float
        p-value of the history term (the time since the last edge, per mode) beyond the
        pressure term.
    p_pressure : float
        p-value of the pressure term (per mode) against none: the rates differ from the
        chosen laws as a function of pressure.
    history_share : float
        RMS of what the history term adds to the fit on the pressure term, over the RMS of
        the model's rate (the size of the second state's signature, 0..).
    pressure_share : float
        RMS of the pressure term's fit, over the RMS of the model's rate.
    second_state : bool
        The history term is significant at ``alpha`` and at least ``min_share`` of the rate.
    pressure_laws : bool
        The pressure term is, and the history term is not.
    alpha, min_share : float
        The test's level and smallest share.
    """

    samples: int
    blocks: int
    p_history: float
    p_pressure: float
    history_share: float
    pressure_share: float
    second_state: bool
    pressure_laws: bool
    alpha: float
    min_share: float

    def to_dict(self) -> dict[str, Any]:
        """Plain types for ``params.yaml``."""

        def num(x: float) -> float | None:
            return float(f"{x:.4g}") if math.isfinite(x) else None

        return {
            "samples": int(self.samples),
            "blocks": int(self.blocks),
            "p_history": num(self.p_history),
            "p_pressure": num(self.p_pressure),
            "history_share": num(self.history_share),
            "pressure_share": num(self.pressure_share),
            "second_state": bool(self.second_state),
            "pressure_laws": bool(self.pressure_laws),
            "alpha": float(self.alpha),
            "min_share": float(self.min_share),
        }

    def sentence(self, suggest_laws: bool) -> str:
        """What the test says, or ``""`` when it says nothing: a second state; or, with
        ``suggest_laws`` (the paper's laws kept untried), rates that depend on the pressure
        otherwise than they do."""
        if self.second_state:
            return (
                "the pressure's rate depends on the time since the last valve edge beyond "
                f"any law of the pressure (history term p = {self.p_history:.2g}, "
                f"{100 * self.history_share:.1f} % of the rate): the plant has a second "
                "state, such as heat exchange with the wall, a creeping wall, a lagging "
                "sensor or line, or a supply hose's own pressure, which no choice of laws "
                "describes"
            )
        if self.pressure_laws and suggest_laws:
            return (
                "the rates depend on the pressure otherwise than the paper's laws (pressure "
                f"term p = {self.p_pressure:.2g}, {100 * self.pressure_share:.1f} % of the "
                "rate), and not on the time since the last edge: identification.laws: auto "
                "fits the actuator's own laws"
            )
        return ""


def edge_history(
    t: FloatArray,
    starts: FloatArray,
    level: np.ndarray,
    t_on: float,
    t_off: float,
    reach: float,
    dead: float = 0.0,
) -> tuple[np.ndarray, FloatArray, np.ndarray]:
    """Each sample's mode, the time since its mode began, and whether it is usable.

    Parameters
    ----------
    t : numpy.ndarray
        Sample times, s.
    starts, level : numpy.ndarray
        The command's runs: start times (s; the first is the run's start, taken as an edge)
        and levels.
    t_on, t_off : float
        The valve's delays, s: a mode begins ``t_on`` after a rising edge, ``t_off`` after
        a falling one.
    reach : float
        Half the smoothing window plus a guard, s: samples closer than this to a mode's
        change (either side), or inside an edge's delay, are not used.
    dead : float, optional
        The longest dead time to clear after any edge, s (the model's delays may be shorter
        than the plant's): samples within ``dead + reach`` of a command edge are not used.

    Returns
    -------
    on : numpy.ndarray of bool
        The sample's mode (the level of the last edge).
    since : numpy.ndarray
        Time since that edge's mode began, s.
    usable : numpy.ndarray of bool
        Away from every change of mode by more than ``reach``.
    """
    starts = np.asarray(starts, dtype=np.float64)
    lv = np.asarray(level, dtype=bool)
    delay = np.where(lv, t_on, t_off)
    change = starts + delay
    k = np.clip(np.searchsorted(starts, t, side="right") - 1, 0, starts.size - 1)
    on = lv[k]
    since = t - change[k]
    nxt = np.append(change[1:], np.inf)[k]
    usable = (since > reach) & (nxt - t > reach) & (t - starts[k] > dead + reach)
    return on, since, usable


def derivative_residuals(
    t: FloatArray, p: FloatArray, params: ValveParams, on: np.ndarray, window: float
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """``dp/dt - f_mode(p)`` on the smoothed pressure (Savitzky-Golay, quadratic).

    Parameters
    ----------
    t, p : numpy.ndarray
        Sample times (s, near uniform) and pressure (bar).
    params : ValveParams
        The chosen model (its laws, or the paper's when ``laws`` is None).
    on : numpy.ndarray of bool
        Each sample's mode.
    window : float
        Smoothing window, s (at least 5 samples).

    Returns
    -------
    residual, rate, ps : numpy.ndarray
        The residual and the model's rate (bar/s), and the smoothed pressure (bar); within
        half a window of either end they lean on the end sample (not to be used).
    """
    dt = float(np.median(np.diff(t)))
    ps, dp = _smooth(p, dt, window)
    rate = _rates(ps, on, params)
    return dp - rate, rate, ps


def _rates(p: FloatArray, on: np.ndarray, params: ValveParams) -> FloatArray:
    """The model's rate in each sample's mode, bar/s."""
    return np.where(on, open_rate(p, params), closed_rate(p, params))


@lru_cache(maxsize=32)
def _kernels(n: int, dt: float) -> tuple[FloatArray, FloatArray]:
    """Savitzky-Golay (quadratic) kernels of the value and the derivative, ``n`` samples."""
    return savgol_coeffs(n, 2, use="dot"), savgol_coeffs(n, 2, deriv=1, delta=dt, use="dot")


def _smooth(p: FloatArray, dt: float, window: float) -> tuple[FloatArray, FloatArray]:
    """The smoothed pressure and its derivative (edges padded with the end samples)."""
    n = max(5, 2 * round(window / dt / 2) + 1)
    n = min(n, p.size - (1 - p.size % 2))
    value, slope = _kernels(n, round(dt, 12))
    h = n // 2
    padded = np.concatenate((np.full(h, p[0]), p, np.full(h, p[-1])))
    frames = np.lib.stride_tricks.sliding_window_view(padded, n)
    return frames @ value, frames @ slope


def _hats(x: FloatArray, knots: FloatArray) -> FloatArray:
    """Piecewise-linear hat functions on ``knots`` (a partition of unity over their span)."""
    x = np.clip(x, knots[0], knots[-1])
    out = np.zeros((x.size, knots.size))
    j = np.clip(np.searchsorted(knots, x, side="right") - 1, 0, knots.size - 2)
    w = (x - knots[j]) / (knots[j + 1] - knots[j])
    rows = np.arange(x.size)
    out[rows, j] = 1.0 - w
    out[rows, j + 1] += w
    return out


def _pressure_basis(p: FloatArray, on: np.ndarray, knots: int) -> FloatArray:
    """Hat functions of the pressure per mode, on ``knots`` knots at the mode's quantiles
    and as many evenly spaced over its range (so that a range the runs seldom visit is not
    left to one hat)."""
    cols = []
    for mode in (True, False):
        sel = on == mode
        if not sel.any():
            continue
        x = p[sel]
        lo, hi = float(x.min()), float(x.max())
        q = np.concatenate([np.quantile(x, np.linspace(0.0, 1.0, knots)),
                            np.linspace(lo, hi, knots)])  # fmt: skip
        q = np.unique(q)
        q = q[np.concatenate(([True], np.diff(q) > 1e-3 * (hi - lo)))]
        if q.size < 2:
            cols.append(sel[:, None].astype(np.float64))
            continue
        cols.append(_hats(p, q) * sel[:, None])
    return np.hstack(cols)


def _orthonormal(x: FloatArray, norms: FloatArray | None = None) -> FloatArray:
    """An orthonormal basis of the span of ``x``'s columns, less the directions whose
    singular value is below 1e-5 of the largest column's norm (or of ``norms``'s): nearly
    collinear columns are merged, not inverted. From the scaled Gram matrix (a small
    eigenproblem), two passes so that the basis is orthonormal to rounding."""
    if x.shape[1] == 0:
        return x
    size = np.sqrt(np.sum(x * x, axis=0)) if norms is None else np.asarray(norms)
    top = float(np.max(size)) if size.size else 0.0
    if top <= 0.0:
        return x[:, :0]
    q = x
    for _ in range(2):
        w, v = np.linalg.eigh(q.T @ q)
        good = w > (1e-5 * top) ** 2
        q = q @ (v[:, good] / np.sqrt(w[good]))
        top = 1.0
    return q


def nested_wald(
    y: FloatArray, base: FloatArray, extra: FloatArray, blocks: np.ndarray
) -> tuple[float, FloatArray]:
    """p-value of ``extra``'s columns beyond ``base``'s, robust to correlation in blocks.

    Least squares of ``y`` on ``[base, extra]``; the Wald statistic of ``extra``'s
    coefficients with the cluster-robust (block) sandwich covariance, referred to
    ``F(q, G - 1)`` (``q`` estimable columns, ``G`` blocks). It is computed on ``extra``
    made orthogonal to ``base`` (the same statistic, by the Frisch-Waugh-Lovell theorem),
    so that nearly collinear columns are dropped rather than inverted.

    Parameters
    ----------
    y : numpy.ndarray
        The response, one per sample.
    base, extra : numpy.ndarray
        Design columns (samples x k); ``base`` may have no columns.
    blocks : numpy.ndarray of int
        Each sample's block, non-decreasing from 0 to G-1: residuals are taken as
        independent between blocks only.

    Returns
    -------
    p_value : float
        1 when ``extra`` adds nothing estimable (or there are too few blocks).
    gain : numpy.ndarray
        What ``extra`` adds to the fit (the full fit less the fit on ``base`` alone), one
        per sample.

    Examples
    --------
    >>> rng = np.random.default_rng(0)
    >>> x = rng.normal(size=(2000, 1)); b = np.arange(2000) // 20
    >>> nested_wald(0.3 * x[:, 0] + rng.normal(size=2000), np.ones((2000, 1)), x, b)[0] < 1e-6
    True
    """
    qb = _orthonormal(base)
    rest = extra - qb @ (qb.T @ extra)
    qe = _orthonormal(rest, np.sqrt(np.sum(extra * extra, axis=0)))
    z = qe.T @ y
    gain = qe @ z
    e = y - qb @ (qb.T @ y) - gain
    g = int(blocks[-1]) + 1 if blocks.size else 0
    if qe.shape[1] == 0 or g <= qe.shape[1] + 1:
        return 1.0, gain
    # blocks are contiguous runs of samples: the scores summed per block
    first = np.flatnonzero(np.diff(blocks, prepend=-1))
    scores = np.add.reduceat(qe * e[:, None], first, axis=0)
    cov = scores.T @ scores * (g / (g - 1))
    w, v = np.linalg.eigh(cov)
    good = w > w.max() * 1e-10
    if not good.any():
        return 1.0, gain
    c = v[:, good].T @ z
    stat = float(np.sum(c * c / w[good]))
    r = int(good.sum())
    return float(fdtrc(r, g - 1, stat / r)), gain


def history_test(
    runs: Sequence[CommandRun],
    params: ValveParams,
    *,
    window: float = 0.02,
    guard: float = 0.01,
    dead_time: float = 0.03,
    block: float = 0.25,
    knots: int = 8,
    floor: float = 0.03,
    taus: Sequence[float] = TAUS,
    fast: Sequence[float] = FAST,
    alpha: float = 0.01,
    min_share: float = 0.02,
) -> HistoryTest | None:
    """Whether the rate depends on the time since the last valve edge beyond the pressure.

    Parameters
    ----------
    runs : sequence
        Runs with the valve command at the log's full rate (:func:`full_rate_records` of
        :func:`spa.identification.refine.prepare_runs`), in order.
    params : ValveParams
        The chosen model: its delays, and its laws (the paper's when ``laws`` is None).
    window : float, optional
        Smoothing window of the derivative, s.
    guard : float, optional
        Time kept clear of a mode's change beyond half the window, s (the spool's transit,
        a bounce, the sensor's lag).
    dead_time : float, optional
        Samples closer to a command edge than the longest of this, ``t_on`` and ``t_off``
        (plus half the window and the guard) are not used, s: a dead time the model got
        wrong would otherwise show as history.
    block : float, optional
        Length of the blocks of time taken as independent, s.
    knots : int, optional
        Knots of the pressure basis per mode at its quantiles (and as many evenly spaced).
    floor : float, optional
        Samples below this share of the highest pressure are not used (the exhaust's law
        is singular at 0 bar, and a sensor clips its noise there).
    taus : sequence of float, optional
        Time constants of the history basis ``exp(-s/tau)`` per mode, s.
    fast : sequence of float, optional
        Time constants of fast transients fitted with the pressure term, not tested, s.
    alpha : float, optional
        Level of the tests.
    min_share : float, optional
        Smallest RMS of the history term, as a share of the RMS rate, that names a second
        state (a significant but negligible history, such as a regulator's, is not one).

    Returns
    -------
    HistoryTest or None
        None when fewer than 200 usable samples or no sample in one of the modes.

    Notes
    -----
    With ``r = dp/dt - f_mode(p)``, ``B_p`` hat functions of ``p`` per mode and ``B_s`` the
    columns ``exp(-s/tau_j)`` per mode (``s`` the time since the mode began), the pressure
    test is ``r ~ B_p`` against ``r ~ 0`` and the history test ``r ~ B_p + B_s`` against
    ``r ~ B_p``. Each is a Wald test with the block sandwich covariance: the residuals are
    correlated over the smoothing window and along a slow misfit, not between blocks of
    ``block`` s.
    """
    rs, ps, ons, sinces, ids = [], [], [], [], []
    reach = window / 2 + guard
    dead = max(params.t_on, params.t_off, dead_time)
    offset = 0
    for run in runs:
        t = np.asarray(run.t, dtype=np.float64)
        p = np.asarray(run.p, dtype=np.float64)
        if t.size < 20:
            continue
        on, since, usable = edge_history(
            t, run.command_starts, run.level, params.t_on, params.t_off, reach, dead
        )
        psm, dp = _smooth(p, float(np.median(np.diff(t))), window)
        # the smoothing's reach at the stretch's two ends
        usable &= np.isfinite(dp) & (t > t[0] + reach) & (t < t[-1] - reach)
        bid = np.floor(t / block).astype(np.int64)
        rs.append(dp[usable])
        ps.append(psm[usable])
        ons.append(on[usable])
        sinces.append(since[usable])
        ids.append(bid[usable] + offset)
        offset += int(bid[-1]) + 1
    if not rs:
        return None
    on = np.concatenate(ons)
    p = np.concatenate(ps)
    rate = _rates(p, on, params)
    r = np.concatenate(rs) - rate
    if r.size < 200 or on.all() or not on.any():
        return None
    since = np.concatenate(sinces)
    # Near 0 bar the exhaust's law is singular and a sensor clips its noise: not used.
    keep = p > floor * float(np.max(np.abs(p)))
    r, on, rate, p, since = r[keep], on[keep], rate[keep], p[keep], since[keep]
    if r.size < 200 or on.all() or not on.any():
        return None
    blocks_in = np.concatenate(ids)[keep]
    _, blocks = np.unique(blocks_in, return_inverse=True)
    pressure = _pressure_basis(p, on, knots)

    def decays(values: Sequence[float]) -> FloatArray:
        cols = [np.exp(-since / tau) * (on == mode) for mode in (True, False) for tau in values]
        return np.stack(cols, axis=1) if cols else np.zeros((since.size, 0))

    hist = decays(taus)
    base = np.hstack([pressure, decays(fast)])
    scale = float(np.sqrt(np.mean(rate * rate)))
    p_press, fit_press = nested_wald(r, np.zeros((r.size, 0)), pressure, blocks)
    p_hist, fit_hist = nested_wald(r, base, hist, blocks)
    share_h = float(np.sqrt(np.mean(fit_hist**2))) / scale if scale > 0 else math.inf
    share_p = float(np.sqrt(np.mean(fit_press**2))) / scale if scale > 0 else math.inf
    second = p_hist < alpha and share_h >= min_share
    return HistoryTest(
        samples=int(r.size),
        blocks=int(blocks.max()) + 1,
        p_history=p_hist,
        p_pressure=p_press,
        history_share=share_h,
        pressure_share=share_p,
        second_state=bool(second),
        pressure_laws=bool(not second and p_press < alpha and share_p >= min_share),
        alpha=alpha,
        min_share=min_share,
    )
