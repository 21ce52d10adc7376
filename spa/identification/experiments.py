"""The one identification experiment design: the valve commands of the charge, discharge and
pulse runs, used by the simulator and documented for a bench."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np
import numpy.typing as npt
import pandas as pd

from spa.model.params import ValveParams
from spa.model.plant import simulate

__all__ = ["identification_commands", "simulate_identification"]

# --------------------------------------------------------------------------------------------
# Experiment design
# --------------------------------------------------------------------------------------------


def _steps(duration: float, dt: float, name: str, allow_zero: bool = False) -> int:
    if allow_zero and duration == 0:
        return 0
    if not (math.isfinite(duration) and duration > 0):
        raise ValueError(f"{name} must be finite and > 0 s, got {duration!r}")
    n = math.floor(duration / dt + 0.5)
    if n < 1:
        raise ValueError(f"{name} = {duration:g} s is shorter than dt = {dt:g} s")
    return n


def identification_commands(
    dt: float,
    *,
    lead: float = 0.1,
    charge_duration: float = 5.0,
    discharge_duration: float = 6.0,
    fill: float = 0.3,
    lows: Sequence[float] = (0.005, 0.01, 0.02, 0.05, 0.1),
    highs: Sequence[float] = (0.04, 0.08),
    repeats: int = 2,
    pulse_lead: float | None = None,
    tail: float = 0.0,
) -> dict[str, npt.NDArray[np.int8]]:
    """Valve commands of the three identification experiments (Section 3.2).

    Parameters
    ----------
    dt : float
        Step of the command, s. Every duration is rounded to whole steps.
    lead : float, optional
        Time before the first edge of every experiment, s (lets the recording see the
        initial level and puts the edge inside the record).
    charge_duration : float, optional
        Total length of the charge experiment, s; about 6 ``tau2`` reaches the supply.
    discharge_duration : float, optional
        Total length of the discharge experiment, s.
    fill : float, optional
        Pulse experiment: the valve first stays open this long from 0 bar, bringing the
        pressure to mid range, where both the charging and the exhausting rates are large.
    lows, highs : sequence of float, optional
        Pulse experiment: low-state and high-state durations, s. Every combination is
        applied (for each high duration, each low duration followed by that high).
    repeats : int, optional
        How many times the pulse pattern is repeated.
    pulse_lead : float, optional
        Time closed before the pulse experiment's first edge, s; default ``lead``.
    tail : float, optional
        Time closed after the pulse experiment's last high, s (the last exhaust); default 0.

    Returns
    -------
    dict of str to numpy.ndarray of int8
        ``"charge"``: ``lead`` closed, then open (start from 0 bar);
        ``"discharge"``: ``lead`` open, then closed (start from the supply: ``p0 = k2``, the
        valve settled open); ``"pulse"``: ``lead`` closed, ``fill`` open, then the pulses
        (start from 0 bar). ``u[k]`` is the command over ``[k*dt, (k+1)*dt)``.

    Raises
    ------
    ValueError
        If ``dt`` or a duration is not positive, or a duration is shorter than ``dt``.

    Notes
    -----
    The default pulse pattern (about 2.4 s, 20 rising and 20 falling edges) mixes low
    pulses shorter than the nominal ``t_off`` (5 ms: no exhaust at all, the dead-zone; 10 ms:
    at the edge) with longer ones that show the exhaust, and high pulses long enough to show
    the charge after ``t_on``. :func:`simulate_identification` runs them through the model.

    Examples
    --------
    >>> cmds = identification_commands(0.001)
    >>> sorted(cmds)
    ['charge', 'discharge', 'pulse']
    >>> cmds["charge"].size, int(cmds["charge"][:100].sum()), int(cmds["charge"][100:].min())
    (5000, 0, 1)
    """
    if not (isinstance(dt, int | float | np.floating) and math.isfinite(dt) and dt > 0):
        raise ValueError(f"dt must be finite and > 0 s, got {dt!r}")
    if not (isinstance(repeats, int | np.integer) and repeats >= 1):
        raise ValueError(f"repeats must be an integer >= 1, got {repeats!r}")
    if len(lows) == 0 or len(highs) == 0:
        raise ValueError("lows and highs must each hold at least one duration")
    n_lead = _steps(lead, dt, "lead", allow_zero=True)
    n_pulse_lead = _steps(lead if pulse_lead is None else pulse_lead, dt, "pulse_lead", True)
    n_charge = _steps(charge_duration, dt, "charge_duration")
    n_dis = _steps(discharge_duration, dt, "discharge_duration")
    if n_charge <= n_lead or n_dis <= n_lead:
        raise ValueError("charge_duration and discharge_duration must be longer than lead")
    charge = np.ones(n_charge, dtype=np.int8)
    charge[:n_lead] = 0
    dis = np.zeros(n_dis, dtype=np.int8)
    dis[:n_lead] = 1
    n_lows = [_steps(v, dt, "lows") for v in lows]
    n_highs = [_steps(v, dt, "highs") for v in highs]
    levels = [0, 1]
    counts = [n_pulse_lead, _steps(fill, dt, "fill")]
    for _ in range(int(repeats)):
        for nh in n_highs:
            for nl in n_lows:
                levels += [0, 1]
                counts += [nl, nh]
    levels.append(0)
    counts.append(_steps(tail, dt, "tail", allow_zero=True))
    pulse = np.repeat(np.array(levels, dtype=np.int8), counts)
    return {"charge": charge, "discharge": dis, "pulse": pulse}


def simulate_identification(
    params: ValveParams, dt: float = 0.001, **durations: Any
) -> dict[str, pd.DataFrame]:
    """Noise-free run tables of the three identification experiments.

    Parameters
    ----------
    params : ValveParams
        True parameters.
    dt : float, optional
        Sample step, s.
    **durations
        Passed to :func:`identification_commands`.

    Returns
    -------
    dict of str to pandas.DataFrame
        ``"charge"``, ``"discharge"``, ``"pulse"``: tables with ``t`` (s), ``p`` (bar),
        ``valve`` (int8), from :func:`spa.simulate` (exact at the sample times; the discharge
        starts at ``p0 = k2``, the others at 0 bar). Add a sensor model to mimic data.

    Examples
    --------
    >>> runs = simulate_identification(ValveParams())
    >>> round(float(runs["discharge"]["p"].iloc[0]), 3)
    0.837
    """
    cmds = identification_commands(dt, **durations)
    out = {}
    for name, u in cmds.items():
        p0 = params.k2 if name == "discharge" else 0.0
        out[name] = pd.DataFrame(
            {"t": dt * np.arange(u.size), "p": simulate(u, dt, params, p0), "valve": u}
        )
    return out
