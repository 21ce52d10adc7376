"""Compliant low-supply balloons: the physical plants the paper's two laws do not describe.

A soft chamber on a low supply (0.4–0.8 bar gauge) breathes through subsonic flow both ways
(the pressure ratio across each port stays above its critical ratio) while its volume grows
by 100 % per bar or more. Its charge and discharge rates then differ from the paper's
exponential and square-root laws in mid-range, where modulated use keeps the pressure
(docs/explanation/physical-plant.md).
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from spa.synthetic._physical_core import _CM3, _DM3_PER_S_BAR, R_AIR, RHO0, PhysicalPlant

__all__ = [
    "BALLOON_SEEDS",
    "COMPLIANT_GROWTH",
    "LOW_SUPPLY",
    "SHORT_SESSION",
    "balloon",
    "compliant_balloons",
    "compliant_low_supply",
    "random_balloon",
]

#: The seed of each fixture balloon's bench data (sensor noise).
BALLOON_SEEDS: dict[str, int] = {"balloon-06": 4706, "balloon-04": 4704}

#: A low supply, bar gauge: at most this.
LOW_SUPPLY = 0.8
#: A compliant chamber's volume growth per bar, as a fraction of its volume at 0 bar: at
#: least this.
COMPLIANT_GROWTH = 1.0

#: A short session on a balloon (about a minute of logs a run), the quick dataset of the
#: tests and benchmarks that identify a balloon end to end: three modulators at a balloon's
#: scale and the experiments' sizes (``generate_dataset``'s ``modulators`` and
#: ``experiments``). The full configuration's balloon datasets record longer ones.
SHORT_SESSION: dict = {
    "modulators": [
        {"type": "pwm", "f_w": 5.0},
        {"type": "iipfm", "t_l": 0.06, "gain": 1.25},
        {"type": "dsm", "period": 0.05},
    ],
    "experiments": {
        "identification": {"charge_time": 4.0, "discharge_time": 3.0, "repeats": 2},
        "staircase": {"step": 0.2, "hold": 3.0},
        "sine": {
            "frequency": 0.2,
            "amplitudes": [0.4, 0.2],
            "periods_per_level": 1,
            "offset": 0.5,
            "settle": 2.0,
        },
    },
}

_PATM = 1.01325
_T0 = 293.15


def balloon(
    supply: float,
    growth: float,
    *,
    volume: float = 30.0,
    fill: float = 0.6,
    exhaust_ratio: float = 1.2,
    b: float = 0.3,
    polytropic: float = 1.2,
    t_open: float = 0.015,
    t_close: float = 0.025,
    **other: float,
) -> PhysicalPlant:
    """A compliant chamber on a low supply.

    Parameters
    ----------
    supply : float
        Regulator set-point, bar gauge.
    growth : float
        Volume growth per bar, as a fraction of the volume at 0 bar (1.0: doubling per
        bar).
    volume : float, optional
        Chamber volume at 0 bar gauge, cm³.
    fill : float, optional
        Time the chamber's flow at 0 bar would take to fill it to the supply, s: sets the
        supply port's conductance.
    exhaust_ratio : float, optional
        Exhaust conductance over the supply's.
    b : float, optional
        Critical pressure ratio of both ports (subsonic both ways when ``b`` is below
        ``p_atm/(p_atm + supply)``).
    polytropic, t_open, t_close : float, optional
        As :class:`~spa.synthetic.physical.PhysicalPlant`.
    **other
        Any other :class:`~spa.synthetic.physical.PhysicalPlant` setting.

    Returns
    -------
    PhysicalPlant

    Raises
    ------
    ValueError
        If the flow would be choked on either port (``b >= p_atm/(p_atm + supply)``).

    Examples
    --------
    >>> p = balloon(0.6, 1.0)
    >>> p.compliance / p.volume
    1.0
    """
    if b >= _PATM / (_PATM + supply):
        raise ValueError(
            f"balloon: b = {b:g} chokes the flow at supply {supply:g} bar; it must be below "
            f"{_PATM / (_PATM + supply):.3f}"
        )
    compliance = growth * volume
    cap = (volume * _CM3 + polytropic * _PATM * compliance * _CM3) / (polytropic * R_AIR * _T0)
    c_si = cap * supply / (fill * RHO0 * (supply + _PATM))
    c_supply = c_si / _DM3_PER_S_BAR
    settings = {
        "supply": supply,
        "c_supply": c_supply,
        "b_supply": b,
        "c_exhaust": c_supply * exhaust_ratio,
        "b_exhaust": b,
        "volume": volume,
        "compliance": compliance,
        "polytropic": polytropic,
        "t_open": t_open,
        "t_close": t_close,
        "transit": 0.003,
        "droop": 0.0,
        "noise": 0.002,
        "quantum": 1.5 * supply / 4096.0,
        "mains": 0.0,
        "sensor_lag": 0.002,
    }
    settings.update(other)
    return PhysicalPlant(**settings)


def compliant_balloons() -> dict[str, PhysicalPlant]:
    """The two fixture balloons (their data's seeds in :data:`BALLOON_SEEDS`).

    ``balloon-06``: 0.6 bar supply, volume doubling per bar, a slow valve (15/25 ms);
    ``balloon-04``: 0.4 bar supply, volume growing 150 % per bar. Both subsonic both ways.

    Examples
    --------
    >>> sorted(compliant_balloons())
    ['balloon-04', 'balloon-06']
    """
    return {
        "balloon-06": balloon(0.6, 1.0),
        "balloon-04": balloon(0.4, 1.5, volume=40.0, fill=0.8, t_open=0.012, t_close=0.02),
    }


def random_balloon(rng: np.random.Generator) -> PhysicalPlant:
    """A compliant low-supply balloon drawn over its range: supply 0.4–0.8 bar, volume
    growth 100–200 % per bar, chamber 5–200 cm³ (log-uniform), fill 0.2–1.5 s, ``b``
    0.15–0.45 (subsonic both ways), dead times 5–25 ms.

    Examples
    --------
    >>> p = random_balloon(np.random.default_rng(3))
    >>> 0.4 <= p.supply <= 0.8 and p.compliance >= p.volume
    True
    """
    volume = float(math.exp(rng.uniform(math.log(5.0), math.log(200.0))))
    t_open, t_close = (float(v) for v in rng.uniform(0.005, 0.025, 2))
    return balloon(
        float(rng.uniform(0.4, 0.8)),
        float(rng.uniform(1.0, 2.0)),
        volume=volume,
        fill=float(math.exp(rng.uniform(math.log(0.2), math.log(1.5)))),
        exhaust_ratio=float(rng.uniform(0.7, 2.0)),
        b=float(rng.uniform(0.15, 0.45)),
        polytropic=float(rng.uniform(1.0, 1.4)),
        t_open=t_open,
        t_close=t_close,
        noise=float(rng.uniform(0.001, 0.004)),
    )


def compliant_low_supply(
    supply: npt.ArrayLike, volume: npt.ArrayLike, compliance: npt.ArrayLike
) -> np.ndarray:
    """Whether plants are compliant low-supply ones: supply at most :data:`LOW_SUPPLY` bar
    gauge and volume growing by at least :data:`COMPLIANT_GROWTH` (100 %) per bar.

    Parameters
    ----------
    supply : array_like
        Regulator set-point, bar gauge (:class:`~spa.synthetic.physical.PhysicalPlant`'s
        ``supply``).
    volume : array_like
        Chamber volume at 0 bar gauge, cm³.
    compliance : array_like
        Volume growth, cm³/bar.

    Returns
    -------
    numpy.ndarray of bool
        One per plant (broadcast).

    Raises
    ------
    ValueError
        If a volume is not positive.

    Examples
    --------
    >>> p = compliant_balloons()["balloon-04"]
    >>> bool(compliant_low_supply(p.supply, p.volume, p.compliance))
    True
    >>> compliant_low_supply([0.6, 2.0, 0.6], [30.0, 30.0, 30.0], [30.0, 60.0, 20.0]).tolist()
    [True, False, False]
    """
    v = np.asarray(volume, dtype=np.float64)
    if np.any(~(v > 0)):
        raise ValueError(f"compliant_low_supply: volumes must be positive cm^3, got {v!r}")
    growth = np.asarray(compliance, dtype=np.float64) / v
    return (np.asarray(supply, dtype=np.float64) <= LOW_SUPPLY) & (growth >= COMPLIANT_GROWTH)
