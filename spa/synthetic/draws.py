"""Physical plants at random: the range a lab meets, with compliant low-supply balloons and
the effects outside a single-state law (docs/explanation/physical-plant.md)."""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from spa.synthetic._physical_core import _BAR, _CM3, _DM3_PER_S_BAR, R_AIR, RHO0, PhysicalPlant
from spa.synthetic.balloons import random_balloon

__all__ = ["random_effects", "random_plant"]


def random_plant(rng: np.random.Generator, *, full: bool = True) -> PhysicalPlant:
    """A physical plant drawn over the range a lab meets.

    With ``full`` (default) the draw goes on after the base plant below: one plant in five
    is replaced by a compliant low-supply balloon (:func:`~spa.synthetic.balloons.
    random_balloon`), and each effect outside a single-state law is added with probability
    0.35 (:func:`random_effects`). ``full=False`` gives the base plant alone, the same
    plant as before those existed for the same generator state.

    Supply log-uniform 0.5–6 bar gauge; dead times uniform 2–25 ms each, opening and closing
    at least 1 ms apart; transit 1–2 ms; chamber 5–200 cm³ (log-uniform) growing by 30–100 %
    of its volume over 0 bar..supply; polytropic index 1–1.4; supply conductance set so that
    the choked charge from 0 bar would fill the chamber in 0.05–1.5 s (log-uniform), exhaust
    conductance 0.7–2 times it; ``b`` 0.15–0.5, ``m`` 0.4–0.6 each port; regulator 5–50 ms,
    sagging 0–5 % of the supply at choked flow; sensor lag 0–5 ms, noise 0.1–0.4 % of
    max(supply, 1 bar), ADC step a 4096th of 1.5 times the supply, mains pickup 0–3 mbar at
    a random phase.

    Parameters
    ----------
    rng : numpy.random.Generator
    full : bool, optional
        Draw the balloons and the effects too.

    Returns
    -------
    PhysicalPlant

    Examples
    --------
    >>> p = random_plant(np.random.default_rng(1))
    >>> 0.5 <= p.supply <= 6.0 and p.t_open != p.t_close
    True
    """

    def logu(lo: float, hi: float) -> float:
        return float(math.exp(rng.uniform(math.log(lo), math.log(hi))))

    supply = logu(0.5, 6.0)
    while True:
        t_open, t_close = (float(v) for v in rng.uniform(0.002, 0.025, 2))
        if abs(t_open - t_close) >= 0.001:
            break
    volume = logu(5.0, 200.0)
    growth = float(rng.uniform(0.3, 1.0))
    compliance = growth * volume / supply
    n = float(rng.uniform(1.0, 1.4))
    fill = logu(0.05, 1.5)
    patm = 1.01325
    # choked charge rate at 0 bar: n*R*T*rho0*C*Ps/(V0 + n*patm*kv); fill = supply/rate
    cap = (volume * _CM3 + n * patm * _BAR * compliance * _CM3 / _BAR) / (n * R_AIR * 293.15)
    c_si = cap * supply / (fill * RHO0 * (supply + patm))  # m^3/(s*Pa)
    c_supply = c_si / _DM3_PER_S_BAR
    c_exhaust = c_supply * float(rng.uniform(0.7, 2.0))
    sag = float(rng.uniform(0.0, 0.05)) * supply
    plant = PhysicalPlant(
        supply=supply,
        c_supply=c_supply,
        b_supply=float(rng.uniform(0.15, 0.5)),
        m_supply=float(rng.uniform(0.4, 0.6)),
        c_exhaust=c_exhaust,
        b_exhaust=float(rng.uniform(0.15, 0.5)),
        m_exhaust=float(rng.uniform(0.4, 0.6)),
        volume=volume,
        compliance=compliance,
        polytropic=n,
        t_open=t_open,
        t_close=t_close,
        transit=float(rng.uniform(0.001, 0.002)),
        droop=sag / (c_supply * (supply + patm)),
        regulator_tau=float(rng.uniform(0.005, 0.05)),
        sensor_lag=float(rng.uniform(0.0, 0.005)),
        noise=float(rng.uniform(0.001, 0.004)) * max(supply, 1.0),
        quantum=1.5 * supply / 4096.0,
        mains=float(rng.uniform(0.0, 0.003)),
        mains_phase=float(rng.uniform(-math.pi, math.pi)),
    )
    if not full:
        return plant
    if rng.uniform() < 0.2:
        plant = random_balloon(rng)
    return dataclasses.replace(plant, **random_effects(plant, rng))


def random_effects(plant: PhysicalPlant, rng: np.random.Generator) -> dict[str, float]:
    """Effects outside a single-state law, each drawn with probability 0.35 for ``plant``.

    Leak 0.5–3 % of the exhaust's choked flow at the supply; wall heat exchange 0.3–5 s
    (the chamber's gas then adiabatic, ``polytropic = 1.4``); a volume creeping by 10–50 %
    of the chamber's compliance in 0.3–5 s; a sensor tube of 1–10 ms; a supply hose of
    0.5–3 chamber volumes behind a line of 1.5–5 times the supply port's conductance; a
    valve bounce of 5–30 % of the stroke decaying in 0.5–3 ms.

    Returns
    -------
    dict
        The :class:`PhysicalPlant` settings to replace (empty when none was drawn).
    """
    on = rng.uniform(size=6) < 0.35
    draws = rng.uniform(size=(6, 2))
    out: dict[str, float] = {}

    def between(u: float, lo: float, hi: float) -> float:
        return float(lo + (hi - lo) * u)

    if on[0]:
        share = between(draws[0, 0], 0.005, 0.03)
        out["leak"] = share * plant.c_exhaust * (plant.supply + plant.atmosphere) / plant.supply
    if on[1]:
        out["heat_tau"] = between(draws[1, 0], 0.3, 5.0)
        out["polytropic"] = 1.4
    if on[2]:
        growth = max(plant.compliance, 0.05 * plant.volume)
        out["creep"] = between(draws[2, 0], 0.1, 0.5) * growth
        out["creep_tau"] = between(draws[2, 1], 0.3, 5.0)
    if on[3]:
        out["tube_tau"] = between(draws[3, 0], 0.001, 0.01)
    if on[4]:
        out["hose_volume"] = between(draws[4, 0], 0.5, 3.0) * plant.volume
        out["c_line"] = min(between(draws[4, 1], 1.5, 5.0) * plant.c_supply, 50.0)
    if on[5]:
        out["bounce"] = between(draws[5, 0], 0.05, 0.3)
        out["bounce_time"] = between(draws[5, 1], 0.0005, 0.003)
    return out
