"""A physical test plant that is not the paper's model: orifice flow, a compliant chamber, a
spool with dead times and transit, a drooping regulator and a lagging, quantised sensor.

The paper's four-state model (:func:`spa.simulate`) is exact for itself; a bench is not that
model. This plant is a *test fixture*: data made by it check that identification, design and
the exported controllers hold on a plant whose physics differ from the model's. It is
integrated with a fixed-step classical Runge-Kutta scheme (compiled with numba; the same
step in plain Python and in C, ``physical_plant.c``, agree with it), which is fine for a
fixture and never used by the simulator.

Physics (docs/model.md, "A physical plant for testing"; absolute pressures inside, gauge at
the interface):

* **Valve ports**: a 3/2 valve connects the chamber to the supply (command 1) or to the
  exhaust (command 0). Each port is an ISO 6358-1:2013 orifice with sonic conductance ``C``,
  critical pressure ratio ``b`` and subsonic index ``m``: choked flow ``C*p1*rho0`` below
  ``b``, ``C*p1*rho0*(1 - ((r - b)/(1 - b))**2)**m`` above it (``r = p2/p1``), made linear
  in ``1 - r`` above ``r = 0.999`` (the laminar region, so that the flow is Lipschitz at
  equilibrium). Air enters at the reference temperature ``T0``.
* **Spool**: after a command edge the armature waits its dead time (``t_open`` after a
  rising edge, ``t_close`` after a falling one) while the *previous connection persists*;
  then the spool crosses over in ``transit`` s, the effective conductances changing
  linearly (supply ``C_s*s``, exhaust ``C_e*(1 - s)``, ``s`` the spool position 0..1). An
  edge whose dead time ends before that of an earlier pending edge cancels it.
* **Chamber**: polytropic with index ``n`` (1: isothermal, 1.4: adiabatic), volume growing
  linearly with the gauge pressure, ``V = V0 + k_v*(P - p_atm)``:
  ``dP/dt = n*R*T0*q / (V + n*P*k_v)`` with ``q`` the net mass flow in.
* **Regulator**: first order, sagging with the flow drawn:
  ``dPs/dt = (p_set - droop*q_s/rho0 - Ps)/tau_r``.
* **Sensor**: first-order lag ``tau_s`` on the gauge pressure, plus a mains pickup
  ``A*sin(2*pi*f*t + phase)``, plus seeded Gaussian noise, rounded to the ADC step.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np
import numpy.typing as npt
import pandas as pd
from numba import njit

from spa.synthetic._physical_core import (  # noqa: F401  (the plant's settings and constants)
    _BAR,
    _CM3,
    _DM3_PER_S_BAR,
    PHYSICAL_KEYS,
    QUEUE,
    R_AIR,
    RHO0,
    PhysicalPlant,
    _check_dt,
    _constants,
    substeps,
)

__all__ = [
    "PHYSICAL_KEYS",
    "PhysicalPlant",
    "c_plant_source",
    "close_loop_in_c",
    "closed_loop_physical",
    "equivalent_params",
    "header_setting",
    "measure_staircase",
    "random_plant",
    "run_plant_in_c",
    "sensor_output",
    "simulate_physical",
    "substeps",
]

# ---- the kernels (compiled; the tests run them as plain Python too) ------------------------
# State x: [P (Pa abs), Ps (Pa abs), y (sensor, Pa gauge), s_ref, t_ref, v_ref, last command,
#           spare, T (gas, K), Vc (creeping volume, m^3), Pt (sensor port, Pa abs),
#           Ph (supply hose, Pa abs)]; queue: pending armature switches (time, value) in a
# ring buffer qt/qv with qi = [head, count]. The integrated states are x[_Z]; the work
# array w (5, NZ) holds the derivative (w[0]), the stages k1..k3 and the stage's state.

#: Indices of the integrated states in x.
_Z = (0, 1, 2, 8, 9, 10, 11)
NZ = 7
NX = 12


@njit(cache=True)
def _flow(p1, p2, cond, b, m, rho0, blam):  # pragma: no cover (compiled)
    """ISO 6358-1 mass flow from p1 to p2 (kg/s, negative when p2 > p1)."""
    if p1 >= p2:
        up, dn, sgn = p1, p2, 1.0
    else:
        up, dn, sgn = p2, p1, -1.0
    if up <= 0.0 or cond <= 0.0:
        return 0.0
    r = dn / up
    if r <= b:
        phi = 1.0
    elif r <= blam:
        z = (r - b) / (1.0 - b)
        phi = (1.0 - z * z) ** m
    else:
        z = (blam - b) / (1.0 - b)
        phi = (1.0 - z * z) ** m * (1.0 - r) / (1.0 - blam)
    return sgn * cond * up * rho0 * phi


@njit(cache=True)
def _spool(t, x, c):  # pragma: no cover (compiled)
    """Spool position at time t of the current segment (x[3] at x[4], towards x[5]), with
    its rebound at the end stop when the valve bounces (c[27] > 0)."""
    direction = 1.0 if x[5] > 0.5 else -1.0
    s = x[3] + (t - x[4]) * direction / c[16]
    if c[27] > 0.0:
        hit = x[4] + abs(x[5] - x[3]) * c[16]
        if abs(x[5] - x[3]) > 0.0 and t > hit:
            a = t - hit
            b = c[27] * math.exp(-a / c[28]) * abs(math.sin(math.pi * a / c[28]))
            return 1.0 - b if direction > 0.0 else b
    if s < 0.0:
        return 0.0
    if s > 1.0:
        return 1.0
    return s


@njit(cache=True)
def _events(t, x, qt, qv, qi, c):  # pragma: no cover (compiled)
    """Apply every pending armature switch due by time t (the spool segment restarts)."""
    while qi[1] > 0 and qt[qi[0]] <= t:
        tau = qt[qi[0]]
        x[3] = _spool(tau, x, c)
        x[4] = tau
        x[5] = qv[qi[0]]
        qi[0] = (qi[0] + 1) % qt.size
        qi[1] -= 1


@njit(cache=True)
def _rhs(z, s, c, d):  # pragma: no cover (compiled)
    """Derivatives of the integrated states z = (P, Ps, y, T, Vc, Pt, Ph) at spool position
    s into d. Each effect whose constant is 0 drops out exactly (the plant without them
    computes the same operations as before they existed)."""
    p, ps, y = z[0], z[1], z[2]
    up = z[6] if c[25] > 0.0 else ps
    q_in = _flow(up, p, c[5] * s, c[6], c[7], c[4], c[19])
    q_out = _flow(p, c[0], c[8] * (1.0 - s), c[9], c[10], c[4], c[19])
    if c[20] > 0.0:
        q_out = q_out + c[20] * c[4] * (p - c[0])
    vol = c[11] + c[12] * (p - c[0])
    dvc = 0.0
    if c[22] > 0.0:
        vol = vol + z[4]
        dvc = (c[22] * (p - c[0]) - z[4]) / c[23]
    d[4] = dvc
    if c[21] > 0.0:
        tg = z[3]
        r_gas = c[3] / c[29]
        heat = p * vol * (c[29] - tg) / (tg * c[21])
        d[0] = (c[2] * r_gas * (q_in * c[29] - q_out * tg) + heat - c[2] * p * dvc) / (
            vol + c[2] * p * c[12]
        )
        mass = p * vol / (r_gas * tg)
        d[3] = tg * (d[0] / p + (c[12] * d[0] + dvc) / vol - (q_in - q_out) / mass)
    else:
        if c[22] > 0.0:
            d[0] = (c[2] * c[3] * (q_in - q_out) - c[2] * p * dvc) / (vol + c[2] * p * c[12])
        else:
            d[0] = c[2] * c[3] * (q_in - q_out) / (vol + c[2] * p * c[12])
        d[3] = 0.0
    q_reg = q_in
    if c[25] > 0.0:
        q_reg = _flow(ps, z[6], c[26], 0.3, 0.5, c[4], c[19])
        d[6] = c[3] * (q_reg - q_in) / c[25]
    else:
        d[6] = 0.0
    d[1] = (c[1] - c[13] * q_reg / c[4] - ps) / c[14]
    src = p
    if c[24] > 0.0:
        d[5] = (p - z[5]) / c[24]
        src = z[5]
    else:
        d[5] = 0.0
    if c[15] > 0.0:
        d[2] = (src - c[0] - y) / c[15]
    else:
        d[2] = 0.0


@njit(cache=True)
def _command(x, qt, qv, qi, tk, u, c):  # pragma: no cover (compiled)
    """The command u (0/1) from time tk on: an edge schedules the armature's switch."""
    v = 1.0 if u != 0 else 0.0
    if v == x[6]:
        return
    tau = tk + (c[17] if v > 0.5 else c[18])
    # a switch due no earlier than this one is overtaken by it
    while qi[1] > 0 and qt[(qi[0] + qi[1] - 1) % qt.size] >= tau:
        qi[1] -= 1
    if qi[1] == qt.size:
        raise ValueError("physical plant: too many pending valve edges (dead time / dt)")
    j = (qi[0] + qi[1]) % qt.size
    qt[j] = tau
    qv[j] = v
    qi[1] += 1
    x[6] = v


