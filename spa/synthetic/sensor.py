"""The simulated sensor: Gaussian noise, ADC quantisation and ringing after each valve edge."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

__all__ = ["Ringing", "Sensor", "edge_declaration", "sensor_record"]

# ---- sensor -----------------------------------------------------------------------------


@dataclass(frozen=True)
class Ringing:
    """Damped oscillation added to the pressure after each valve edge.

    ``amplitude * exp(-damping*s) * sin(2*pi*frequency*s)`` at time ``s`` after the most
    recent edge, positive after an opening edge and negative after a closing one.
    """

    amplitude: float = 0.01  # bar
    frequency: float = 60.0  # Hz
    damping: float = 60.0  # 1/s


@dataclass(frozen=True)
class Sensor:
    """Pressure sensor and logger.

    Parameters
    ----------
    fs : float
        Logging rate in Hz; ``1/fs`` must be a whole number of controller steps.
    noise : float
        Standard deviation of additive Gaussian noise, bar.
    quantum : float
        ADC step, bar (0: none).
    ringing : Ringing, optional
        Damped ringing after each valve edge.
    """

    fs: float = 1000.0
    noise: float = 0.005
    quantum: float = 0.001
    ringing: Ringing | None = None

    @classmethod
    def from_mapping(cls, cfg: Mapping[str, Any] | None) -> Sensor:
        """Build from a config mapping (``fs``, ``noise``, ``quantum``, ``ringing``)."""
        cfg = dict(cfg or {})
        ring = cfg.pop("ringing", None)
        return cls(**cfg, ringing=Ringing(**ring) if ring else None)


def _ringing(t: np.ndarray, edge_t: np.ndarray, edge_sign: np.ndarray, r: Ringing) -> np.ndarray:
    out = np.zeros_like(t)
    if edge_t.size == 0:
        return out
    j = np.searchsorted(edge_t, t, side="right") - 1
    has = j >= 0
    s = t[has] - edge_t[j[has]]
    out[has] = (
        edge_sign[j[has]]
        * r.amplitude
        * np.exp(-r.damping * s)
        * np.sin(2 * np.pi * r.frequency * s)
    )
    return out


def sensor_record(
    t: npt.ArrayLike,
    p: npt.ArrayLike,
    command: npt.ArrayLike,
    dt: float,
    sensor: Sensor,
    rng: np.random.Generator,
) -> np.ndarray:
    """What the sensor logs of a pressure: ringing after each valve edge, noise, ADC step.

    Parameters
    ----------
    t : array_like of float, shape (n,)
        Logging instants, s (whole multiples of ``dt``).
    p : array_like of float, shape (n,)
        The pressure at ``t``, bar.
    command : array_like of int, shape (m,)
        The valve command at every controller step; its edges start the ringing.
    dt : float
        Controller step, s.
    sensor : Sensor
        Noise, quantum and ringing (its ``fs`` is not used: ``t`` is given).
    rng : numpy.random.Generator
        Source of the noise (one draw of ``n`` normals when ``sensor.noise > 0``).

    Returns
    -------
    numpy.ndarray, shape (n,)
        ``p`` plus the ringing, plus the noise, rounded to the ADC step, in that order.

    Examples
    --------
    >>> quiet = Sensor(noise=0.0, quantum=0.001)
    >>> sensor_record([0.0, 0.001], [0.1234, 0.2], [0, 0], 0.001, quiet, None).tolist()
    [0.123, 0.2]
    """
    times = np.asarray(t, dtype=np.float64)
    logged = np.asarray(p, dtype=np.float64)
    u = np.asarray(command)
    if sensor.ringing is not None:
        edges = np.flatnonzero(np.diff(u)) + 1
        sign = np.where(u[edges] == 1, 1.0, -1.0)
        logged = logged + _ringing(times, edges * dt, sign, sensor.ringing)
    if sensor.noise > 0:
        logged = logged + rng.normal(0.0, sensor.noise, logged.size)
    if sensor.quantum > 0:
        logged = np.round(logged / sensor.quantum) * sensor.quantum
    return logged


def edge_declaration(valve: npt.ArrayLike | None, dt: float, sensor: Sensor) -> dict[str, str]:
    """``valve_edges`` of a run given as its valve command ``valve`` (at step ``dt``), as a
    bench that knows its controller declares it: ``on_tick`` when every edge falls on a
    logging tick, else ``sampled``. A modulated run declares nothing: its replayed modulator
    decides edge by edge (:func:`spa.identification.edges.edge_timing`).

    Examples
    --------
    >>> edge_declaration(np.array([0] * 20 + [1] * 20), 1e-4, Sensor(fs=1000.0))
    {'valve_edges': 'on_tick'}
    """
    if valve is None:
        return {}
    every = max(1, round(1.0 / (sensor.fs * dt)))
    edges = np.flatnonzero(np.diff(np.asarray(valve))) + 1
    return {"valve_edges": "on_tick" if np.all(edges % every == 0) else "sampled"}
