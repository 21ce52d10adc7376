"""Plain per-step reference implementations, written straight from docs/model.md for the tests.

Slow on purpose: one Python iteration per sample, no cleverness, so the vectorised code in
``spa`` can be checked against the literal rules.
"""

from __future__ import annotations

import math

import numpy as np

EPS = 1e-9


def pwm(xi, dt, f_w):
    period = 1.0 / f_w
    u = np.zeros(len(xi), dtype=np.int8)
    n_prev, x_held, t_start = -1, 0.0, 0.0
    for k, x in enumerate(np.clip(xi, 0, 1)):
        t = k * dt
        n = math.floor(t / period + EPS)
        if n != n_prev:  # a new period starts in this step: sample xi
            n_prev, x_held, t_start = n, x, n * period
        u[k] = 1 if t < t_start + x_held * period - EPS * dt else 0
    return u


def _integrate_and_fire(xi, dt, width, gain, high_pulses):
    threshold = gain * width
    n_width = max(1, math.floor(width / dt + 0.5))
    u = np.zeros(len(xi), dtype=np.int8)
    acc, remaining = 0.0, 0
    for k, x in enumerate(np.clip(xi, 0, 1)):
        # acc is the integral up to t_k (exclusive of this step)
        if acc >= threshold * (1 - EPS):
            acc -= threshold
            remaining = n_width  # a new firing (re)starts a full-width pulse
        pulse = remaining > 0
        if remaining > 0:
            remaining -= 1
        u[k] = int(pulse) if high_pulses else int(not pulse)
        acc += (x if high_pulses else 1.0 - x) * dt
    return u


def ipfm(xi, dt, t_h, gain=1.0):
    return _integrate_and_fire(xi, dt, t_h, gain, high_pulses=True)


def iipfm(xi, dt, t_l, gain=1.0):
    return _integrate_and_fire(xi, dt, t_l, gain, high_pulses=False)


def dsm(xi, dt, period):
    u = np.zeros(len(xi), dtype=np.int8)
    v, u_prev, m_prev = 0.0, 0, -1
    for k, x in enumerate(np.clip(xi, 0, 1)):
        m = math.floor(k * dt / period + EPS)
        if m != m_prev:  # clock tick
            m_prev = m
            v = v + x - u_prev
            u_prev = 1 if v >= 0.5 - EPS else 0
        u[k] = u_prev
    return u


MODULATE = {"pwm": pwm, "ipfm": ipfm, "iipfm": iipfm, "dsm": dsm}


def simulate(u, dt, params, p0=0.0):
    """Per-sample event-driven reference: state machine with explicit hold timers."""
    p = np.empty(len(u))
    pressure = p0
    hold_left = 0.0
    for k in range(len(u)):
        if k > 0 and u[k] != u[k - 1]:
            hold_left = params.t_on if u[k] else params.t_off
        p[k] = pressure
        # advance over [k dt, (k+1) dt)
        active = max(dt - hold_left, 0.0)
        hold_left = max(hold_left - dt, 0.0)
        if active > 0:
            if u[k]:
                pressure = params.k2 + (pressure - params.k2) * math.exp(-active / params.tau2)
            else:
                r = math.sqrt(pressure) - active / (2 * params.c1)
                pressure = r * r if r > 0 else 0.0
    return p
