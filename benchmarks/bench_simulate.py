"""Benchmark: spa.modulate + spa.simulate against scipy's solve_ivp on the same hybrid model.

For each modulator at the paper's settings, a 55 s staircase (xi from 0 to 1 by 0.1 every
5 s) at dt = 1e-4 s (550,000 samples):

* spa: ``modulate`` then ``simulate`` (closed forms, one Python step per valve edge);
* reference A, per-sample state machine (tests/reference.py): the same closed forms stepped
  sample by sample in pure Python; gives the "closed form" truth independently of spa's
  vectorisation;
* solve_ivp, the way a careful researcher writes it: RK45 restarted at every valve edge and
  at the end of every t_on/t_off hold (so no step straddles a switch), dense output
  evaluated at the sample times, rtol = 1e-10, atol = 1e-12.

Reports wall times (best of several repeats for spa), speed-up, largest errors, and spa's
throughput in samples per second on one core.

Run:  .venv/bin/python benchmarks/bench_simulate.py
"""

from __future__ import annotations

import math
import sys
import time
from pathlib import Path

import numpy as np
from scipy.integrate import solve_ivp

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from spa import ValveParams, modulate, simulate

import reference

DT = 1e-4
DURATION = 55.0
SETTINGS = {
    "pwm": {"f_w": 20.0},
    "ipfm": {"t_h": 0.020},
    "iipfm": {"t_l": 0.020, "gain": 1.15},
    "dsm": {"period": 0.020},
}


def staircase(dt: float = DT, duration: float = DURATION) -> np.ndarray:
    t = np.arange(round(duration / dt)) * dt
    return np.minimum(np.floor(t / 5.0 + 1e-9) / 10.0, 1.0)


def solve_ivp_hybrid(u: np.ndarray, dt: float, params: ValveParams) -> np.ndarray:
    """Integrate the four-state model with solve_ivp, restarting at every switching event."""
    n = u.size
    t_samples = np.arange(n) * dt
    edges = np.flatnonzero(u[1:] != u[:-1]) + 1
    starts = np.concatenate(([0], edges))
    ends = np.append(edges, n)
    p = np.empty(n)
    pressure = 0.0

    def charging(_t, y):
        return (params.k2 - y) / params.tau2

    def exhausting(_t, y):
        return -np.sqrt(np.maximum(y, 0.0)) / params.c1

    for j, (s, e) in enumerate(zip(starts, ends, strict=True)):
        on = bool(u[s])
        t0, t1 = s * dt, e * dt
        hold = 0.0 if j == 0 else (params.t_on if on else params.t_off)
        t_active = min(t0 + hold, t1)
        idx = np.arange(s, e)
        held = t_samples[idx] <= t_active
        p[idx[held]] = pressure
        if t_active < t1:
            rhs = charging if on else exhausting
            sol = solve_ivp(
                rhs,
                (t_active, t1),
                [pressure],
                method="RK45",
                rtol=1e-10,
                atol=1e-12,
                dense_output=True,
            )
            later = idx[~held]
            if later.size:
                p[later] = np.maximum(sol.sol(t_samples[later])[0], 0.0)
            pressure = max(float(sol.y[0, -1]), 0.0)
    return p


def solve_ivp_max_step(u: np.ndarray, dt: float, params: ValveParams) -> np.ndarray:
    """One solve_ivp call over the whole run with ``max_step = dt`` and a hybrid right-hand side.

    The right-hand side looks up the command and the time since the last edge, so the holds
    are honoured; ``max_step = dt`` keeps the solver from stepping over a switch unseen.
    """
    n = u.size
    starts = np.concatenate(([0], np.flatnonzero(u[1:] != u[:-1]) + 1))
    level = u[starts].astype(bool)

    def rhs(t, y):
        j = int(np.searchsorted(starts, min(int(t / dt + 1e-9), n - 1), side="right")) - 1
        on = level[j]
        hold = 0.0 if j == 0 else (params.t_on if on else params.t_off)
        if t - starts[j] * dt < hold:
            return [0.0]
        if on:
            return [(params.k2 - y[0]) / params.tau2]
        return [-math.sqrt(max(y[0], 0.0)) / params.c1]

    t_eval = np.arange(n) * dt
    sol = solve_ivp(
        rhs,
        (0.0, t_eval[-1]),
        [0.0],
        method="RK45",
        t_eval=t_eval,
        max_step=dt,
        rtol=1e-8,
        atol=1e-10,
    )
    return sol.y[0]


def best_of(fn, repeats: int) -> tuple[float, object]:
    best, out = math.inf, None
    for _ in range(repeats):
        t0 = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t0)
    return best, out


def main() -> None:
    params = ValveParams()
    xi = staircase()
    n = xi.size
    print(f"55 s staircase, dt = {DT:g} s, {n} samples per run; nominal parameters")
    header = (
        f"{'modulator':10s} {'edges':>6s} {'spa [ms]':>9s} {'Msamples/s':>10s} "
        f"{'solve_ivp [s]':>13s} {'speed-up':>9s} {'|spa-ref| [bar]':>15s} "
        f"{'|ivp-spa| [bar]':>15s}"
    )
    print(header)
    rows = []
    for kind, s in SETTINGS.items():
        t_spa, p_spa = best_of(
            lambda k=kind, s=s: simulate(modulate(k, xi, DT, **s), DT, params), 7
        )
        t_mod, u = best_of(lambda k=kind, s=s: modulate(k, xi, DT, **s), 7)
        p_ref = reference.simulate(u, DT, params)
        t0 = time.perf_counter()
        p_ivp = solve_ivp_hybrid(u, DT, params)
        t_ivp = time.perf_counter() - t0
        err_ref = float(np.abs(p_spa - p_ref).max())
        err_ivp = float(np.abs(p_ivp - p_spa).max())
        edges = int(np.count_nonzero(np.diff(u)))
        rows.append((kind, t_spa, t_ivp, err_ref, err_ivp))
        print(
            f"{kind:10s} {edges:6d} {t_spa * 1e3:9.1f} {n / t_spa / 1e6:10.1f} "
            f"{t_ivp:13.2f} {t_ivp / t_spa:9.0f} {err_ref:15.2e} {err_ivp:15.2e}"
            f"   (modulate alone {t_mod * 1e3:.1f} ms)"
        )
    print("\nsolve_ivp with max_step = dt over the whole run (the other usual way), first 11 s:")
    n11 = round(11.0 / DT)
    for kind, s in SETTINGS.items():
        u = modulate(kind, xi, DT, **s)[:n11]
        t_spa, p_spa = best_of(lambda u=u: simulate(u, DT, params), 7)
        t0 = time.perf_counter()
        p_ivp = solve_ivp_max_step(u, DT, params)
        t_ivp = time.perf_counter() - t0
        print(
            f"{kind:10s} spa {t_spa * 1e3:6.1f} ms  solve_ivp {t_ivp:6.1f} s  "
            f"speed-up {t_ivp / t_spa:7.0f}x  "
            f"largest |ivp - spa| {np.abs(p_ivp - p_spa).max():.1e} bar"
        )
    total_spa = sum(r[1] for r in rows)
    total_ivp = sum(r[2] for r in rows)
    print(
        f"all four: spa {total_spa * 1e3:.1f} ms ({4 * n / total_spa / 1e6:.1f} Msamples/s), "
        f"solve_ivp {total_ivp:.1f} s, speed-up {total_ivp / total_spa:.0f}x, "
        f"largest |spa - per-sample closed form| {max(r[3] for r in rows):.1e} bar"
    )


if __name__ == "__main__":
    main()