@njit(cache=True)
def _advance(x, qt, qv, qi, tk, dt, nsub, c, w):  # pragma: no cover (compiled)
    """Integrate the plant from tk over one controller step dt (nsub RK4 steps)."""
    h = dt / nsub
    d, k1, k2, k3, zt = w[0], w[1], w[2], w[3], w[4]
    z = np.empty(NZ)
    for i in range(nsub):
        t = tk + i * h
        for j in range(NZ):
            z[j] = x[_Z[j]]
        _events(t, x, qt, qv, qi, c)
        _rhs(z, _spool(t, x, c), c, d)
        for j in range(NZ):
            k1[j] = d[j]
            zt[j] = z[j] + 0.5 * h * k1[j]
        _events(t + 0.5 * h, x, qt, qv, qi, c)
        s2 = _spool(t + 0.5 * h, x, c)
        _rhs(zt, s2, c, d)
        for j in range(NZ):
            k2[j] = d[j]
            zt[j] = z[j] + 0.5 * h * k2[j]
        _rhs(zt, s2, c, d)
        for j in range(NZ):
            k3[j] = d[j]
            zt[j] = z[j] + h * k3[j]
        _events(t + h, x, qt, qv, qi, c)
        _rhs(zt, _spool(t + h, x, c), c, d)
        for j in range(NZ):
            x[_Z[j]] = z[j] + h / 6.0 * (k1[j] + 2.0 * k2[j] + 2.0 * k3[j] + d[j])
        if c[15] <= 0.0:
            x[2] = (x[10] if c[24] > 0.0 else x[0]) - c[0]


