"""The linear reference of the sine and chirp analyses: a noise-free first-order system.

A test of linearity is only worth its number if a linear system passes it. The reference is
the averaged plant linearised at mid-range (paper Eq. 9): static gain ``k2`` (the supply
pressure, so that ``xi = 1`` maps to ``k2`` as on the ideal line of Fig. 7a) and the time
constant ``tau_m`` of Eq. 9 at ``xi = 0.5`` (the median over the dataset's settings). It is driven
by the very input fraction of a recorded run, without noise, and analysed exactly as the
runs are: whatever deviation or bicoherence it shows is what the analysis itself reports for
a linear plant (lag, finite record, windowing), not nonlinearity. (The chirp analysis of a
simulated dataset also logs it through the run's sensor, `spa.openloop.chirp.chirp_reference`.)

>>> import numpy as np
>>> t = np.arange(0.0, 10.0, 0.01)
>>> y = first_order_response(t, np.ones_like(t), gain=0.8, tau=1.0)
>>> bool(np.isclose(y[100], 0.8 * (1 - np.exp(-1.0))))  # one tau after the step
True
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from typing import Any

import numpy as np
import numpy.typing as npt
import pandas as pd

from spa import _checks
from spa._signal import first_order_filter
from spa.model.averaging import time_constant, time_fractions
from spa.model.modulators import Modulator
from spa.model.params import ValveParams
from spa.openloop._arrays import _array, _time, uniform_step

__all__ = [
    "REFERENCE",
    "SKIPPED_PART",
    "first_order_response",
    "linear_reference",
    "reference_run",
    "reference_skip_reason",
    "reference_time_constant",
]

#: The model-based part of the sine and chirp stages, named when it is skipped.
SKIPPED_PART = "linear reference"

#: The ``modulator`` (and ``setting``, ``run``) of the linear reference's row in a table.
REFERENCE = "linear"


def first_order_response(
    t: npt.ArrayLike, xi: npt.ArrayLike, gain: float, tau: float, y0: float = 0.0
) -> npt.NDArray[np.float64]:
    """Exact response of ``tau*dy/dt + y = gain*xi`` to an input held between samples.

    Parameters
    ----------
    t : array_like of float, shape (n,)
        Uniformly spaced sample times, s.
    xi : array_like of float, shape (n,)
        Input; ``xi[k]`` is held over ``[t[k], t[k+1])`` (as a modulator samples it).
    gain : float
        Static gain (bar per unit of ``xi``), > 0.
    tau : float
        Time constant, s, > 0.
    y0 : float, default 0.0
        Output at ``t[0]``.

    Returns
    -------
    numpy.ndarray of float64, shape (n,)
        ``y[k]`` at ``t[k]``: ``y[k+1] = a*y[k] + (1 - a)*gain*xi[k]`` with
        ``a = exp(-dt/tau)``, the exact discretisation for a held input (no ODE solver).

    Raises
    ------
    ValueError
        If the arrays are not finite, one-dimensional, of one length >= 2, ``t`` is not
        uniformly spaced, or ``gain``/``tau`` are not finite and > 0.

    Examples
    --------
    >>> first_order_response([0.0, 1.0, 2.0], [1.0, 1.0, 1.0], gain=2.0, tau=1.0).round(4)
    array([0.    , 1.2642, 1.7293])
    """
    tt = _time(t)
    x = _array("xi", xi, size=tt.size)
    k = _checks.positive("gain", gain)
    tc = _checks.positive("tau", tau, "s")
    y_start = _checks.number("y0", y0)
    a = float(np.exp(-uniform_step(tt, "first_order_response") / tc))
    # y[k] = a*y[k-1] + (1 - a)*gain*xi[k-1]: the input enters one sample later.
    drive = np.concatenate(([0.0], (1.0 - a) * k * x[:-1]))
    return first_order_filter(drive, a, y_start)


def reference_time_constant(
    modulators: Iterable[Mapping[str, Any] | Modulator], params: ValveParams, xi: float = 0.5
) -> float:
    """The dataset's time constant for the linear reference: Eq. 9 at ``xi``, median over settings.

    Parameters
    ----------
    modulators : iterable of mapping or Modulator
        The settings of the runs analysed (e.g. every sine run's).
    params : ValveParams
        The dataset's (identified) parameters.
    xi : float, default 0.5
        Input fraction at which Eq. 9 is evaluated.

    Returns
    -------
    float
        The median over the settings of ``tau_m`` (Eq. 9, with each setting's time fractions,
        Eqs. 6-7), ignoring settings for which ``xi`` is in the dead-zone or saturation. (The
        largest would bound every run's lag, but it comes from a setting at the edge of
        saturation, where ``tau_m`` jumps with the last digit of ``t_off``: nominal IPFM
        10 ms gives 2.36 s, the identified valve NaN. The median does not move so.)

        When no setting gives a finite ``tau_m`` at ``xi`` (a valve whose identified delays
        put every setting in its dead-zone there), the nearest input fraction on the grid
        ``0.05, 0.10, ..., 0.95`` where one does is used; when none does anywhere, the
        valve's own ``tau2``.

    Examples
    --------
    >>> mods = [{"type": "iipfm", "t_l": 0.02}, {"type": "pwm", "f_w": 5.0}]
    >>> round(reference_time_constant(mods, ValveParams()), 3)  # IIPFM 1.077, PWM 0.652
    0.864
    """
    x = _checks.fraction("xi", xi)
    settings = [Modulator.from_mapping(mod) for mod in modulators]
    grid = np.round(np.arange(1, 20) * 0.05, 12)
    for at in [x, *sorted(grid, key=lambda g: (abs(g - x), g))]:
        taus = []
        for setting in settings:
            a1, a2 = time_fractions(setting.kind, float(at), params, **setting.settings)
            taus.append(float(time_constant(a1, a2, params)))
        finite = [tau for tau in taus if np.isfinite(tau)]
        if finite:
            return float(np.median(finite))
    return float(params.tau2)


def reference_skip_reason(
    modulators: Iterable[Mapping[str, Any] | Modulator], params: ValveParams, xi: float = 0.5
) -> str:
    """Why the linear reference cannot be built for these settings on this valve, or ``""``.

    The reference needs Eq. 9's ``tau_m`` at ``xi`` from at least one setting
    (:func:`reference_time_constant`); a setting that cannot work on the valve (its pulses
    shorter than the valve's delays: :func:`spa.model.usable.unusable_reason`), or whose
    ``xi`` lies in its dead-zone or saturation, gives none. The runs themselves are analysed
    as recorded whatever this says: only the model-based reference is left out.

    Returns
    -------
    str
        ``""`` when some setting gives a finite ``tau_m``; else one sentence naming each
        setting and its reason.

    Examples
    --------
    >>> slow = ValveParams(t_on=0.007, t_off=0.038)
    >>> reference_skip_reason([{"type": "pwm", "f_w": 25.0}], slow)[:74]
    'no setting of these runs gives a finite tau_m (Eq. 9) at xi = 0.5: pwm-25H'
    >>> reference_skip_reason([{"type": "pwm", "f_w": 25.0}, {"type": "pwm", "f_w": 5.0}], slow)
    ''
    """
    from spa.model.usable import unusable_reason

    x = _checks.fraction("xi", xi)
    why = []
    for mod in modulators:
        setting = Modulator.from_mapping(mod)
        a1, a2 = time_fractions(setting.kind, x, params, **setting.settings)
        if np.isfinite(float(time_constant(a1, a2, params))):
            return ""
        reason = unusable_reason(setting, params)
        why.append(reason or f"{setting.label}: xi = {x:g} lies in its dead-zone or saturation")
    return f"no setting of these runs gives a finite tau_m (Eq. 9) at xi = {x:g}: " + "; ".join(
        dict.fromkeys(why)
    )


def reference_run(run: pd.DataFrame, params: ValveParams, tau: float) -> pd.DataFrame:
    """A run's input through the linear reference: the table the analyses take.

    Parameters
    ----------
    run : pandas.DataFrame
        Run table with uniformly spaced ``t`` (s) and the input fraction ``u``.
    params : ValveParams
        Supplies the gain ``k2``.
    tau : float
        Time constant, s (`reference_time_constant`).

    Returns
    -------
    pandas.DataFrame
        ``t``, ``u`` (copied) and ``p``: `first_order_response` from 0 bar, as a run that
        starts with the actuator empty.
    """
    for column in ("t", "u"):
        if column not in run.columns:
            raise ValueError(f"reference_run: run table lacks column {column!r}")
    t = run["t"].to_numpy(dtype=np.float64)
    u = run["u"].to_numpy(dtype=np.float64)
    return pd.DataFrame({"t": t, "p": first_order_response(t, u, params.k2, tau), "u": u})


def linear_reference(
    run: pd.DataFrame, params: ValveParams, modulators: Iterable[Mapping[str, Any] | Modulator]
) -> tuple[pd.DataFrame, dict[str, Any]]:
    """A run's input through the dataset's linear reference, and the tags of its table row.

    Parameters
    ----------
    run : pandas.DataFrame
        The run whose ``t`` and ``u`` drive the reference.
    params : ValveParams
        The dataset's parameters (gain ``k2``, and ``tau_m`` with ``modulators``).
    modulators : iterable of mapping or Modulator
        The settings of the dataset's runs of that kind (`reference_time_constant`).

    Returns
    -------
    reference : pandas.DataFrame
        `reference_run` with `reference_time_constant`.
    tags : dict
        ``run``, ``modulator`` and ``setting`` all `REFERENCE`, ``gain`` 1 and ``tau_m`` (s).
    """
    tau = reference_time_constant(modulators, params)
    tags = {"run": REFERENCE, "modulator": REFERENCE, "setting": REFERENCE, "gain": 1.0}
    return reference_run(run, params, tau), {**tags, "tau_m": tau}
