"""One sine run: the lag-compensated input against the normalised pressure (Fig. 8).

`sine_analysis` compares ``p/max(p)``, shifted back by the lag found by cross-correlation,
with the line from (0, 0) to (1, 1). That measures the static nonlinearity only well below
the plant's corner frequency ``1/(2*pi*tau_m)``: nearer to it, a linear plant's attenuation
alone moves the curve off the line. `sine_reference` therefore runs the same input through
the linear reference (`spa.openloop.reference`) and analyses it identically; its deviation
is the floor below which a run's deviation means nothing.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from typing import Any

import numpy as np
import pandas as pd

from spa.model.modulators import Modulator
from spa.model.params import ValveParams
from spa.openloop._arrays import run_columns
from spa.openloop.reference import linear_reference
from spa.openloop.sine_fit import compensate_lag, sine_linearity

#: A sine at most this fraction of the plant's corner frequency tests the static
#: nonlinearity: a linear first-order plant's RMS deviation is at most about 0.012 there.
LOW_FREQUENCY = 0.3

__all__ = [
    "LOW_FREQUENCY",
    "frequency_note",
    "lag_search_limit",
    "sine_analysis",
    "sine_frequency",
    "sine_reference",
]


def sine_frequency(t: np.ndarray, u: np.ndarray) -> float:
    """Frequency of a sine input, from its upward crossings of its mid-range (Hz).

    Parameters
    ----------
    t, u : numpy.ndarray, shape (n,)
        Times (s) and input fraction of a sine run (noise-free: the command).

    Returns
    -------
    float
        ``(m - 1)/(t_m - t_1)`` for the ``m`` upward crossings of ``(max(u) + min(u))/2``
        (linearly interpolated); NaN with fewer than two crossings.

    Examples
    --------
    >>> t = np.arange(0.0, 100.0, 0.01)
    >>> round(sine_frequency(t, 0.5 + 0.3 * np.sin(2 * np.pi * 0.05 * t)), 6)
    0.05
    """
    mid = 0.5 * (float(np.max(u)) + float(np.min(u)))
    d = u - mid
    k = np.flatnonzero((d[:-1] < 0.0) & (d[1:] >= 0.0))
    if k.size < 2:
        return math.nan
    crossing = t[k] + (t[k + 1] - t[k]) * (-d[k]) / (d[k + 1] - d[k])
    return float((k.size - 1) / (crossing[-1] - crossing[0]))


def lag_search_limit(frequency: float, max_lag: float | None = None) -> float | None:
    """The largest lag the cross-correlation of a sine run searches, s.

    Parameters
    ----------
    frequency : float
        The sine's frequency, Hz (`sine_frequency`; NaN when it cannot be measured).
    max_lag : float or None, default None
        A limit in s; None: half the sine's period. Within half a period the lag of a
        periodic response is unique (the next candidate is a whole period later), and a
        first-order plant lags by less than a quarter period, however slow.

    Returns
    -------
    float or None
        ``max_lag`` when given, else ``1/(2*frequency)``; None (the whole record) when
        neither is known.

    Examples
    --------
    >>> lag_search_limit(0.02), lag_search_limit(0.02, 2.0), lag_search_limit(float("nan"))
    (25.0, 2.0, None)
    """
    if max_lag is not None:
        return float(max_lag)
    return 0.5 / frequency if math.isfinite(frequency) and frequency > 0.0 else None


def sine_analysis(
    run: pd.DataFrame, *, settle: float = 0.0, max_lag: float | None = None
) -> tuple[pd.DataFrame, dict[str, float]]:
    """Linearity of the response to a sine of piece-wise decreasing amplitude (Fig. 8).

    Parameters
    ----------
    run : pandas.DataFrame
        Run table with ``t`` (s, uniformly spaced), ``p`` (bar) and ``u`` (input fraction).
    settle : float, default 0.0
        Seconds dropped at the start (a hold at the offset before the sine starts).
    max_lag : float or None, default None
        Largest lag searched by the cross-correlation, s (None: half the sine's period,
        `lag_search_limit`).

    Returns
    -------
    aligned : pandas.DataFrame
        ``t``, ``xi`` (input) and ``p_norm`` (pressure shifted back by the lag, divided by
        its maximum) over the overlapping part.
    summary : dict
        ``frequency`` (Hz, `sine_frequency`), ``lag`` (s; NaN when the correlation peaks on
        the search limit, where the true lag is likely beyond it), ``lag_at_limit`` (bool,
        that case), ``max_lag`` (the limit searched, s; NaN: the whole record), ``rms`` and
        ``max_dev`` (RMS and largest ``|p_norm - xi|``; with the lag at the limit, at that
        shift), ``p_max`` (bar).

    Examples
    --------
    >>> t = np.arange(0.0, 300.0, 0.01)
    >>> u = 0.5 + 0.4 * np.sin(2 * np.pi * 0.02 * t)
    >>> run = pd.DataFrame({"t": t, "u": u, "p": np.roll(u, 300)})  # 3 s late
    >>> round(sine_analysis(run)[1]["lag"], 1)  # the raw correlation: 2.97
    3.0
    >>> summary = sine_analysis(run, max_lag=2.0)[1]
    >>> summary["lag"], summary["lag_at_limit"]
    (nan, True)
    """
    t, p, u = run_columns(run, ("t", "p", "u"), "sine_analysis")
    keep = t >= t[0] + settle
    if keep.sum() < 2:
        raise ValueError(f"sine_analysis: settle = {settle} s leaves no samples")
    frequency = sine_frequency(t[keep], u[keep])
    limit = lag_search_limit(frequency, max_lag)
    lag, ta, xa, pa = compensate_lag(t[keep], u[keep], p[keep], max_lag=limit)
    dt = (t[keep][-1] - t[keep][0]) / max(int(keep.sum()) - 1, 1)
    at_limit = limit is not None and lag >= math.floor(limit / dt + 1e-9) * dt - 0.5 * dt
    lin = sine_linearity(xa, pa)
    aligned = pd.DataFrame({"t": ta, "xi": xa, "p_norm": pa / lin["p_max"]})
    return aligned, {
        "frequency": frequency,
        "lag": math.nan if at_limit else lag,
        "lag_at_limit": bool(at_limit),
        "max_lag": math.nan if limit is None else limit,
        **lin,
    }


def sine_reference(
    run: pd.DataFrame,
    params: ValveParams,
    modulators: Iterable[Mapping[str, Any] | Modulator],
    *,
    settle: float = 0.0,
    max_lag: float | None = None,
) -> tuple[pd.DataFrame, dict[str, Any]]:
    """The linear reference's row of a sine table: a run's input through a linear plant.

    Parameters
    ----------
    run, params, modulators
        A sine run (its ``t`` and ``u`` drive the reference), the dataset's parameters and
        its sine runs' settings: as `spa.openloop.reference.linear_reference`.
    settle, max_lag : float
        As `sine_analysis`, with the run's values.

    Returns
    -------
    aligned : pandas.DataFrame
        As `sine_analysis`.
    row : dict
        ``run``, ``modulator`` and ``setting`` all ``"linear"``, ``gain`` 1, ``tau_m`` (s),
        ``corner_frequency`` ``1/(2*pi*tau_m)`` (Hz) and `sine_analysis`'s summary.
    """
    reference, tags = linear_reference(run, params, modulators)
    aligned, summary = sine_analysis(reference, settle=settle, max_lag=max_lag)
    corner = 1.0 / (2.0 * math.pi * tags["tau_m"])
    return aligned, {**tags, "corner_frequency": corner, **summary}


def frequency_note(reference: Mapping[str, Any]) -> str:
    """Fig. 8's title: the sine's frequency against the plant's corner, and what that means.

    Parameters
    ----------
    reference : mapping
        The linear reference's row (`sine_reference`): ``frequency``, ``corner_frequency``,
        ``tau_m`` and ``rms``.

    Examples
    --------
    >>> frequency_note({"frequency": 0.02, "corner_frequency": 0.17, "tau_m": 0.94,
    ...                 "rms": 0.002})  # doctest: +ELLIPSIS
    "sine at 0.02 Hz, well below the plant's corner 0.17 Hz..."
    """
    f, corner = float(reference["frequency"]), float(reference["corner_frequency"])
    head = f"sine at {f:.3g} Hz"
    where = (
        f"well below the plant's corner {corner:.2g} Hz (1/(2π τ_m), τ_m = "
        f"{float(reference['tau_m']):.2f} s): the deviation is the static nonlinearity"
        if f <= LOW_FREQUENCY * corner
        else f"not well below the plant's corner {corner:.2g} Hz (1/(2π τ_m), τ_m = "
        f"{float(reference['tau_m']):.2f} s): part of the deviation is the plant's lag and "
        "attenuation"
    )
    return f"{head}, {where}; a linear plant gives RMS {float(reference['rms']):.3f} (grey)"
