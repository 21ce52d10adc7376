"""Exact closed-loop simulation: PI controller -> pulse modulator -> valve -> actuator.

The loop is sequential (the controller reads the pressure the previous commands produced), so
it runs as one numba-compiled loop over the samples; per step it evaluates the plant's closed
form once (:func:`spa.model.plant.segment_pressure_scalar`, compiled; for a valve with its
own laws the time maps' step :func:`spa.model.laws._kernel.law_step` on the valve's
:func:`~spa.model.laws.timemap.law_tables`), the controller's law and the modulator's
per-step kernel (:mod:`spa.model.modulators.kernels`). Convention in docs/model.md section 8;
checked against the open-loop functions and a plain-Python loop in tests/test_closed_loop.py
and tests/test_closed_loop_laws.py.
"""

from __future__ import annotations

import math
from dataclasses import replace
from typing import Any

import numpy as np
import numpy.typing as npt
import pandas as pd
from numba import njit

from spa import _checks as checks
from spa.closedloop.controller import PIController, interp
from spa.model.laws._kernel import law_step
from spa.model.modulators import Modulator, kernels
from spa.model.modulators.kernels import KERNELS
from spa.model.params import ValveParams, valve_params
from spa.model.plant import NO_LAWS as _NO_LAWS
from spa.model.plant import loop_laws, segment_pressure_scalar

__all__ = [
    "closed_loop_arrays",
    "closed_loop_many",
    "simulate_closed_loop",
]

_interp = njit(cache=True)(interp)


#: The plant's closed form for one sample (:func:`spa.model.plant.segment_pressure_scalar`),
#: compiled for the loop.
_segment = njit(cache=True)(segment_pressure_scalar)


@njit(cache=True)
def _advance(on, p, e, c1, k2, tau2, lawful, la):  # pragma: no cover  (compiled)
    # One mode's pressure after e active seconds: the valve's laws (their time maps) or the
    # paper's closed form.
    if lawful:
        return law_step(
            on, p, e, la[0], la[1], la[2], la[3], la[4], la[5], la[6], la[7], la[8], la[9],
            la[10], la[11],
        )  # fmt: skip
    return _segment(on, p, e, c1, k2, tau2)


