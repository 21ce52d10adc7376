"""Exact simulation of the four-state valve + actuator model (docs/model.md section 1).

Every segment of the hybrid model has a closed form, so the simulation needs no ODE solver:
it walks the runs of constant command (one Python iteration per valve *edge*, never per
sample) to get the pressure at the start of each run, then evaluates the closed forms at all
sample times at once with numpy.
"""

from __future__ import annotations

import math
from types import ModuleType

import numpy as np
import numpy.typing as npt

from spa import _checks as checks
from spa.model.params import DELAY_CONVENTIONS, ValveParams, valve_params

__all__ = [
    "NO_LAWS",
    "charge",
    "discharge",
    "edge_indices",
    "loop_laws",
    "mode_time",
    "replay",
    "run_start_pressures",
    "segment_pressure",
    "segment_pressure_scalar",
    "simulate",
    "transport_runs",
]


def _laws() -> ModuleType:
    """The general laws' time maps, imported when a valve carries laws."""
    from spa.model.laws import timemap

    return timemap


def _check_delay(delay: str | None, params: ValveParams | None = None) -> str:
    """The delay convention to simulate with: ``delay``, or the valve's own when None
    (docs/model.md section 1)."""
    if delay is None:
        return params.delay if params is not None else "hold"
    if delay not in DELAY_CONVENTIONS:
        raise ValueError(f"delay must be one of {DELAY_CONVENTIONS}, got {delay!r}")
    return delay


def segment_pressure(
    on: bool | npt.ArrayLike,
    p_start: npt.ArrayLike,
    elapsed: npt.ArrayLike,
    params: ValveParams,
    repeats: npt.ArrayLike | None = None,
) -> np.ndarray:
    """The plant's closed forms: pressure after ``elapsed`` s of charging or exhausting.

    Every evaluation of the model in spa (simulation, the replay of a run for validation,
    identification's model response, the exact periodic orbits of tuning) calls this one
    function.

    Parameters
    ----------
    on : bool or array_like of bool
        True: charging (state 2, valve open); False: exhausting (state 1, valve closed).
        Broadcast against ``p_start`` and ``elapsed``.
    p_start : array_like
        Pressure when the segment's active phase starts, bar (>= 0).
    elapsed : array_like
        Active time since then, s; negative values count as 0 (still in the hold).
    params : ValveParams
        Uses ``c1`` (s·bar^-0.5), ``k2`` (bar) and ``tau2`` (s).
    repeats : array_like of int, optional
        When given, ``on`` and ``p_start`` hold one value per run of ``repeats[j]``
        consecutive entries of ``elapsed`` (as :func:`numpy.repeat`): a whole simulation in
        one call, with the per-run terms computed once per run.

    Returns
    -------
    numpy.ndarray
        Charging: ``k2 + (p_start - k2) * exp(-elapsed/tau2)`` (Eq. 2 solved; Appendix B
        Eq. A2). Exhausting: ``max(sqrt(p_start) - elapsed/(2*c1), 0)**2`` (Eq. 1 solved;
        Eq. A1): the actuator empties in finite time ``2*c1*sqrt(p_start)`` and stays at 0.

    Notes
    -----
    Evaluated as ``k2 + (p_start - k2) * exp(-elapsed/tau2)`` and
    ``max(sqrt(p_start) - elapsed/(2*c1), 0)**2`` in every path, so that a simulation and a
    replay of it agree to the last bit. A valve with general laws (``params.laws`` not None)
    is evaluated by its time maps instead
    (:func:`spa.model.laws.timemap.law_segment_pressure`).

    Examples
    --------
    >>> prm = ValveParams()
    >>> p = float(segment_pressure(True, 0.0, prm.tau2, prm))   # one time constant
    >>> abs(p - prm.k2 * (1 - math.exp(-1))) < 1e-15
    True
    >>> float(segment_pressure(False, 0.25, 2 * prm.c1 * 0.5, prm))  # empty after 2*c1*sqrt(p)
    0.0
    """
    if getattr(params, "laws", None) is not None:  # duck-typed valves carry none
        return _laws().law_segment_pressure(on, p_start, elapsed, params, repeats)
    e = np.maximum(np.asarray(elapsed, dtype=np.float64), 0.0)
    p0 = np.asarray(p_start, dtype=np.float64)
    if np.ndim(on) == 0:
        if on:
            return params.k2 + (p0 - params.k2) * np.exp(-e / params.tau2)
        root = np.maximum(np.sqrt(p0) - e / (2.0 * params.c1), 0.0)
        return root * root
    # Both closed forms at once: base + a*exp(-e/tau2) + max(b - e/(2*c1), 0)**2, with the
    # terms of the other state zero (a = base = 0 while exhausting, b = 0 while charging): the
    # same bits as above, sample by sample.
    level = np.asarray(on, dtype=bool)
    a = np.where(level, p0 - params.k2, 0.0)
    base = np.where(level, params.k2, 0.0)
    b = np.where(level, 0.0, np.sqrt(np.where(level, 0.0, p0)))

    if repeats is None:
        root = np.maximum(b - e / (2.0 * params.c1), 0.0)
        return np.exp(-e / params.tau2) * a + base + root * root

    def per_sample(x: np.ndarray) -> np.ndarray:
        # Expanded just before use, so that each full-length temporary is freed at once
        # (keeping them all alive doubles the time in page faults).
        return np.repeat(x, repeats)

    out = np.negative(e)
    out /= params.tau2
    np.exp(out, out=out)
    out *= per_sample(a)
    out += per_sample(base)
    root = e / (2.0 * params.c1)
    np.subtract(per_sample(b), root, out=root)
    np.maximum(root, 0.0, out=root)
    root *= root
    out += root
    return out