@njit(cache=True)
def _init(x, qi, p0, c, u0):  # pragma: no cover (compiled)
    """Rest at p0 (Pa gauge) with the valve settled at command u0 and no flow drawn."""
    x[0] = c[0] + p0
    x[1] = c[1]
    x[2] = p0
    x[3] = 1.0 if u0 != 0 else 0.0
    x[4] = 0.0
    x[5] = x[3]
    x[6] = x[3]
    x[7] = 0.0
    x[8] = c[29]
    x[9] = c[22] * p0
    x[10] = x[0]
    x[11] = c[1]
    qi[0] = 0
    qi[1] = 0


@njit(cache=True)
def _run(u, dt, nsub, every, c, p0, u0, p_out, y_out):  # pragma: no cover (compiled)
    """The open-loop run: command u[k] over [k*dt, (k+1)*dt); samples every `every` steps
    of the chamber's gauge pressure (p_out) and of the lagged sensor (y_out), Pa."""
    x = np.zeros(NX)
    qt = np.zeros(QUEUE)
    qv = np.zeros(QUEUE)
    qi = np.zeros(2, dtype=np.int64)
    d = np.zeros((5, NZ))
    _init(x, qi, p0, c, u0)
    j = 0
    for k in range(u.size):
        tk = k * dt
        if k % every == 0:
            p_out[j] = x[0] - c[0]
            y_out[j] = x[2]
            j += 1
        _command(x, qt, qv, qi, tk, u[k], c)
        _advance(x, qt, qv, qi, tk, dt, nsub, c, d)


