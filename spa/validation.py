"""Model validation: re-simulate a recorded run and score the fit (docs/model.md section 1).

A run table holds ``t`` (s), ``p`` (bar) and either ``valve`` (the recorded 0/1 command: the
value at sample ``k`` is the command over ``[t_k, t_{k+1})``) or ``u`` (the input fraction,
turned into a command by the run's modulator). The model pressure is evaluated *exactly* at the
recorded sample times, even when the sampling is irregular: every segment of the four-state
model has a closed form, so :func:`model_response` walks the command edges (one Python step
per edge) and evaluates the closed forms at all sample times at once. On a uniform grid it
equals :func:`spa.simulate` to rounding error (checked in the tests).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt
import pandas as pd

from spa._progress import progress
from spa.model.modulators import Modulator, modulate
from spa.model.params import ValveParams
from spa.model.plant import edge_indices, replay

__all__ = [
    "ValidationResult",
    "command_from_input",
    "fit_percent",
    "initial_pressure",
    "model_response",
    "validate_run",
    "validate_runs",
    "with_fit_before_refinement",
]


def _check_times(t: npt.ArrayLike, name: str = "t") -> npt.NDArray[np.float64]:
    arr = np.asarray(t, dtype=np.float64)
    if arr.ndim != 1 or arr.size < 2:
        raise ValueError(f"{name} must be a one-dimensional array of >= 2 times, got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} must be finite")
    if np.any(np.diff(arr) <= 0):
        k = int(np.flatnonzero(np.diff(arr) <= 0)[0])
        raise ValueError(f"{name} must be strictly increasing; {name}[{k + 1}] <= {name}[{k}]")
    return arr


def _check_valve(valve: npt.ArrayLike, n: int, name: str = "valve") -> npt.NDArray[np.int8]:
    arr = np.asarray(valve)
    if arr.shape != (n,):
        raise ValueError(f"{name} must have shape ({n},) like t, got {arr.shape}")
    if arr.dtype.kind == "b":
        return arr.astype(np.int8)
    if arr.dtype.kind not in "iuf" or not np.all((arr == 0) | (arr == 1)):
        raise ValueError(f"{name} must hold only 0 and 1")
    return arr.astype(np.int8)


def model_response(
    t: npt.ArrayLike,
    valve: npt.ArrayLike,
    params: ValveParams,
    p0: float,
) -> npt.NDArray[np.float64]:
    """Exact model pressure at the sample times of a recorded valve command.

    Parameters
    ----------
    t : array_like of float, shape (n,)
        Sample times in s, strictly increasing; need not be uniform nor start at 0.
    valve : array_like of {0, 1}, shape (n,)
        ``valve[k]`` is the command over ``[t[k], t[k+1])``: a change between samples
        ``k-1`` and ``k`` is an edge at ``t[k]``.
    params : ValveParams
        Model parameters.
    p0 : float
        Pressure at ``t[0]`` in bar (>= 0). At ``t[0]`` the valve is settled in state
        ``valve[0]`` (no hold running), as in :func:`spa.simulate`.

    Returns
    -------
    numpy.ndarray of float64, shape (n,)
        Model pressure in bar at each ``t[k]``.

    Raises
    ------
    ValueError
        If ``t`` is not strictly increasing and finite, ``valve`` holds anything but 0/1 or
        has another length, or ``p0`` is negative.

    Notes
    -----
    The same four states as :func:`spa.simulate` (docs/model.md section 1); the edges sit at the
    recorded sample times rather than on a uniform grid, and the closed forms are evaluated at
    the exact sample times, so irregular sampling costs no accuracy.

    Examples
    --------
    >>> import numpy as np
    >>> from spa import ValveParams, simulate
    >>> u = np.array([0, 0, 1, 1, 1, 0, 0, 1], dtype=np.int8)
    >>> t = 0.01 * np.arange(8)
    >>> p = model_response(t, u, ValveParams(), 0.1)
    >>> bool(np.allclose(p, simulate(u, 0.01, ValveParams(), 0.1)))
    True
    """
    tt = _check_times(t)
    v = _check_valve(valve, tt.size)
    if not (math.isfinite(p0) and p0 >= 0.0):
        raise ValueError(f"p0 must be finite and >= 0 bar, got {p0!r}")
    k = np.concatenate(([0], edge_indices(v)))
    level = v[k].astype(bool)
    hold = np.where(level, params.t_on, params.t_off)
    hold[0] = 0.0
    return replay(tt, tt[k], level, hold, float(p0), params)


def fit_percent(measured: npt.ArrayLike, model: npt.ArrayLike) -> float:
    """NRMSE fit in percent: ``100*(1 - ||p - p_model|| / ||p - mean(p)||)``.

    Parameters
    ----------
    measured, model : array_like of float, shape (n,)
        Measured and model pressure.

    Returns
    -------
    float
        100 for a perfect fit, 0 for a model no better than the mean, negative when worse.
        NaN when the measured signal is constant.

    Examples
    --------
    >>> fit_percent([0.0, 1.0, 2.0], [0.0, 1.0, 2.0])
    100.0
    >>> fit_percent([0.0, 1.0, 2.0], [1.0, 1.0, 1.0])
    0.0
    """
    p = np.asarray(measured, dtype=np.float64)
    m = np.asarray(model, dtype=np.float64)
    den = float(np.linalg.norm(p - p.mean()))
    if den == 0.0:
        return math.nan
    return 100.0 * (1.0 - float(np.linalg.norm(p - m)) / den)


def initial_pressure(t: npt.ArrayLike, p: npt.ArrayLike, span: float = 0.01) -> float:
    """Measured pressure at ``t[0]``: a straight line fitted over the first ``span`` seconds.

    Parameters
    ----------
    t, p : array_like of float, shape (n,)
        Sample times (s) and pressure (bar).
    span : float, optional
        Length in s of the start of the record used (at least 3 samples are used).

    Returns
    -------
    float
        The line's value at ``t[0]``, clipped at 0 bar. A line rather than the first sample
        averages the sensor noise while following a pressure that is already moving.

    Examples
    --------
    >>> initial_pressure([0.0, 0.001, 0.002, 0.003], [0.2, 0.21, 0.22, 0.23])
    0.2
    """
    tt = np.asarray(t, dtype=np.float64)
    pp = np.asarray(p, dtype=np.float64)
    n = max(3, int(np.searchsorted(tt, tt[0] + span, side="right")))
    n = min(n, tt.size)
    if n < 2:
        return max(float(pp[0]), 0.0)
    _slope, icept = np.polyfit(tt[:n] - tt[0], pp[:n], 1)
    return round(max(float(icept), 0.0), 12)


def command_from_input(
    t: npt.ArrayLike, u: npt.ArrayLike, modulator: Mapping[str, Any]
) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.int8]]:
    """Valve command produced by a modulator from a recorded input fraction.

    Parameters
    ----------
    t : array_like of float, shape (n,)
        Sample times in s.
    u : array_like of float, shape (n,)
        Input fraction at the sample times.
    modulator : mapping
        The run's modulator settings, e.g. ``{"type": "pwm", "f_w": 20}`` (keys as in
        :func:`spa.modulate`, plus ``type``).

    Returns
    -------
    grid : numpy.ndarray of float64
        Uniform grid from ``t[0]`` with step the median sample step, covering ``t``.
    command : numpy.ndarray of int8
        The modulator output on that grid (``command[k]`` over ``[grid[k], grid[k+1])``).

    Raises
    ------
    ValueError
        If ``modulator`` has no ``type`` or invalid settings.

    Notes
    -----
    The input fraction is held between samples (the value at ``grid[k]`` is that of the last
    sample at or before it), then modulated at the grid step. The step is the median sample
    step rounded to 9 significant digits.
    """
    tt = _check_times(t)
    uu = np.asarray(u, dtype=np.float64)
    if uu.shape != tt.shape:
        raise ValueError(f"u must have shape {tt.shape} like t, got {uu.shape}")
    if "type" not in modulator:
        raise ValueError(f"modulator must have a 'type' key, got {dict(modulator)!r}")
    settings = {k: float(v) for k, v in modulator.items() if k != "type"}
    # Median step, rounded to 9 significant digits: a nominal 1 ms step is then exactly 1e-3
    # (float noise in the recorded times would otherwise shift the modulator's ties).
    dt = float(f"{float(np.median(np.diff(tt))):.9g}")
    n = math.floor((tt[-1] - tt[0]) / dt + 1e-9) + 1
    grid = tt[0] + dt * np.arange(n)
    idx = np.searchsorted(tt, grid + 1e-9 * dt, side="right") - 1
    command = modulate(str(modulator["type"]), uu[np.maximum(idx, 0)], dt, **settings)
    return grid, command


@dataclass(frozen=True)
class ValidationResult:
    """Scores of a model re-simulation against one measured run.

    Attributes
    ----------
    fit_percent : float
        ``100*(1 - ||p - p_model|| / ||p - mean(p)||)``.
    rmse : float
        Root-mean-square error in bar.
    max_abs_error : float
        Largest absolute error in bar.
    n : int
        Number of samples compared.
    p0 : float
        Initial pressure used, bar.
    trace : pandas.DataFrame
        ``t``, ``p``, ``p_model``, ``valve`` (int8): the data of an overlay plot.
    """

    fit_percent: float
    rmse: float
    max_abs_error: float
    n: int
    p0: float
    trace: pd.DataFrame

    def as_dict(self) -> dict[str, float | int]:
        """Return the scores (not the trace) as a plain dictionary."""
        return {
            "fit_percent": self.fit_percent,
            "rmse": self.rmse,
            "max_abs_error": self.max_abs_error,
            "n": self.n,
            "p0": self.p0,
        }


def validate_run(
    table: pd.DataFrame,
    params: ValveParams,
    modulator: Mapping[str, Any] | None = None,
    *,
    p0: float | None = None,
) -> ValidationResult:
    """Re-simulate a run with given parameters and score it against the measurement.

    Parameters
    ----------
    table : pandas.DataFrame
        Run table with ``t`` (s, strictly increasing) and ``p`` (bar), and ``valve`` (0/1) or
        ``u`` (input fraction).
    params : ValveParams
        Parameters to validate.
    modulator : mapping, optional
        The run's modulator, e.g. ``{"type": "iipfm", "t_l": 0.02, "gain": 1.15}``. Used only
        when the table has no ``valve`` column: the command is then rebuilt from ``u`` by
        :func:`command_from_input`.
    p0 : float, optional
        Initial pressure in bar; by default :func:`initial_pressure` of the measurement.

    Returns
    -------
    ValidationResult
        FIT %, RMSE, largest absolute error and the model trace.

    Raises
    ------
    ValueError
        If a column is missing or malformed, or the table has neither ``valve`` nor ``u`` with
        a ``modulator``.

    Notes
    -----
    With a ``valve`` column the model is exact at the sample times (the recorded command is
    piecewise constant between samples). From ``u`` the command is the modulator's output on
    a uniform grid at the median sample step, and the model is still evaluated exactly at the
    sample times for that command.
    """
    if not isinstance(table, pd.DataFrame):
        raise ValueError(f"table must be a pandas DataFrame, got {type(table).__name__}")
    for col in ("t", "p"):
        if col not in table.columns:
            raise ValueError(f"table must have a {col!r} column; it has {list(table.columns)}")
    t = _check_times(table["t"].to_numpy(), "table['t']")
    p = table["p"].to_numpy(dtype=np.float64)
    if not np.all(np.isfinite(p)):
        raise ValueError("table['p'] must be finite")
    start = initial_pressure(t, p) if p0 is None else float(p0)
    if "valve" in table.columns:
        valve = _check_valve(table["valve"].to_numpy(), t.size, "table['valve']")
        model = model_response(t, valve, params, start)
    elif "u" in table.columns and modulator is not None:
        # a setting that inverts a valve without naming one inverts the identified valve
        setting = Modulator.from_mapping(modulator).bind(params)
        grid, command = command_from_input(t, table["u"].to_numpy(), setting)
        k = np.concatenate(([0], edge_indices(command)))
        level = command[k].astype(bool)
        hold = np.where(level, params.t_on, params.t_off)
        hold[0] = 0.0
        model = replay(t, grid[k], level, hold, start, params)
        idx = np.searchsorted(grid, t + 1e-9 * (grid[1] - grid[0]), side="right") - 1
        valve = command[np.clip(idx, 0, command.size - 1)]
    else:
        raise ValueError(
            "table has no 'valve' column; pass modulator=... to rebuild the command from 'u'"
            if "u" in table.columns
            else "table needs a 'valve' column, or a 'u' column and a modulator"
        )
    err = p - model
    trace = pd.DataFrame({"t": t, "p": p, "p_model": model, "valve": valve.astype(np.int8)})
    return ValidationResult(
        fit_percent=fit_percent(p, model),
        rmse=float(np.sqrt(np.mean(err * err))),
        max_abs_error=float(np.max(np.abs(err))),
        n=int(t.size),
        p0=start,
        trace=trace,
    )


def validate_runs(
    runs: Mapping[str, pd.DataFrame] | Sequence[pd.DataFrame],
    params: ValveParams,
    modulators: Mapping[str, Mapping[str, Any] | None] | None = None,
    kinds: Mapping[str, str] | None = None,
) -> pd.DataFrame:
    """Validate several runs; one row of scores per run.

    Parameters
    ----------
    runs : mapping of run id to table, or sequence of tables
        Run tables (see :func:`validate_run`); a sequence gets ids ``"0"``, ``"1"``, ...
    params : ValveParams
        Parameters to validate.
    modulators : mapping of run id to modulator settings, optional
        Needed for runs without a ``valve`` column.
    kinds : mapping of run id to kind, optional
        Copied into a ``kind`` column (e.g. ``"staircase"``).

    Returns
    -------
    pandas.DataFrame
        Columns ``run``, ``kind``, ``modulator`` (type) and ``setting``
        (:attr:`spa.model.modulators.Modulator.label`; both empty for a run without a
        modulator), ``fit_percent``, ``rmse``, ``max_abs_error``, ``n``, ``p0``, in the order
        of ``runs``. A run whose log holds no command to replay (neither ``valve`` nor ``u``
        with a modulator: a charge logged without its valve, whose onset the log does not
        show) has no row; ``attrs["not_replayed"]`` maps its id to why.
    """
    items = list(runs.items()) if isinstance(runs, Mapping) else list(enumerate(runs))
    rows = []
    not_replayed: dict[str, str] = {}
    for rid, table in progress(items, "replaying runs"):
        mod = None if modulators is None else modulators.get(str(rid))
        if "valve" not in table.columns and not ("u" in table.columns and mod):
            not_replayed[str(rid)] = (
                "no valve command in the log: when the valve switched is not known, so the "
                "model cannot replay it"
            )
            continue
        res = validate_run(table, params, mod)
        kind = None if kinds is None else kinds.get(str(rid))
        setting = Modulator.from_mapping(mod) if mod else None
        rows.append(
            {
                "run": str(rid),
                "kind": kind,
                "modulator": setting.kind if setting else "",
                "setting": setting.label if setting else "",
                **res.as_dict(),
            }
        )
    columns = ["run", "kind", "modulator", "setting", "fit_percent", "rmse", "max_abs_error"]
    out = pd.DataFrame(rows, columns=[*columns, "n", "p0"])
    out.attrs["not_replayed"] = not_replayed
    return out


def with_fit_before_refinement(
    table: pd.DataFrame,
    runs: Mapping[str, pd.DataFrame],
    params_file: str | Path,
    modulators: Mapping[str, Mapping[str, Any] | None] | None = None,
    kinds: Mapping[str, str] | None = None,
) -> pd.DataFrame:
    """``table`` (:func:`validate_runs`) with each run's FIT before the refinement beside it.

    Parameters
    ----------
    table : pandas.DataFrame
        :func:`validate_runs` with the identified (refined) parameters.
    runs, modulators, kinds
        As :func:`validate_runs`.
    params_file : str or Path
        The identification's ``params.yaml``; its ``refinement: start:`` holds the charge,
        discharge and pulse fits' parameters.

    Returns
    -------
    pandas.DataFrame
        A copy with ``fit_before_refinement`` (%) before ``fit_percent``; ``table`` itself
        when the file records no refinement.
    """
    from spa._yaml import read_yaml

    start = ((read_yaml(params_file) or {}).get("refinement") or {}).get("start")
    if not start:
        return table
    before = validate_runs(runs, ValveParams(**start), modulators, kinds)
    out = table.copy()
    out.insert(
        out.columns.get_loc("fit_percent"),
        "fit_before_refinement",
        before["fit_percent"].to_numpy(),
    )
    return out
