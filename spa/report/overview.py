"""The view across datasets: one row per session, and where the valve changed between sessions.

A dataset's job writes its row (:func:`overview_row`: date, rig, the five identified
parameters with their 95 % intervals, validation FIT, the recommended setting and its J_exact,
status) as ``results/<dataset>/report/overview.json``; the overview job puts the rows in
session order (:func:`overview_table`), flags every parameter whose interval excludes the
previous session's of the same valve identified from the same kind of runs
(:func:`interval_changes`) and fits each parameter's trend
(:func:`trend`). The table is ``results/overview.csv``, also the data of Fig. O1
(:func:`spa.report.overview_figure.plot_overview`).

>>> interval_changes([1.0, 1.1, 2.0], [1.2, 1.3, 2.2], ["a", "a", "a"]).tolist()
[False, False, True]
"""

from __future__ import annotations

import datetime
import json
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from spa.io import read_yaml
from spa.report.params import PARAM_NAMES

__all__ = [
    "UNDATED",
    "dataset_session",
    "interval_changes",
    "overview_row",
    "overview_table",
    "rig_label",
    "session_days",
    "trend",
]

UNDATED = "undated"
"""The ``recorded`` cell of a dataset whose ``dataset.yaml`` has no ``recorded:`` date."""


def rig_label(rig: Mapping[str, Any] | None) -> str:
    """A short name of a bench: ``rig.name``, else ``rig.valve``, else ``"unnamed rig"``.

    Examples
    --------
    >>> rig_label({"valve": "V1", "actuator": "A"}), rig_label({"name": "bench 2"}), rig_label({})
    ('V1', 'bench 2', 'unnamed rig')
    """
    rig = rig or {}
    for key in ("name", "valve"):
        if rig.get(key):
            return str(rig[key])
    return "unnamed rig"


def valve_identity(rig: Mapping[str, Any] | None, dataset: str, simulated: bool = False) -> str:
    """The valve a session measured, for comparing sessions: the rig and the dataset's own
    valve name (``rig.valve``); a simulated dataset is a valve of its own.

    Sessions of one valve share a trend in Fig. O1 and are compared for a change; sessions
    of different valves never are, whatever rig label they share.

    Examples
    --------
    >>> valve_identity({"name": "bench 2", "valve": "V1"}, "s1")
    'bench 2 / V1'
    >>> valve_identity({"valve": "V1"}, "s1"), valve_identity({}, "s1")
    ('V1', 'unnamed rig')
    >>> valve_identity(None, "large-slow", simulated=True)
    'simulated: large-slow'
    """
    if simulated:
        return f"simulated: {dataset}"
    label = rig_label(rig)
    valve = str((rig or {}).get("valve") or "")
    return f"{label} / {valve}" if valve and valve != label else label


def dataset_valve(raw_dir: str | Path, dataset: str) -> str:
    """:func:`valve_identity` of ``raw_dir/<dataset>``: a dataset without ``dataset.yaml``
    is simulated; one whose ``dataset.yaml`` does not parse is its own unnamed valve."""
    from spa.datasets import DatasetError, load_spec

    folder = Path(raw_dir) / dataset
    if not (folder / "dataset.yaml").is_file():
        return valve_identity(None, dataset, simulated=True)
    try:
        spec = load_spec(folder)
    except DatasetError:
        return f"unnamed rig: {dataset}"
    return valve_identity(spec.rig, dataset)


def dataset_session(raw_dir: str | Path, dataset: str) -> tuple[str | None, str]:
    """The session's date (``recorded:``) and rig label of ``raw_dir/<dataset>/dataset.yaml``.

    A dataset without ``dataset.yaml`` (simulated) has neither: ``(None, "simulated")``; one
    whose ``dataset.yaml`` does not parse is ``(None, "unnamed rig")``.
    """
    from spa.datasets import DatasetError, load_spec

    folder = Path(raw_dir) / dataset
    if not (folder / "dataset.yaml").is_file():
        return None, "simulated"
    try:
        spec = load_spec(folder)
    except DatasetError:
        return None, "unnamed rig"
    return spec.recorded, rig_label(spec.rig)


def _read_yaml(path: Path) -> dict[str, Any]:
    if not path.is_file():
        return {}
    doc = read_yaml(path)
    return doc if isinstance(doc, dict) else {}


def _lost_stages(folder: Path) -> set[str]:
    """The stages of a dataset folder whose status says they failed or were skipped: their
    outputs are placeholders."""
    from spa.pipeline.status import STATUS_DIR, read_status

    lost = set()
    for path in sorted((folder / STATUS_DIR).glob("*.json")):
        status = read_status(path)
        if status is not None and not status.get("ok", False):
            lost.add(path.stem)
    return lost