# ---- the public functions --------------------------------------------------------------


def _every(fs: float, dt: float) -> int:
    ratio = 1.0 / (float(fs) * dt)
    every = round(ratio)
    if every < 1 or abs(ratio - every) > 1e-6:
        raise ValueError(
            f"fs = {fs:g} Hz: 1/fs must be a whole number of controller steps dt = {dt:g} s"
        )
    return every


def sensor_output(
    t: npt.ArrayLike, lagged: npt.ArrayLike, plant: PhysicalPlant, noise: npt.ArrayLike | None
) -> np.ndarray:
    """What the logger records, bar: lagged pressure + mains pickup + noise, ADC-rounded.

    Parameters
    ----------
    t : array_like
        Sample times, s.
    lagged : array_like
        The sensor's lagged gauge pressure at ``t``, bar.
    plant : PhysicalPlant
        ``mains``, ``mains_frequency``, ``mains_phase``, ``quantum``.
    noise : array_like or None
        The noise sequence (bar, one per sample), or None for none.

    Examples
    --------
    >>> plant = PhysicalPlant(mains=0.0, quantum=0.01)
    >>> sensor_output([0.0, 0.001], [0.123, 0.456], plant, None).tolist()
    [0.12, 0.46]
    """
    tt = np.asarray(t, dtype=np.float64)
    out = np.asarray(lagged, dtype=np.float64).copy()
    if plant.mains > 0:
        phase = 2.0 * np.pi * plant.mains_frequency * tt + plant.mains_phase
        out = out + plant.mains * np.sin(phase)
    if noise is not None:
        out = out + np.asarray(noise, dtype=np.float64)
    if plant.quantum > 0:
        out = np.round(out / plant.quantum) * plant.quantum
    return out


def simulate_physical(
    plant: PhysicalPlant,
    valve: npt.ArrayLike,
    dt: float,
    *,
    fs: float | None = None,
    p0: float = 0.0,
    rng: np.random.Generator | None = None,
    u: npt.ArrayLike | None = None,
    settled: int | None = None,
    compiled: bool = True,
) -> pd.DataFrame:
    """Drive the physical plant with a valve command sampled at the controller step.

    Parameters
    ----------
    plant : PhysicalPlant
        The plant.
    valve : array_like of int, shape (n,)
        The command (0/1) over ``[k*dt, (k+1)*dt)``.
    dt : float
        Controller step, s, in [1e-5, 0.1].
    fs : float, optional
        Logging rate, Hz (``1/fs`` a whole number of steps); default every step.
    p0 : float, default 0
        Initial chamber pressure, bar gauge, at rest (the valve settled at ``valve[0]``,
        the regulator at its set-point, the sensor at ``p0``).
    rng : numpy.random.Generator, optional
        Source of the sensor noise (one draw of ``n`` normals when ``plant.noise > 0``);
        None: no noise.
    u : array_like, optional
        The input fraction at every step (copied into the table's ``u``, clipped to [0, 1]).
    settled : {0, 1}, optional
        The connection the valve rests at before ``t = 0`` (default ``valve[0]``: no edge at
        the start, as the model's runs; :func:`closed_loop_physical` starts from 0).
    compiled : bool, default True
        False runs the same step as plain Python (slow; for the tests).

    Returns
    -------
    pandas.DataFrame
        The canonical run table: ``t`` (s), ``p`` (bar gauge, as logged), ``valve`` (int8,
        the command at each sample) and ``u`` when given; ``attrs["p_true"]`` holds the
        chamber's gauge pressure and ``attrs["p_lagged"]`` the sensor's lagged pressure
        (bar) at the samples, before pickup, noise and ADC.

    Raises
    ------
    ValueError
        For a bad step, rate, command or initial pressure.
    """
    dt = _check_dt(plant, dt)
    cmd = np.asarray(valve)
    if cmd.ndim != 1 or cmd.size < 1:
        raise ValueError(f"valve: a non-empty 1-D command, got shape {cmd.shape}")
    if not np.all((cmd == 0) | (cmd == 1)):
        raise ValueError("valve: every command must be 0 or 1")
    cmd = cmd.astype(np.int8)
    every = 1 if fs is None else _every(fs, dt)
    p0 = float(p0)
    if not (math.isfinite(p0) and -plant.atmosphere < p0 <= 2.0 * plant.supply + 1.0):
        raise ValueError(f"p0 = {p0!r} bar gauge: outside the plant's range")
    idx = np.arange(0, cmd.size, every)
    p_true = np.zeros(idx.size)
    lagged = np.zeros(idx.size)
    start = int(cmd[0]) if settled is None else int(settled)
    if start not in (0, 1):
        raise ValueError(f"settled = {settled!r}: 0 or 1")
    run = _run if compiled else _run.py_func
    c = _constants(plant)
    run(cmd, dt, substeps(plant, dt), every, c, p0 * _BAR, start, p_true, lagged)
    p_true /= _BAR
    lagged /= _BAR
    t = idx * dt
    noisy = rng is not None and plant.noise > 0
    noise = rng.normal(0.0, plant.noise, idx.size) if noisy else None
    table = {"t": t, "p": sensor_output(t, lagged, plant, noise), "valve": cmd[idx]}
    if u is not None:
        table["u"] = np.clip(np.asarray(u, dtype=np.float64)[idx], 0.0, 1.0)
    out = pd.DataFrame(table)
    out.attrs["p_true"] = p_true
    out.attrs["p_lagged"] = lagged
    return out


