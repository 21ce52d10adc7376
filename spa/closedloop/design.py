"""PI design from the identified valve: local models from the averaged analysis, SIMC tuning.

For a modulator setting the averaged analysis (docs/model.md section 3) gives, at every input
fraction ``xi``, the equilibrium pressure ``P_eq(xi)`` (Eq. 5) and the equivalent time
constant ``tau_m(xi)`` (Eq. 9). Around the set-point ``r`` the loop sees a first-order plant
with dead time,

    K(r) = dP_eq/dxi at xi_ff(r) = P_eq^-1(r),   tau(r) = tau_m(xi_ff(r)),
    theta(r) = (t_on + t_off)/2 + T(xi_ff(r))/2,

the dead time being the valve's mean switching delay plus half the modulator's pulse period
``T = t_h + t_l`` (Appendix A; a change of ``xi`` acts on average half a period later), the
period capped at :data:`MAX_PERIOD`. SIMC (Skogestad 2003) turns a first-order-plus-dead-time
model into a PI with one closed-loop time constant ``tau_c``:
``Kp = tau/(K*(tau_c + theta))``, ``Ti = min(tau, 4*(tau_c + theta))``, ``Ki = Kp/Ti``.
The fixed PI uses the local model at one design point; the scheduled PI uses it at every
point of a set-point grid, plus the feed-forward ``xi_ff(r)``.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from typing import Any

import numpy as np
import numpy.typing as npt

from spa import _checks as checks
from spa._docs import fill_doc
from spa.closedloop.controller import PIController
from spa.model.averaging import equilibrium, pulse_times, time_constant, time_fractions
from spa.model.modulators import Modulator
from spa.model.params import ValveParams, valve_params

__all__ = [
    "DEFAULT_TAU_C",
    "LocalModels",
    "design_pi",
    "feedforward",
    "local_models",
    "operating_levels",
    "simc",
]

#: Margin kept from each end of a setting's rising range of ``P_eq``, as a fraction of it.
LEVEL_MARGIN = 0.02

#: Default closed-loop time constant of SIMC, s. Chosen by measurement
#: (benchmarks/sweep_tau_c.py, docs/model.md section 8): on the nominal valve it is the
#: shortest of 0.05-0.5 s for which the fixed PI of IIPFM (20 ms, G = 1.15) overshoots by at
#: most about 5 % over the staircase 0.05-0.75 bar (0.1 s: 10 %); longer only slows the loop.
DEFAULT_TAU_C = 0.2

#: Longest pulse period counted in the dead time, s (IPFM near xi = 0 and IIPFM near xi = 1
#: have unbounded periods, where the averaged model no longer describes the loop).
MAX_PERIOD = 0.2

_N_XI = 2001  # points of the xi grid on which P_eq is inverted and differentiated


@dataclass(frozen=True)
class LocalModels:
    """First-order-plus-dead-time models of the loop at set-points ``r``.

    Attributes
    ----------
    r : numpy.ndarray
        Set-points, bar.
    xi : numpy.ndarray
        Feed-forward input fraction ``P_eq^-1(r)``.
    gain : numpy.ndarray
        ``K = dP_eq/dxi`` there, bar.
    tau : numpy.ndarray
        ``tau_m`` (Eq. 9), s.
    dead_time : numpy.ndarray
        ``theta``, s.
    """

    r: np.ndarray
    xi: np.ndarray
    gain: np.ndarray
    tau: np.ndarray
    dead_time: np.ndarray


def _curve(mod: Modulator, params: ValveParams) -> tuple[np.ndarray, np.ndarray]:
    """``(xi, P_eq)`` on a fine grid, restricted to where ``P_eq`` strictly increases.

    Computed once per setting and valve (:func:`_curve_of`, cached): the design, the
    feed-forward, the cycle period and the settled start of every experiment share it.
    """
    return _curve_of(mod.kind, tuple(sorted(mod.settings.items())), params)


@lru_cache(maxsize=256)
def _curve_of(
    kind: str, settings: tuple[tuple[str, Any], ...], params: ValveParams
) -> tuple[np.ndarray, np.ndarray]:
    xi = np.linspace(0.0, 1.0, _N_XI)
    peq = np.asarray(equilibrium(kind, xi, params, **dict(settings)), dtype=np.float64)
    keep = np.concatenate(([True], np.diff(peq) > 0.0))
    # Drop the flat dead-zone except its last point, and the flat saturation.
    out = xi[keep], peq[keep]
    for a in out:
        a.setflags(write=False)  # shared by every caller
    return out


@fill_doc
def feedforward(
    r: npt.ArrayLike, modulator: Modulator | dict[str, Any], params: ValveParams | None = None
) -> np.ndarray:
    """The averaged model's inverse: the input fraction whose ``P_eq`` is ``r``.

    Parameters
    ----------
    r : array_like
        Set-points, bar; outside the reachable range the edge of the range is used.
    %(setting_valve)s

    Returns
    -------
    numpy.ndarray
        ``xi_ff(r)`` in [0, 1], by linear interpolation of the inverse of ``P_eq`` (Eq. 5)
        on a grid of 2001 values of ``xi``.

    Examples
    --------
    >>> xi = feedforward([0.3], {"type": "iipfm", "t_l": 0.02, "gain": 1.15})
    >>> from spa.model.averaging import equilibrium
    >>> p = equilibrium("iipfm", xi, t_l=0.02, gain=1.15)
    >>> bool(abs(p[0] - 0.3) < 1e-3)
    True
    """
    return _feedforward(r, Modulator.from_mapping(modulator), valve_params(params))


def _feedforward(r: npt.ArrayLike, mod: Modulator, params: ValveParams) -> np.ndarray:
    """:func:`feedforward` of a setting and a valve already checked (the closed-loop stage's
    modules, which received the valve once where it entered)."""
    xi, peq = _curve(mod, params)
    return np.interp(np.asarray(r, dtype=np.float64), peq, xi)


@fill_doc
def local_models(
    r: npt.ArrayLike, modulator: Modulator | dict[str, Any], params: ValveParams | None = None
) -> LocalModels:
    """Static gain, time constant and dead time of the averaged loop at set-points ``r``.

    Parameters
    ----------
    r : array_like
        Set-points, bar (inside ``(0, k2)``).
    %(setting_valve)s

    Returns
    -------
    LocalModels
        As the module's docstring defines them.

    Examples
    --------
    >>> m = local_models([0.2, 0.6], {"type": "iipfm", "t_l": 0.02, "gain": 1.15})
    >>> bool(np.all(m.gain > 0) and np.all(m.tau > 0))
    True
    """
    return _local_models(r, Modulator.from_mapping(modulator), valve_params(params))


def _local_models(r: npt.ArrayLike, mod: Modulator, params: ValveParams) -> LocalModels:
    """:func:`local_models` of a setting and a valve already checked (the closed-loop
    stage's modules, which received the valve once where it entered)."""
    rr = np.atleast_1d(np.asarray(r, dtype=np.float64))
    xi_grid, peq = _curve(mod, params)
    slope = np.gradient(peq, xi_grid)
    x = np.interp(rr, peq, xi_grid)
    gain = np.interp(x, xi_grid, slope)
    a1, a2 = time_fractions(mod.kind, x, params, **mod.settings)
    tau = np.asarray(time_constant(a1, a2, params), dtype=np.float64)
    t_h, t_l = pulse_times(mod.kind, x, **mod.settings)
    period = np.minimum(np.asarray(t_h) + np.asarray(t_l), MAX_PERIOD)
    theta = 0.5 * (params.t_on + params.t_off) + 0.5 * period
    return LocalModels(rr, x, gain, tau, theta)


@fill_doc
def operating_levels(
    levels: npt.ArrayLike,
    modulator: Modulator | dict[str, Any],
    params: ValveParams | None = None,
    max_fraction: float = 1.0,
    spread: bool = False,
) -> tuple[list[float], str | None]:
    """The set-points a setting can hold on a valve, or why it can hold none.

    Parameters
    ----------
    levels : array_like
        Wanted set-points, bar.
    %(setting_valve)s
    max_fraction : float, default 1
        Levels at or above ``max_fraction * k2`` are left out too.
    spread : bool, default False
        When fewer than two of ``levels`` fit (a valve whose supply is below the wanted
        set-points), spread as many levels as were wanted (at least three) evenly over the
        range the setting holds, rounded to 3 significant digits, instead of giving up.

    Returns
    -------
    kept : list of float
        The levels strictly inside the rising range of ``P_eq``
        (:func:`spa.model.usable.rising_range`) less :data:`LEVEL_MARGIN` of it at each end,
        and below ``max_fraction * k2``, in their order.
    reason : str or None
        None when at least two levels are kept; else one sentence naming the setting and
        what it can reach (:func:`spa.model.usable.unusable_reason` when it reaches nothing).

    Examples
    --------
    >>> operating_levels([0.1, 0.5, 0.9], {"type": "pwm", "f_w": 20.0})
    ([0.1, 0.5], None)
    >>> low = ValveParams(k2=0.3)
    >>> operating_levels([0.1, 0.5, 0.9], {"type": "pwm", "f_w": 20.0}, low, spread=True)
    ([0.078, 0.15, 0.222], None)
    """
    from spa.model.usable import rising_range, unusable_reason

    params = valve_params(params)
    mod = Modulator.from_mapping(modulator).bind(params)
    wanted = [float(v) for v in np.atleast_1d(np.asarray(levels, dtype=np.float64))]
    why = unusable_reason(mod, params)
    reach = None if why else rising_range(mod, params)
    if reach is None:
        return [], why or f"{mod.label}: P_eq does not rise on this valve"
    lo, hi = reach
    pad = LEVEL_MARGIN * (hi - lo)
    top = min(hi - pad, max_fraction * params.k2)
    kept = [v for v in wanted if lo + pad < v < top]
    if len(kept) >= 2:
        return kept, None
    if spread and top > lo + pad:
        n = max(len(wanted), 3)
        inner = np.linspace(lo + pad, top, n + 2)[1:-1]
        even = sorted({float(f"{v:.3g}") for v in inner})
        if len(even) >= 2:
            return even, None
    return kept, (
        f"{mod.label}: no usable operating range for the closed loop: it holds "
        f"{lo + pad:.3g}–{top:.3g} bar on this valve, which leaves {len(kept)} of the "
        f"set-points {wanted} bar (two are needed)"
    )


def simc(
    gain: npt.ArrayLike, tau: npt.ArrayLike, dead_time: npt.ArrayLike, tau_c: float
) -> tuple[np.ndarray, np.ndarray]:
    """SIMC PI gains for first-order-plus-dead-time models (Skogestad 2003).

    Parameters
    ----------
    gain, tau, dead_time : array_like
        ``K`` (bar per unit of xi), ``tau`` (s) and ``theta`` (s); broadcast.
    tau_c : float
        Desired closed-loop time constant, s (> 0).

    Returns
    -------
    kp, ki : numpy.ndarray
        ``Kp = tau/(K*(tau_c + theta))`` in 1/bar and ``Ki = Kp/min(tau, 4*(tau_c + theta))``
        in 1/(bar·s).

    Examples
    --------
    >>> kp, ki = simc(0.8, 0.8, 0.02, 0.18)
    >>> round(float(kp), 3), round(float(ki), 3)
    (5.0, 6.25)
    """
    tau_c = checks.positive("tau_c", tau_c, "s")
    k = np.asarray(gain, dtype=np.float64)
    tau = np.asarray(tau, dtype=np.float64)
    theta = np.asarray(dead_time, dtype=np.float64)
    kp = tau / (k * (tau_c + theta))
    ti = np.minimum(tau, 4.0 * (tau_c + theta))
    return kp, kp / ti


@fill_doc
def design_pi(
    modulator: Modulator | dict[str, Any],
    params: ValveParams | None = None,
    *,
    levels: npt.ArrayLike,
    tau_c: float = DEFAULT_TAU_C,
    design_point: float | None = None,
) -> dict[str, PIController]:
    """A fixed and a gain-scheduled PI for a modulator setting on an identified valve.

    Parameters
    ----------
    %(setting_valve)s
    levels : array_like
        Set-points of the operating range, bar: the schedule's grid.
    tau_c : float, optional
        SIMC's closed-loop time constant, s.
    design_point : float, optional
        Set-point of the fixed PI's local model, bar; the middle of ``levels`` by default.

    Returns
    -------
    dict
        ``{"fixed": ..., "scheduled": ..., "scheduled_ff": ...}`` (:class:`PIController`):
        SIMC at the design point; SIMC at every level, interpolated in the set-point; the
        same plus the averaged model's feed-forward ``xi_ff(r)``.

    Raises
    ------
    ValueError
        If a local model is degenerate (a level outside the modulator's reachable range).
    """
    params = valve_params(params)
    mod = Modulator.from_mapping(modulator)
    grid = np.unique(np.asarray(levels, dtype=np.float64))
    mid = float(np.median(grid)) if design_point is None else float(design_point)
    models = _local_models(np.append(grid, mid), mod, params)
    bad = ~(np.isfinite(models.tau) & (models.gain > 0))
    if np.any(bad):
        where = np.append(grid, mid)[bad]
        raise ValueError(
            f"{mod.label}: no local model at set-point(s) {where.tolist()} bar "
            "(outside the range the modulator reaches on this valve)"
        )
    kp, ki = simc(models.gain, models.tau, models.dead_time, tau_c)
    ff = (tuple(grid), tuple(np.clip(models.xi[:-1], 0.0, 1.0)))
    if grid.size > 1:
        gains: dict[str, Any] = {
            "kp": tuple(kp[:-1]),
            "ki": tuple(ki[:-1]),
            "schedule": tuple(grid),
        }
    else:
        gains = {"kp": float(kp[0]), "ki": float(ki[0])}
    return {
        "fixed": PIController(kp=float(kp[-1]), ki=float(ki[-1])),
        "scheduled": PIController(**gains),
        "scheduled_ff": PIController(**gains, feedforward=ff),
    }