@njit(cache=True)
def _loop(  # pragma: no cover  (compiled; its Python body is run by the tests)
    r,
    dt,
    p0,
    i0,
    plant,
    grid,
    kp,
    ki,
    ff_r,
    ff_xi,
    kind,
    cfg,
    st,
    p_out,
    xi_out,
    u_out,
    k2_at,
    k2_new,
    noise,
    lawful,
    la,
    lb,
):
    # lawful: the plant follows its laws' time maps, la (lb: those of the valve whose supply
    # is k2_new, from step k2_at on) as loop_laws gives them; else the paper's closed forms.
    c1, k2, tau2, t_on, t_off = plant[0], plant[1], plant[2], plant[3], plant[4]
    # The transport convention (plant[5] == 1): each command edge reaches the plant after its
    # delay and the plant keeps its previous connection meanwhile; the edges in flight wait
    # in a queue, and one that arrives no later than the edge before it cancels both
    # (spa.model.plant.transport_runs).
    transport = plant.size > 5 and plant[5] > 0.5
    cap = int(max(t_on, t_off) / dt) + 4
    q_t = np.empty(cap)
    q_l = np.zeros(cap, dtype=np.int64)
    q_head = 0
    q_n = 0
    plevel = 0
    t_start = 0.0
    noisy = noise.size > 0
    integ = i0
    level = 0
    start = 0
    hold = 0.0
    p_start = p0
    r_prev = math.nan
    g_kp = g_ki = g_ff = 0.0
    for k in range(r.size):
        # The pressure at t_k: the closed form of the run in progress.
        if transport:
            tk = k * dt
            while q_n > 0 and q_t[q_head] <= tk:
                p_start = _advance(
                    plevel == 1, p_start, q_t[q_head] - t_start, c1, k2, tau2, lawful, la
                )
                t_start = q_t[q_head]
                plevel = q_l[q_head]
                q_head = (q_head + 1) % cap
                q_n -= 1
            p = (
                p0
                if k == 0
                else _advance(plevel == 1, p_start, tk - t_start, c1, k2, tau2, lawful, la)
            )
        elif k == 0:
            p = p0
        else:
            p = _advance(
                level == 1, p_start, k * dt - (start * dt + hold), c1, k2, tau2, lawful, la
            )
        if k == k2_at:
            # The supply changes at t_k: the run in progress restarts from p_k (the closed
            # forms compose), with what is left of its hold.
            hold = max(start * dt + hold - k * dt, 0.0)
            p_start = p
            start = k
            t_start = k * dt
            k2 = k2_new
            la = lb
        # The controller: gains and feed-forward at the set-point, conditional integration.
        rk = r[k]
        if rk != r_prev:
            g_kp = _interp(rk, grid, kp)
            g_ki = _interp(rk, grid, ki)
            g_ff = _interp(rk, ff_r, ff_xi)
            r_prev = rk
        e = rk - (p + noise[k]) if noisy else rk - p
        v = g_kp * e + integ + g_ff
        xi = min(max(v, 0.0), 1.0)
        if not ((v > 1.0 and e > 0.0) or (v < 0.0 and e < 0.0)):
            integ += g_ki * dt * e
        # The modulator over [t_k, t_k+1); a change of command starts a new run.
        u = kernels.step(kind, k, xi, cfg, st)
        if k == 0:
            level = u
            plevel = u
        elif u != level:
            if transport:
                arrival = k * dt + (t_on if u == 1 else t_off)
                last = (q_head + q_n - 1) % cap
                if q_n > 0 and arrival <= q_t[last]:
                    q_n -= 1  # overtakes the edge in flight before it: neither arrives
                else:
                    q_t[(q_head + q_n) % cap] = arrival
                    q_l[(q_head + q_n) % cap] = u
                    q_n += 1
            else:
                # The pressure the run of (k - start)*dt - hold active seconds leaves.
                p_start = _advance(
                    level == 1, p_start, max((k - start) * dt - hold, 0.0), c1, k2, tau2,
                    lawful, la,
                )  # fmt: skip
                start = k
                hold = t_on if u == 1 else t_off
            level = u
        p_out[k] = p
        xi_out[k] = xi
        u_out[k] = u


@njit(cache=True)
def _loop_many(  # pragma: no cover  (compiled; its Python body is run by the tests)
    r, dt, p0s, i0s, plants, grid, kp, ki, ff_r, ff_xi, kind, cfg, initial, p_out, xi_out, u_out
):
    # _loop once per plant (row of `plants`), each from the modulator's initial state; the
    # paper's laws (valves with their own laws run plant by plant, each with its tables).
    noise = np.empty(0)
    for j in range(plants.shape[0]):
        st = initial.copy()
        _loop(
            r, dt, p0s[j], i0s[j], plants[j], grid, kp, ki, ff_r, ff_xi, kind, cfg, st,
            p_out[j], xi_out[j], u_out[j], -1, plants[j, 1], noise, False, _NO_LAWS, _NO_LAWS,
        )  # fmt: skip


def _plant_row(v: ValveParams) -> npt.NDArray[np.float64]:
    """The plant as the compiled loop reads it: the five parameters and the convention
    (1.0 for the transport delay)."""
    flag = 1.0 if v.delay == "transport" else 0.0
    return np.array([v.c1, v.k2, v.tau2, v.t_on, v.t_off, flag], dtype=np.float64)


def _checked_loop(
    modulator: Any, controller: PIController, dt: float, reference: npt.ArrayLike
) -> tuple[float, Modulator, dict[str, Any], np.ndarray]:
    """The closed loop's arguments, checked once: ``dt``, the setting (a kind with a
    closed-loop kernel, its settings valid at ``dt``) and the reference."""
    dt = checks.positive("dt", dt, "s")
    if not isinstance(controller, PIController):
        raise ValueError(f"controller must be a PIController, got {controller!r}")
    mod = Modulator.from_mapping(modulator)
    if mod.kind not in KERNELS:
        raise ValueError(f"no closed-loop kernel for modulator kind {mod.kind!r}")
    settings = dict(mod.settings)
    from spa.model.modulators import check_settings

    check_settings(mod.kind, dt, **settings)
    return dt, mod, settings, checks.finite_array("reference", reference, ndim=1)