def segment_pressure_scalar(
    on: bool, p_start: float, elapsed: float, c1: float, k2: float, tau2: float
) -> float:
    """:func:`segment_pressure` for one sample, on plain floats: the same closed forms.

    Written for numba (``numba.njit(segment_pressure_scalar)``): the closed loop, whose
    samples follow one another, compiles it into its per-sample loop
    (:mod:`spa.closedloop.loop`), so the plant's formula is written once, here.

    Parameters
    ----------
    on : bool
        True: charging (valve open); False: exhausting.
    p_start : float
        Pressure when the segment's active phase starts, bar (>= 0).
    elapsed : float
        Active time since then, s; negative counts as 0.
    c1, k2, tau2 : float
        The valve's :class:`~spa.model.params.ValveParams` fields.

    Returns
    -------
    float
        ``k2 + (p_start - k2)*exp(-e/tau2)`` charging, ``max(sqrt(p_start) - e/(2*c1), 0)**2``
        exhausting, with ``e = max(elapsed, 0)``: :func:`segment_pressure`'s formula (the
        scalar ``exp`` may differ from numpy's in the last bit).

    Examples
    --------
    >>> prm = ValveParams()
    >>> args = (prm.c1, prm.k2, prm.tau2)
    >>> abs(segment_pressure_scalar(True, 0.1, 0.05, *args)
    ...     - float(segment_pressure(True, 0.1, 0.05, prm))) < 1e-15
    True
    >>> segment_pressure_scalar(False, 0.25, 2 * prm.c1 * 0.5, *args)
    0.0
    """
    e = max(elapsed, 0.0)
    if on:
        return math.exp(-e / tau2) * (p_start - k2) + k2
    root = max(math.sqrt(p_start) - e / (2.0 * c1), 0.0)
    return root * root


#: The law tables' arguments of a valve without laws, for a compiled loop's signature (never
#: read: :func:`loop_laws`'s flag is off).
NO_LAWS: tuple = (
    1.0, 0.5, 1.0, 1.0, 1e-14, np.zeros(2), np.ones(2), np.zeros((2, 2)), np.zeros((2, 2)),
    np.zeros(2), np.ones(2), np.zeros((4, 2)),
)  # fmt: skip


