"""Exact simulation of the four-state valve + actuator model (MODEL.md section 1).

Every segment of the hybrid model has a closed form, so the simulation needs no ODE solver:
it walks the runs of constant command (one Python iteration per valve *edge*, never per
sample) to get the pressure at the start of each run, then evaluates the closed forms at all
sample times at once with numpy.
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from spa.model.params import ValveParams

__all__ = ["charge", "discharge", "run_start_pressures", "simulate"]


def charge(p0: npt.ArrayLike, elapsed: npt.ArrayLike, params: ValveParams) -> np.ndarray:
    """Pressure after charging (state 2) for ``elapsed`` seconds from ``p0``.

    Parameters
    ----------
    p0 : array_like
        Pressure at the start of the charge, bar.
    elapsed : array_like
        Time spent charging, s (>= 0).
    params : ValveParams
        Uses ``k2`` (bar) and ``tau2`` (s).

    Returns
    -------
    numpy.ndarray
        ``k2 + (p0 - k2) * exp(-elapsed/tau2)`` (Eq. 2 solved; Appendix B Eq. A2).
    """
    p0 = np.asarray(p0, dtype=np.float64)
    return params.k2 + (p0 - params.k2) * np.exp(
        -np.asarray(elapsed, dtype=np.float64) / params.tau2
    )


def discharge(p0: npt.ArrayLike, elapsed: npt.ArrayLike, params: ValveParams) -> np.ndarray:
    """Pressure after exhausting (state 1) for ``elapsed`` seconds from ``p0``.

    Parameters
    ----------
    p0 : array_like
        Pressure at the start of the discharge, bar (>= 0).
    elapsed : array_like
        Time spent exhausting, s (>= 0).
    params : ValveParams
        Uses ``c1`` (s·bar^-0.5).

    Returns
    -------
    numpy.ndarray
        ``max(sqrt(p0) - elapsed/(2*c1), 0)**2`` (Eq. 1 solved; Appendix B Eq. A1). The
        actuator empties in finite time ``2*c1*sqrt(p0)`` and stays at 0.
    """
    root = np.sqrt(np.asarray(p0, dtype=np.float64)) - np.asarray(elapsed, dtype=np.float64) / (
        2.0 * params.c1
    )
    return np.square(np.maximum(root, 0.0))


def _check_command(u: npt.ArrayLike) -> np.ndarray:
    arr = np.asarray(u)
    if arr.ndim != 1:
        raise ValueError(f"u must be a one-dimensional array, got shape {arr.shape}")
    if arr.dtype.kind == "b":
        return arr.astype(np.int8)
    if arr.dtype.kind not in "iuf":
        raise ValueError(f"u must hold numbers 0/1, got dtype {arr.dtype}")
    if arr.size and not np.all((arr == 0) | (arr == 1)):
        bad = int(np.flatnonzero((arr != 0) & (arr != 1))[0])
        raise ValueError(f"u must hold only 0 and 1; u[{bad}] = {arr[bad]!r}")
    return arr.astype(np.int8, copy=False)


def simulate(
    u: npt.ArrayLike, dt: float, params: ValveParams | None = None, p0: float = 0.0
) -> npt.NDArray[np.float64]:
    """Exact pressure response of the valve + actuator to a sampled 0/1 command.

    Parameters
    ----------
    u : array_like of {0, 1}, shape (n,)
        Valve command; ``u[k]`` is held over ``[k*dt, (k+1)*dt)``. A change between
        ``u[k-1]`` and ``u[k]`` is an edge at ``t = k*dt``.
    dt : float
        Sample step, s.
    params : ValveParams, optional
        Model parameters; the paper's nominal values by default.
    p0 : float, optional
        Pressure at ``t = 0``, bar (>= 0). At ``t = 0`` the valve is settled in state
        ``u[0]``: no transition is running.

    Returns
    -------
    numpy.ndarray of float64, shape (n,)
        ``p[k]``, the pressure at ``t = k*dt``, in bar.

    Raises
    ------
    ValueError
        If ``u`` holds anything but 0 and 1, ``dt`` is not finite and positive, or ``p0`` is
        negative or not finite.

    Notes
    -----
    Four states (MODEL.md section 1): discharging ``dP/dt = -sqrt(P)/c1`` (valve off),
    charging ``dP/dt = (k2 - P)/tau2`` (valve on), and two holds ``dP/dt = 0`` lasting
    ``t_on`` after a 0→1 edge and ``t_off`` after a 1→0 edge. An edge during a hold starts the
    hold of the new command, so a high pulse shorter than ``t_on`` (or a low pulse shorter
    than ``t_off``) leaves the pressure unchanged. For a run of constant command lasting ``L``
    the active time is ``max(L - hold, 0)``; the pressure at each sample is the closed form of
    its run evaluated at the active time elapsed so far. Cost: one Python step per edge, the
    rest vectorised.

    Examples
    --------
    >>> import numpy as np
    >>> p = simulate(np.ones(11, dtype=np.int8), dt=0.1)   # settled open at t = 0: no t_on
    >>> bool(abs(p[10] - 0.837 * (1 - np.exp(-1 / 0.826))) < 1e-12)
    True
    """
    params = ValveParams() if params is None else params
    if not (isinstance(dt, int | float | np.floating) and math.isfinite(dt) and dt > 0):
        raise ValueError(f"dt must be finite and > 0, got {dt!r}")
    if not (math.isfinite(p0) and p0 >= 0.0):
        raise ValueError(f"p0 must be finite and >= 0 bar, got {p0!r}")
    cmd = _check_command(u)
    n = cmd.size
    if n == 0:
        return np.zeros(0, dtype=np.float64)

    # Runs of constant command: starts[j] is the first sample of run j.
    starts = np.concatenate(([0], np.flatnonzero(cmd[1:] != cmd[:-1]) + 1))
    lengths = np.diff(np.append(starts, n))
    level = cmd[starts].astype(bool)
    hold = np.where(level, params.t_on, params.t_off)
    hold[0] = 0.0  # settled at t = 0

    # Pressure at the start of every run: a recurrence over edges with precomputed factors.
    active = np.maximum(lengths * dt - hold, 0.0)
    p_start = run_start_pressures(level, active, p0, params)

    # Closed form at every sample of every run, in one pass over the samples:
    # charging runs: p = k2 + a*exp(-e/tau2) (b = r = 0); exhausting runs: p = max(b - r*e, 0)^2
    # (a = 0), with e the active time elapsed since the run's hold ended.
    a = np.where(level, p_start - params.k2, 0.0)
    b = np.where(level, 0.0, np.sqrt(p_start))
    r = np.where(level, 0.0, 1.0 / (2.0 * params.c1))
    rate = np.where(level, -1.0 / params.tau2, 0.0)
    base = np.where(level, params.k2, 0.0)
    elapsed = np.arange(n, dtype=np.float64)
    elapsed *= dt
    elapsed -= np.repeat(starts * dt + hold, lengths)
    np.maximum(elapsed, 0.0, out=elapsed)
    p = elapsed * np.repeat(rate, lengths)
    np.exp(p, out=p)
    p *= np.repeat(a, lengths)
    p += np.repeat(base, lengths)
    root = elapsed * np.repeat(r, lengths)
    np.subtract(np.repeat(b, lengths), root, out=root)
    np.maximum(root, 0.0, out=root)
    root *= root
    p += root
    return p


def run_start_pressures(
    level: npt.NDArray[np.bool_], active: npt.NDArray[np.float64], p0: float, params: ValveParams
) -> npt.NDArray[np.float64]:
    """Pressure at the start of every run of constant command (one scalar step per edge).

    Parameters
    ----------
    level : numpy.ndarray of bool
        Command of each run (True: valve open).
    active : numpy.ndarray of float
        Time each run spends charging or exhausting after its hold, s (>= 0).
    p0 : float
        Pressure at the start of the first run, bar.
    params : ValveParams
        Model parameters.

    Returns
    -------
    numpy.ndarray
        ``p_start[j]``; run ``j + 1`` starts where the closed form of run ``j`` ends.
    """
    decay = np.exp(-active / params.tau2).tolist()
    drop = (active / (2.0 * params.c1)).tolist()
    out = [0.0] * level.size
    p = float(p0)
    k2 = params.k2
    sqrt = math.sqrt
    for j, on in enumerate(level.tolist()):
        out[j] = p
        if on:
            p = k2 + (p - k2) * decay[j]
        else:
            r = sqrt(p) - drop[j]
            p = r * r if r > 0.0 else 0.0
    return np.asarray(out, dtype=np.float64)