def closed_loop_many(
    reference: npt.ArrayLike,
    dt: float,
    modulator: Modulator | dict[str, Any],
    controller: PIController,
    valves: list[ValveParams],
    p0: npt.ArrayLike,
    integral0: npt.ArrayLike,
    *,
    compiled: bool = True,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`closed_loop_arrays` for several plants in one compiled call.

    Parameters
    ----------
    reference, dt, modulator, controller : as :func:`closed_loop_arrays`
    valves : list of ValveParams
        The plants (e.g. the estimate and the corners of a box).
    p0, integral0 : array_like, shape (len(valves),)
        Each plant's starting pressure (bar) and integrator.
    compiled : bool, default True
        False runs the same loops as plain Python (for the tests).

    Returns
    -------
    p, xi, valve : numpy.ndarray, shape (len(valves), n)
        Row ``j`` equals ``closed_loop_arrays(..., valves[j], p0[j], integral0=integral0[j])``.
    """
    dt, mod, settings, r = _checked_loop(modulator, controller, dt, reference)
    m = len(valves)
    p0s = np.asarray(p0, dtype=np.float64).reshape(m)
    i0s = np.asarray(integral0, dtype=np.float64).reshape(m)
    if np.any(p0s < 0.0) or not np.all(np.isfinite(p0s)):
        raise ValueError("p0: expected finite pressures >= 0 bar")
    kernel = KERNELS[mod.kind]
    plants = np.array([_plant_row(v) for v in valves], dtype=np.float64)
    n = r.size
    p, xi, u = np.empty((m, n)), np.empty((m, n)), np.empty((m, n), dtype=np.int8)
    initial = np.array(kernel.INITIAL, dtype=np.float64)
    laws = [loop_laws(v) for v in valves]
    code = kernels.code(mod.kind)
    if compiled and not any(lawful for lawful, _ in laws):
        cfg = kernel.configure(settings, dt, valves[0] if valves else None)
        args = (*controller.arrays(), code, cfg)
        _loop_many(r, dt, p0s, i0s, plants, *args, initial, p, xi, u)
        return p, xi, u
    run = _loop if compiled else _loop.py_func
    for j, (lawful, la) in enumerate(laws):  # plant by plant, each with its tables
        cfg = kernel.configure(settings, dt, valves[j])
        run(
            r, dt, p0s[j], i0s[j], plants[j], *controller.arrays(), code, cfg, initial.copy(),
            p[j], xi[j], u[j], -1, plants[j, 1], np.empty(0), lawful, la, la,
        )  # fmt: skip
    return p, xi, u


def closed_loop_arrays(
    reference: npt.ArrayLike,
    dt: float,
    modulator: Modulator | dict[str, Any],
    controller: PIController,
    params: ValveParams | None = None,
    p0: float = 0.0,
    *,
    integral0: float = 0.0,
    compiled: bool = True,
    k2_change: tuple[int, float] | None = None,
    sensor_noise: npt.ArrayLike | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The closed loop's ``(p, xi, valve)`` arrays (see :func:`simulate_closed_loop`).

    ``integral0`` as :func:`simulate_closed_loop`. Disturbances a bench has:
    ``k2_change = (k, k2)`` sets the supply pressure to ``k2`` from ``t_k`` on (``k >= 1``;
    the run in progress restarts from ``p_k``); ``sensor_noise`` (shape ``(n,)``, bar) is
    added to the pressure the controller reads (``p`` stays the actuator's).

    ``compiled=False`` runs the same loop as plain Python (slow; for the tests).
    """
    params = valve_params(params)
    p0 = checks.nonnegative("p0", p0, "bar")
    dt, mod, settings, r = _checked_loop(modulator, controller, dt, reference)
    kernel = KERNELS[mod.kind]
    n = r.size
    p, xi, u = np.empty(n), np.empty(n), np.empty(n, dtype=np.int8)
    plant = _plant_row(params)
    args = (r, dt, p0, float(integral0), plant, *controller.arrays())
    state = np.array(kernel.INITIAL, dtype=np.float64)
    cfg = kernel.configure(settings, dt, params)
    k2_at, k2_new = -1, params.k2
    lawful, la = loop_laws(params)
    lb = la
    if k2_change is not None:
        k2_at = int(k2_change[0])
        k2_new = checks.positive("k2_change supply", k2_change[1], "bar")
        if not 1 <= k2_at < n:
            raise ValueError(f"k2_change: step {k2_at} outside 1..{n - 1}")
        lb = loop_laws(replace(params, k2=k2_new))[1]
    noise = np.empty(0)
    if sensor_noise is not None:
        noise = checks.finite_array("sensor_noise", sensor_noise, ndim=1)
        if noise.size != n:
            raise ValueError(f"sensor_noise: {noise.size} samples for a reference of {n}")
    run = _loop if compiled else _loop.py_func
    run(*args, kernels.code(mod.kind), cfg, state, p, xi, u, k2_at, k2_new, noise, lawful, la, lb)
    return p, xi, u


def simulate_closed_loop(
    reference: npt.ArrayLike,
    dt: float,
    modulator: Modulator | dict[str, Any],
    controller: PIController,
    params: ValveParams | None = None,
    p0: float = 0.0,
    *,
    integral0: float = 0.0,
) -> pd.DataFrame:
    """Exact pressure of the actuator under PI control through a pulse modulator.

    Parameters
    ----------
    reference : array_like of float, shape (n,)
        Set-point ``r[k]`` at ``t_k = k*dt``, bar.
    dt : float
        Step shared by the controller and the modulator, s.
    modulator : Modulator or mapping
        The modulator setting, e.g. ``{"type": "iipfm", "t_l": 0.02, "gain": 1.15}``.
    controller : PIController
        Gains (fixed or scheduled over the set-point) and optional feed-forward.
    params : ValveParams, optional
        The plant; nominal when omitted.
    p0 : float, optional
        Pressure at ``t = 0``, bar; the valve is settled at ``t = 0``.
    integral0 : float, optional
        The integrator's state ``I_0`` (input fraction): ``xi_ff(r_0)`` starts a PI without
        feed-forward settled at the equilibrium of ``r_0``.

    Returns
    -------
    pandas.DataFrame
        Columns ``t`` (s), ``r`` (bar), ``p`` (bar, the pressure the controller read at
        ``t_k``), ``xi`` (the controller's output over ``[t_k, t_k+1)``) and ``valve`` (the
        command over ``[t_k, t_k+1)``, int8).

    Raises
    ------
    ValueError
        For a non-finite reference, a bad step, ``p0`` or controller, or a modulator
        setting that does not fit the step.

    Notes
    -----
    At ``t_k`` the controller reads ``p_k``, forms ``e_k = r_k - p_k`` and
    ``xi_k = clip(Kp(r_k)*e_k + I_k + xi_ff(r_k), 0, 1)``; ``I_{k+1} = I_k + Ki(r_k)*dt*e_k``
    unless ``xi_k`` is clipped and ``e_k`` pushes it further out. ``xi_k`` drives the
    modulator exactly as in open loop (fed ``xi``, the loop gives
    :func:`spa.model.modulators.modulate`'s command and :func:`spa.model.plant.simulate`'s
    pressure to 1e-12), and the command drives the exact four-state plant.

    Examples
    --------
    >>> c = PIController(kp=1.0, ki=2.0)
    >>> df = simulate_closed_loop([0.4] * 4000, 1e-3, {"type": "iipfm", "t_l": 0.02}, c)
    >>> bool(abs(df["p"].iloc[-500:].mean() - 0.4) < 0.02)
    True
    """
    p, xi, u = closed_loop_arrays(
        reference, dt, modulator, controller, params, p0, integral0=integral0
    )
    n = p.size
    t = np.arange(n, dtype=np.float64) * dt
    r = np.asarray(reference, dtype=np.float64)
    return pd.DataFrame({"t": t, "r": r, "p": p, "xi": xi, "valve": u})