def loop_laws(params: ValveParams) -> tuple[bool, tuple]:
    """The plant as a compiled per-sample loop steps it (the closed loop).

    Returns
    -------
    lawful : bool
        True for a valve with its own laws: the loop steps each mode with
        :func:`spa.model.laws._kernel.law_step` on ``tables``; False for the paper's laws,
        whose closed form (:func:`segment_pressure_scalar`) the loop evaluates, bit for bit.
    tables : tuple
        ``law_tables(params).kernel_args`` (:func:`spa.model.laws.timemap.law_tables`), or
        :data:`NO_LAWS`.
    """
    if getattr(params, "laws", None) is None:  # duck-typed valves carry none
        return False, NO_LAWS
    return True, _laws().law_tables(params).kernel_args


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
        ``k2 + (p0 - k2) * exp(-elapsed/tau2)`` (:func:`segment_pressure` with ``on=True``).
    """
    return segment_pressure(True, p0, elapsed, params)


def mode_time(
    on: bool, start: npt.ArrayLike, end: npt.ArrayLike, params: ValveParams
) -> np.ndarray:
    """Time the plant held in one mode takes from ``start`` to ``end`` bar, s.

    Parameters
    ----------
    on : bool
        True for a charge (``start <= end < k2``), False for a discharge
        (``start >= end >= 0``).
    start, end : array_like
        Pressures, bar; broadcast.
    params : ValveParams
        The valve. The paper's laws give Eq. A2, ``tau2*ln((k2 - start)/(k2 - end))``, and
        Eq. A1, ``2*c1*(sqrt(start) - sqrt(end))``; a valve with its own laws the difference
        of its mode's time map ``T(end) - T(start)``
        (:func:`spa.model.laws.timemap.law_tables`, at ``FIT_NODES``: a transit time, not
        a simulation).

    Returns
    -------
    numpy.ndarray
        The time, s (``inf`` for a charge to ``k2``).

    Examples
    --------
    >>> p = ValveParams(c1=0.5, k2=1.0, tau2=1.0)
    >>> round(float(mode_time(True, 0.25, 0.5, p)), 4), float(mode_time(False, 1.0, 0.25, p))
    (0.4055, 0.5)
    """
    a = np.asarray(start, dtype=np.float64)
    b = np.asarray(end, dtype=np.float64)
    if getattr(params, "laws", None) is not None:  # duck-typed valves carry none
        laws = _laws()
        tab = laws.law_tables(params, laws.FIT_NODES)  # T to about 1e-6 of itself
        mode = tab.mode(bool(on))
        return mode.forward(b, tab.k2) - mode.forward(a, tab.k2)
    if on:
        with np.errstate(divide="ignore", invalid="ignore"):
            return params.tau2 * np.log((params.k2 - a) / np.maximum(params.k2 - b, 1e-12))
    return 2.0 * params.c1 * (np.sqrt(a) - np.sqrt(b))


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
        ``max(sqrt(p0) - elapsed/(2*c1), 0)**2`` (:func:`segment_pressure` with
        ``on=False``).
    """
    return segment_pressure(False, p0, elapsed, params)


