"""Every setting of the sweeps as a candidate: its costs, what a user must live with, and
whether it meets the user's constraints.

Every setting of the four sweeps is a candidate (IIPFM with ``G = 1 + t_on/t_l``, and with
every gain of an optional gain sweep). Each gets its cost (``J`` of Eq. 25 and ``J_exact`` of
the exact periodic steady state) and what a user must live with, as a maximum over the
input fractions of the cost's grid (:func:`setting_metrics`): the valve's switching rate
(command edges per second, ``2/(t_h + t_l)``), the chattering (Appendix B's ``P+ - P-``), the
shortest pulse the controller must produce and the slowest response. :func:`candidate_frame`
checks each against the constraints of :class:`~spa.tuning.constraints.TuningOptions`.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
import numpy.typing as npt
import pandas as pd

from spa._docs import fill_doc
from spa._progress import progress
from spa.model.averaging import pulse_times, time_constant, time_fractions
from spa.model.chattering import pseudo_steady_state
from spa.model.modulators import get_kind
from spa.model.params import ValveParams
from spa.model.usable import usable
from spa.tuning.constraints import _METRIC, CONSTRAINTS, TuningOptions, violation
from spa.tuning.cost import _on_xi_grid, feasible, linearity_cost, modulator_settings, sweep_grid

__all__ = ["candidate_frame", "setting_metrics"]


@fill_doc
def setting_metrics(
    kind: str,
    value: npt.ArrayLike,
    params: ValveParams,
    n_xi: int = 100,
    gain: npt.ArrayLike | None = None,
) -> dict[str, npt.NDArray[np.float64]]:
    """Switching rate, chattering and shortest pulse of settings, each a maximum over ``xi``.

    Parameters
    ----------
    %(cost_args)s

    Returns
    -------
    dict
        Arrays of the shape of ``value``: ``switching_rate`` (largest ``2/(t_h + t_l)`` over
        the grid of ``xi``, edges/s), ``chattering`` (largest ``P+ - P-`` of Appendix B, bar)
        and ``min_pulse`` (shortest pulse that moves the pressure, s; ΔΣM: the clock period;
        ``inf`` when nothing pulses) and ``tau_max`` (largest equivalent time constant of
        Eq. 9 over the ``xi`` where it is defined, s; NaN where it is defined nowhere). Where
        the command is constant there is no pulse train: rate and chattering 0. Durations
        are those of :func:`spa.model.averaging.pulse_times`, as in
        :func:`spa.openloop.predicted_levels`.

    Examples
    --------
    >>> m = setting_metrics("pwm", 20.0, ValveParams())
    >>> float(m["switching_rate"])
    40.0
    """
    _, xi, grid = _on_xi_grid(kind, value, params, n_xi, gain)
    t_h, t_l = (np.asarray(a, dtype=np.float64) for a in pulse_times(kind, xi, params, **grid))
    pulsing = np.isfinite(t_h) & np.isfinite(t_l) & (t_h > 0.0) & (t_l > 0.0)
    th = np.where(pulsing, t_h, 1.0)
    tl = np.where(pulsing, t_l, 1.0)
    hi, lo = (np.asarray(a) for a in pseudo_steady_state(th, tl, params))
    # A pulse within rounding of its hold (IIPFM's t_on-long high at xi = 0 with the gain of
    # Eq. 17) does not move the pressure.
    moving = np.minimum(
        np.where(pulsing & (th > params.on_loss * (1 + 1e-9)), th, np.inf),
        np.where(pulsing & (tl > params.off_loss * (1 + 1e-9)), tl, np.inf),
    ).min(axis=-1)
    moving = get_kind(kind).min_pulse(moving, grid)
    with np.errstate(all="ignore"):
        tau = np.asarray(
            time_constant(*time_fractions(kind, xi, params, **grid), params), dtype=np.float64
        )
    tau = np.where(np.isfinite(tau), tau, -np.inf).max(axis=-1)
    return {
        "switching_rate": np.where(pulsing, 2.0 / (th + tl), 0.0).max(axis=-1),
        "chattering": np.where(pulsing, hi - lo, 0.0).max(axis=-1),
        "min_pulse": moving,
        "tau_max": np.where(np.isfinite(tau), tau, np.nan),
    }


def candidate_frame(
    grids: Mapping[str, Mapping[str, float]],
    params: ValveParams,
    n_xi: int = 100,
    options: TuningOptions | None = None,
    data: pd.DataFrame | None = None,
) -> pd.DataFrame:
    """Every setting of the sweeps with its costs, metrics and constraint checks.

    Parameters
    ----------
    grids : mapping
        ``kind -> {start, stop, step}`` (:func:`spa.tuning.cost.check_sweeps`).
    params : ValveParams
        Valve parameters.
    n_xi : int, default 100
        Points of ``xi`` in the costs and metrics.
    options : TuningOptions, optional
        Constraints and gain sweep; defaults when omitted.
    data : pandas.DataFrame, optional
        ``sweep_frame(grids, params, n_xi, exact=True)`` when already computed: its ``J``
        and ``J_exact`` are used for the settings with the default gain.

    Returns
    -------
    pandas.DataFrame
        One row per candidate: ``modulator``, ``value`` (Hz for PWM, s otherwise), ``gain``
        (NaN for PWM, ΔΣM), ``J``, ``J_exact``, ``switching_rate``, ``chattering``,
        ``min_pulse`` (:func:`setting_metrics`), one boolean column per entry of
        :data:`CONSTRAINTS` (True: the candidate meets it) and ``feasible`` (all of them).
        Settings outside Section 5's constraints (:func:`spa.tuning.cost.feasible`) or with
        no input range that moves the pressure (:func:`spa.model.usable.usable`) are left
        out.
    """
    opts = options or TuningOptions()
    parts = []
    for kind, g in progress(grids.items(), "sweeps", total=len(grids), unit="modulator"):
        values = sweep_grid(g["start"], g["stop"], g["step"])
        keep = np.asarray(feasible(kind, values, params), dtype=bool)
        keep &= usable(kind, values, params)
        values = values[keep]
        sets: list[tuple[npt.NDArray[np.float64], npt.NDArray[np.float64] | None]] = [
            (values, None)
        ]
        if get_kind(kind).gain_swept and opts.gain_sweep is not None:
            gains = sweep_grid(**opts.gain_sweep)
            sets.append((np.repeat(values, gains.size), np.tile(gains, values.size)))
        for v, gain in sets:
            settings = modulator_settings(kind, v, params, gain)
            if gain is None and data is not None:
                known = data[data["modulator"] == kind]
                if len(known) != keep.size:
                    raise ValueError(f"data: {kind} rows do not match the grid {dict(g)}")
                costs = {
                    "J": known["J"].to_numpy()[keep],
                    "J_exact": known["J_exact"].to_numpy()[keep],
                }
            else:
                costs = {
                    "J": linearity_cost(kind, v, params, n_xi, gain=gain),
                    "J_exact": linearity_cost(kind, v, params, n_xi, gain=gain, exact=True),
                }
            frame = pd.DataFrame(
                {
                    "modulator": kind,
                    "value": v,
                    "gain": settings.get("gain", np.full(v.shape, np.nan)),
                    **costs,
                    **setting_metrics(kind, v, params, n_xi, gain),
                }
            )
            lo, hi = opts.ranges.get(kind, (-np.inf, np.inf))
            frame["setting_range"] = (v >= lo * (1 - 1e-12)) & (v <= hi * (1 + 1e-12))
            parts.append(frame)
    out = pd.concat(parts, ignore_index=True)
    on_valve = opts.limits(params)
    for name, (column, sign) in _METRIC.items():
        limit = on_valve[name]
        if limit is None:
            out[name] = True
        elif sign > 0:
            out[name] = out[column] <= limit
        else:
            out[name] = out[column] >= limit * (1 - 1e-9)
    out["feasible"] = out[list(CONSTRAINTS)].all(axis=1)
    out["violation"] = violation(out, opts, params)
    return out