# ---- what a designer would take from it, and plants at random ------------------------------


def _crossing(t: np.ndarray, p: np.ndarray, level: float, rising: bool) -> float:
    """First time p crosses level (linear between samples), NaN when never."""
    hit = np.flatnonzero(p >= level) if rising else np.flatnonzero(p <= level)
    if hit.size == 0:
        return math.nan
    i = int(hit[0])
    if i == 0:
        return float(t[0])
    a, b = p[i - 1], p[i]
    return float(t[i - 1] + (level - a) / (b - a) * (t[i] - t[i - 1]))


def equivalent_params(plant: PhysicalPlant, dt: float = 1e-3):
    """The paper's five parameters a designer would read off this plant's step responses.

    Not an identification (no noise, no fit): ``k2`` is the supply set-point; ``t_on`` and
    ``t_off`` are the dead times plus half the transit; ``tau2`` is the time the noise-free
    charge from 0 bar takes to 63.2 % of ``k2`` after ``t_on``; ``c1`` makes the model's
    discharge (Eq. A1, ``sqrt(P) = sqrt(k2) - t/(2*c1)``) reach ``k2/4`` when the plant's
    does: ``c1 = t25/sqrt(k2)``.

    Parameters
    ----------
    plant : PhysicalPlant
    dt : float
        Step of the responses simulated, s.

    Returns
    -------
    spa.model.params.ValveParams

    Examples
    --------
    >>> eq = equivalent_params(PhysicalPlant(t_open=0.004, transit=0.002))
    >>> eq.k2, round(eq.t_on, 6)
    (0.85, 0.005)
    """
    from spa.model.params import ValveParams

    k2 = plant.supply
    t_on = plant.t_open + 0.5 * plant.transit
    t_off = plant.t_close + 0.5 * plant.transit
    out = {}
    for name, first, level, start in (
        ("tau2", 0, (1.0 - math.exp(-1.0)) * k2, 0.0),
        ("t25", 1, 0.25 * k2, k2),
    ):
        duration = 2.0
        while True:
            n = round(duration / dt)
            u = np.full(n, 1 - first, dtype=np.int8)
            u[0] = first
            res = simulate_physical(plant, u, dt, p0=start)
            t = res["t"].to_numpy()
            cross = _crossing(t, res.attrs["p_true"], level, rising=first == 0)
            if math.isfinite(cross) or duration > 500.0:
                break
            duration *= 4.0
        if not math.isfinite(cross):
            raise ValueError(f"plant {plant}: the {name} response never crosses {level:g} bar")
        out[name] = cross - dt - (t_on if first == 0 else t_off)
    tau2 = max(out["tau2"], 1e-3)
    c1 = max(out["t25"], 1e-3) / math.sqrt(k2)
    return ValveParams(c1=c1, k2=k2, tau2=tau2, t_on=t_on, t_off=t_off)