def _no_runs(folder: Path) -> list[str]:
    """The kinds of runs the stages of a dataset folder found none of (their status's
    ``no_runs``, :class:`spa.pipeline.status.NoRuns`), in stage order."""
    from spa.pipeline.outputs import STAGES
    from spa.pipeline.status import STATUS_DIR, read_status

    kinds: list[str] = []
    for stage in STAGES:
        status = read_status(folder / STATUS_DIR / f"{stage.name}.json") or {}
        if status.get("ok", False):
            kinds += [str(r.get("kind")) for r in status.get("no_runs") or [] if r.get("kind")]
    return list(dict.fromkeys(kinds))


def overview_row(
    folder: str | Path,
    name: str,
    recorded: str | None,
    rig: str,
    failed: str | None = None,
    valve: str | None = None,
) -> dict[str, Any]:
    """A dataset's row of the overview, from its results folder.

    Parameters
    ----------
    folder : str or Path
        ``results/<dataset>``: ``identification/params.yaml``, ``validation/fit.csv`` and
        ``tuning/recommendation.yaml`` are read when present and valid.
    name : str
        The dataset.
    recorded : str or None
        Its ISO date (``dataset.yaml`` ``recorded:``), or None.
    rig : str
        Its rig's short name (:func:`rig_label`).
    failed : str or None
        The stage that failed, if one did (the status). The numbers of each stage that
        worked are kept: the parameters when identification worked, whatever failed after
        it; a stage that failed or was skipped (its status file, ``<folder>/status``) leaves
        its numbers empty.
    valve : str, optional
        Its valve (:func:`valve_identity`); default the rig.

    Returns
    -------
    dict
        ``dataset``, ``recorded`` (ISO date or :data:`UNDATED`), ``rig``, ``valve``,
        ``status`` (``ok``
        or ``failed: <stage>``, then ``; no runs: <kinds>`` when stages found no runs of
        their kind), ``<p>``, ``<p>_lo``, ``<p>_hi`` for each parameter (SI units,
        NaN when missing), ``<p>_basis`` (the kinds of runs it stands on,
        :func:`spa.identification.results.estimate_basis`; ``""`` when ``params.yaml``
        predates it), ``fit_median``, ``fit_min`` (%), ``recommended``, ``J``, ``J_exact``.
    """
    folder = Path(folder)
    row: dict[str, Any] = {
        "dataset": name,
        "recorded": recorded or UNDATED,
        "rig": rig,
        "valve": valve or rig,
        "status": f"failed: {failed}" if failed else "ok",
    }
    missing = _no_runs(folder)
    if missing:  # "ok" alone would stand over empty tables
        row["status"] += f"; no runs: {', '.join(missing)}"
    lost = _lost_stages(folder) if failed else set()
    params = {} if "identify" in lost else _read_yaml(folder / "identification" / "params.yaml")
    for p in PARAM_NAMES:
        entry = params.get(p) if isinstance(params.get(p), Mapping) else {}
        for suffix, key in (("", "value"), ("_lo", "lo"), ("_hi", "hi")):
            value = entry.get(key)
            row[p + suffix] = float(value) if isinstance(value, int | float) else float("nan")
        row[f"{p}_basis"] = str(entry.get("basis") or "")
    fit_path = folder / "validation" / "fit.csv"
    fit = pd.Series(dtype=float)
    if "validate_model" not in lost and fit_path.is_file():
        table = pd.read_csv(fit_path)
        if "fit_percent" in table:
            fit = pd.to_numeric(table["fit_percent"], errors="coerce").dropna()
    row["fit_median"] = float(fit.median()) if len(fit) else float("nan")
    row["fit_min"] = float(fit.min()) if len(fit) else float("nan")
    rec = {} if "tune" in lost else _read_yaml(folder / "tuning" / "recommendation.yaml")
    best = rec.get("recommended") if isinstance(rec.get("recommended"), Mapping) else {}
    row["recommended"] = str(best.get("description") or best.get("label") or "")
    for key in ("J", "J_exact"):
        value = best.get(key)
        row[key] = float(value) if isinstance(value, int | float) else float("nan")
    return row


def write_row(path: str | Path, row: Mapping[str, Any]) -> None:
    """Write a row as JSON (NaN as null), sorted keys: the same row, the same bytes."""
    clean = {k: (None if isinstance(v, float) and np.isnan(v) else v) for k, v in row.items()}
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    Path(path).write_text(json.dumps(clean, indent=1, sort_keys=True) + "\n", encoding="utf-8")


def read_rows(paths: Iterable[str | Path]) -> list[dict[str, Any]]:
    """The rows written by :func:`write_row` (null back to NaN)."""
    rows = []
    for path in paths:
        row = json.loads(Path(path).read_text(encoding="utf-8"))
        rows.append({k: (float("nan") if v is None else v) for k, v in row.items()})
    return rows