def edge_indices(valve: npt.ArrayLike) -> npt.NDArray[np.int64]:
    """Indices ``k`` where ``valve[k] != valve[k-1]``: the valve switches at ``t[k]``.

    Examples
    --------
    >>> edge_indices(np.array([0, 1, 1, 0, 0, 1])).tolist()
    [1, 3, 5]
    """
    v = np.asarray(valve)
    return np.flatnonzero(v[1:] != v[:-1]) + 1


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
    u: npt.ArrayLike,
    dt: float,
    params: ValveParams | None = None,
    p0: float = 0.0,
    *,
    delay: str | None = None,
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
    delay : {"hold", "transport"}, optional
        Delay convention; ``params.delay`` when omitted. ``"hold"`` (the paper's): the
        pressure holds still for ``t_on``/``t_off`` after an edge. ``"transport"``: the
        command reaches the plant ``t_on`` after a rising and ``t_off`` after a falling
        edge, the previous connection persisting meanwhile (see :func:`transport_runs`).

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
    Four states (docs/model.md section 1): discharging ``dP/dt = -sqrt(P)/c1`` (valve off),
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
    params = valve_params(params)
    dt = checks.positive("dt", dt, "s")
    p0 = checks.nonnegative("p0", p0, "bar")
    delay = _check_delay(delay, params)
    cmd = _check_command(u)
    n = cmd.size
    if n == 0:
        return np.zeros(0, dtype=np.float64)
    if delay == "transport":
        k = np.concatenate(([0], edge_indices(cmd)))
        level = cmd[k].astype(bool)
        hold = np.where(level, params.t_on, params.t_off)
        hold[0] = 0.0
        t = np.arange(n, dtype=np.float64) * dt
        return replay(t, k * dt, level, hold, p0, params, delay="transport")

    # Runs of constant command: starts[j] is the first sample of run j.
    starts = np.concatenate(([0], np.flatnonzero(cmd[1:] != cmd[:-1]) + 1))
    lengths = np.diff(np.append(starts, n))
    level = cmd[starts].astype(bool)
    hold = np.where(level, params.t_on, params.t_off)
    hold[0] = 0.0  # settled at t = 0

    # Pressure at the start of every run: a recurrence over edges with precomputed factors.
    active = np.maximum(lengths * dt - hold, 0.0)
    p_start = run_start_pressures(level, active, p0, params)

    # The closed form of each run at its samples, with the active time elapsed since the
    # run's hold ended.
    elapsed = np.arange(n, dtype=np.float64)
    elapsed *= dt
    elapsed -= np.repeat(starts * dt + hold, lengths)
    return segment_pressure(level, p_start, elapsed, params, repeats=lengths)


def replay(
    t: npt.NDArray[np.float64],
    starts: npt.NDArray[np.float64],
    level: npt.NDArray[np.bool_],
    hold: npt.NDArray[np.float64],
    p0: float,
    params: ValveParams,
    *,
    delay: str | None = None,
) -> npt.NDArray[np.float64]:
    """Exact pressure at any times ``t`` for a sequence of runs of constant command.

    Parameters
    ----------
    t : numpy.ndarray of float
        Times, s (``t >= starts[0]``); any spacing, e.g. a recording's own sample times.
    starts : numpy.ndarray of float
        Start of each run, s, increasing (the first sample, then every valve edge).
    level : numpy.ndarray of bool
        Command of each run (True: valve open).
    hold : numpy.ndarray of float
        How long each run holds the pressure before it acts (``t_on``/``t_off``, or 0 for a
        run settled at the start), s.
    p0 : float
        Pressure at ``starts[0]``, bar.
    params : ValveParams
        Model parameters.
    delay : {"hold", "transport"}, optional
        ``params.delay`` when omitted. ``"hold"``: ``hold`` is how long each run holds the
        pressure still.
        ``"transport"``: ``hold`` is the transport delay after which each run's command
        reaches the plant (:func:`transport_runs`); the plant keeps its previous connection
        meanwhile.

    Returns
    -------
    numpy.ndarray
        The pressure at ``t``: :func:`run_start_pressures` chains the runs, then
        :func:`segment_pressure` evaluates each sample's run.
    """
    if _check_delay(delay, params) == "transport":
        starts, level = transport_runs(starts, level, hold)
        hold = np.zeros(starts.size)
    ends = np.append(starts[1:], np.inf)
    active = np.maximum(ends - starts - hold, 0.0)
    p_start = run_start_pressures(level, active, p0, params)
    j = np.searchsorted(starts, t, side="right") - 1
    np.maximum(j, 0, out=j)
    if j.size > 1 and np.all(j[1:] >= j[:-1]):
        # Sorted times: each run's samples are contiguous, so the per-run terms are computed
        # once per run (the same bits as the per-sample path).
        counts = np.bincount(j, minlength=starts.size)
        elapsed = t - np.repeat(starts, counts)
        elapsed -= np.repeat(hold, counts)
        return segment_pressure(level, p_start, elapsed, params, repeats=counts)
    return segment_pressure(level[j], p_start[j], t - starts[j] - hold[j], params)


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
    if getattr(params, "laws", None) is not None:  # duck-typed valves carry none
        return _laws().law_run_start_pressures(level, active, p0, params)
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


def transport_runs(
    starts: npt.ArrayLike, level: npt.ArrayLike, delay: npt.ArrayLike
) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.bool_]]:
    """The plant's runs of constant connection under the transport-delay convention.

    Parameters
    ----------
    starts : array_like of float
        Start of each command run, s, increasing (the first sample, then every edge).
    level : array_like of bool
        Command of each run.
    delay : array_like of float
        Transport delay of each run's starting edge, s (>= 0; the first run's is ignored:
        the valve is settled in it).

    Returns
    -------
    starts : numpy.ndarray of float
        Times at which the plant's connection changes (the first run's start, then every
        delayed edge that survives), increasing.
    level : numpy.ndarray of bool
        Connection of each plant run (True: supply, charging).

    Notes
    -----
    The plant follows the most recent command whose delay has elapsed: at time ``t`` its
    connection is the level after edge ``J(t) = max{j : starts[j] + delay[j] <= t}``. A
    delayed edge that reaches the plant no later than the one before it (a pulse shorter
    than the difference of the two delays) cancels that one: the pair is removed and the
    previous connection persists. With two delays ``t_on >= t_off`` this is
    ``u_plant(t) = u(t - t_on) and u(t - t_off)``; with ``t_off > t_on``,
    ``u(t - t_on) or u(t - t_off)``.

    Examples
    --------
    >>> s, lv = transport_runs([0.0, 1.0, 1.002], [False, True, False], [0.0, 0.005, 0.001])
    >>> s.tolist(), lv.tolist()      # a 2 ms high pulse with t_on - t_off = 4 ms: cancelled
    ([0.0], [False])
    """
    st = np.asarray(starts, dtype=np.float64)
    lv = np.asarray(level, dtype=bool)
    d = np.asarray(delay, dtype=np.float64)
    if st.size <= 1:
        return st.copy(), lv.copy()
    s = st + d
    s[0] = st[0]
    keep = np.ones(s.size, dtype=bool)
    idx = np.arange(s.size)
    while True:
        alive = idx[keep]
        cross = np.flatnonzero(s[alive[1:]] <= s[alive[:-1]])  # pair (cross, cross+1) in alive
        cross = cross[cross > 0]  # the first run is the settled state, never an edge
        if cross.size == 0:
            break
        first = cross[np.r_[True, np.diff(cross) > 1]]  # the first pair of each chain
        keep[alive[first]] = False
        keep[alive[first + 1]] = False
    out_s, out_l = s[keep], lv[keep]
    # Two successive plant runs with the same connection (after a cancellation) merge.
    same = np.r_[False, out_l[1:] == out_l[:-1]]
    return out_s[~same], out_l[~same]