from spa.synthetic._physical_c import (  # noqa: E402  (they use the plant above)
    c_plant_source,
    close_loop_in_c,
    header_setting,
    measure_staircase,
    run_plant_in_c,
)
from spa.synthetic.draws import random_plant  # noqa: E402


def closed_loop_physical(
    plant: PhysicalPlant,
    reference: npt.ArrayLike,
    dt: float,
    modulator: Mapping[str, Any],
    controller: Any,
    *,
    integral0: float = 0.0,
    rng: np.random.Generator | None = None,
) -> pd.DataFrame:
    """A PI and a modulator (:class:`spa.closedloop.ControllerStepper`) closed on the plant.

    From rest at 0 bar (exhaust open). Every controller step ``k`` the sensor is read at
    ``t_k`` (lag, mains pickup, noise, ADC step, as :func:`sensor_output`), the stepper gives
    the command, the plant integrates over the step. The loop steps in Python (a test
    fixture; the plant's step is compiled); :func:`close_loop_in_c` runs the same loop with
    an exported header in C.

    Parameters
    ----------
    plant : PhysicalPlant
    reference : array_like
        Set-point at every controller step, bar.
    dt : float
        Controller step, s.
    modulator : mapping
        The setting, e.g. ``{"type": "pwm", "f_w": 20.0}``.
    controller : spa.closedloop.PIController
    integral0 : float, default 0
        The integrator at start.
    rng : numpy.random.Generator, optional
        Sensor noise (one draw of ``n`` normals); None: none.

    Returns
    -------
    pandas.DataFrame
        ``t``, ``r``, ``p`` (what the controller read, bar gauge), ``valve``, ``u`` (``xi``)
        and ``p_true`` (the chamber's gauge pressure, bar), one row per step.
    """
    from spa.closedloop.stepper import ControllerStepper

    dt = _check_dt(plant, dt)
    r = np.asarray(reference, dtype=np.float64)
    n = r.size
    stepper = ControllerStepper(modulator, controller, dt, integral0)
    noisy = rng is not None and plant.noise > 0
    noise = rng.normal(0.0, plant.noise, n) if noisy else np.zeros(n)
    c = _constants(plant)
    nsub = substeps(plant, dt)
    x, qt, qv = np.zeros(NX), np.zeros(QUEUE), np.zeros(QUEUE)
    qi, d = np.zeros(2, dtype=np.int64), np.zeros((5, NZ))
    _init(x, qi, 0.0, c, 0)
    p_read, p_true, xi = np.zeros(n), np.zeros(n), np.zeros(n)
    valve = np.zeros(n, dtype=np.int8)
    w = 2.0 * math.pi * plant.mains_frequency
    for k in range(n):
        tk = k * dt
        y = x[2] / _BAR
        if plant.mains > 0:
            y = y + plant.mains * math.sin(w * tk + plant.mains_phase)
        y = y + noise[k]
        if plant.quantum > 0:
            y = round(y / plant.quantum) * plant.quantum
        p_read[k], p_true[k] = y, (x[0] - c[0]) / _BAR
        valve[k], xi[k] = stepper.step(r[k], y)
        _command(x, qt, qv, qi, tk, int(valve[k]), c)
        _advance(x, qt, qv, qi, tk, dt, nsub, c, d)
    t = np.arange(n) * dt
    return pd.DataFrame({"t": t, "r": r, "p": p_read, "valve": valve, "u": xi, "p_true": p_true})