def interval_changes(lo: Sequence[float], hi: Sequence[float], groups: Sequence[str]) -> np.ndarray:
    """Where a session's interval excludes the previous session's of its group (valve).

    Parameters
    ----------
    lo, hi : sequence of float
        Each session's interval, in session order (NaN: none, never flagged, skipped).
    groups : sequence of str
        Each session's group (its valve, :func:`valve_identity`): a session is compared
        with the previous one of its group.

    Returns
    -------
    numpy.ndarray of bool
        True where ``[lo, hi]`` and the previous interval do not overlap.

    Examples
    --------
    >>> interval_changes([1, 5, 1.5], [2, 6, 2.5], ["a", "b", "a"]).tolist()
    [False, False, False]
    """
    lo_, hi_ = np.asarray(lo, dtype=float), np.asarray(hi, dtype=float)
    out = np.zeros(len(lo_), dtype=bool)
    last: dict[str, int] = {}
    for i, group in enumerate(groups):
        if not (np.isfinite(lo_[i]) and np.isfinite(hi_[i])):
            continue
        j = last.get(group)
        if j is not None:
            out[i] = bool(lo_[i] > hi_[j] or hi_[i] < lo_[j])
        last[group] = i
    return out


def session_days(recorded: Sequence[str]) -> np.ndarray:
    """Each session's place on the time axis, in days: its date's day number when every
    session is dated, else its position (0, 1, ...).

    Examples
    --------
    >>> session_days(["2025-01-01", "2025-01-08"]).tolist()
    [0.0, 7.0]
    >>> session_days(["2025-01-01", "undated"]).tolist()
    [0.0, 1.0]
    """
    if len(recorded) and all(r != UNDATED for r in recorded):
        days = np.array([_day_number(r) for r in recorded], float)
        return days - days[0]
    return np.arange(len(recorded), dtype=float)


def _day_number(recorded: str) -> float:
    """The day number of a ``recorded`` cell, the time of day as its fraction.

    Examples
    --------
    >>> _day_number("2025-01-02T12:00") - _day_number("2025-01-02")
    0.5
    """
    when = datetime.datetime.fromisoformat(recorded)
    return when.toordinal() + (when.hour * 60 + when.minute) / 1440


def trend(x: Sequence[float], y: Sequence[float]) -> tuple[float, float]:
    """Least-squares line ``y = a + b x`` through the finite points: ``(a, b)``, NaN when
    fewer than two.

    Examples
    --------
    >>> trend([0, 1, 2], [1.0, 3.0, 5.0])
    (1.0, 2.0)
    """
    x_, y_ = np.asarray(x, float), np.asarray(y, float)
    ok = np.isfinite(x_) & np.isfinite(y_)
    if ok.sum() < 2 or np.ptp(x_[ok]) == 0:
        return float("nan"), float("nan")
    b, a = np.polyfit(x_[ok], y_[ok], 1)
    return round(float(a), 12), round(float(b), 12)


_COLUMNS = (
    ["session", "dataset", "recorded", "rig", "valve", "status"]
    + [p + s for p in PARAM_NAMES for s in ("", "_lo", "_hi")]
    + ["fit_median", "fit_min", "recommended", "J", "J_exact"]
)


def overview_table(rows: Iterable[Mapping[str, Any]]) -> pd.DataFrame:
    """The overview: rows in session order, with the interval changes.

    Parameters
    ----------
    rows : iterable of mapping
        :func:`overview_row` of each dataset.

    Returns
    -------
    pandas.DataFrame
        Dated sessions by date (then name), then the undated ones by name; columns
        ``session`` (1, 2, ...), the row's columns, and ``changed_<p>`` for each parameter
        (:func:`interval_changes` within each valve, column ``valve``, the rig for rows
        written without one, and within the same kind of runs, ``<p>_basis``: a delay
        from a pilot's pulse runs is never compared with one refined on a full session's
        modulated runs).
    """
    table = pd.DataFrame(list(rows))
    if table.empty:
        cols = ["session", "dataset", "recorded", "rig", "status"]
        return pd.DataFrame(columns=cols + [f"changed_{p}" for p in PARAM_NAMES])
    undated = table["recorded"] == UNDATED
    table = table.assign(_undated=undated).sort_values(
        ["_undated", "recorded", "dataset"], kind="stable"
    )
    table = table.drop(columns="_undated").reset_index(drop=True)
    table.insert(0, "session", np.arange(1, len(table) + 1))
    table = table[[c for c in _COLUMNS if c in table] + [c for c in table if c not in _COLUMNS]]
    if "valve" not in table:
        table.insert(table.columns.get_loc("rig") + 1, "valve", table["rig"])
    table["valve"] = table["valve"].where(table["valve"].notna(), table["rig"])
    for p in PARAM_NAMES:
        basis = table[f"{p}_basis"] if f"{p}_basis" in table else pd.Series("", index=table.index)
        groups = table["valve"].astype(str) + " | " + basis.fillna("").astype(str)
        table[f"changed_{p}"] = interval_changes(table[f"{p}_lo"], table[f"{p}_hi"], groups)
    return table
