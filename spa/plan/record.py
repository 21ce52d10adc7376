"""``spa record``: the player's stream split into the plan's run files.

The stream (a file, stdin, or a serial port read as a plain file) holds ``R <index>``
lines, one ``tick,adc,valve,q`` line per logged tick (hex but the valve) and
``E <index> done|vent``, and ``O <steps>`` before a tick that started late (an overrun).
Each run becomes ``<file>`` of ``plan.yaml`` with ``t`` (s, from the
tick counter), ``p`` (bar, from the declared calibration), ``valve``, ``u`` and, for a
closed-loop run, its set-point ``r`` (bar); a jump of
the tick counter (mod 65536) is a dropped line; both are reported.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import yaml

from spa.plan.limits import PlanError
from spa.plan.session import Q15

__all__ = ["RunCapture", "parse_stream", "read_plan", "record_stream"]


@dataclass
class RunCapture:
    """One run as captured: its rows and what went wrong."""

    index: int
    rows: list[tuple[int, int, int, int]] = field(default_factory=list)
    end: str = ""
    bad_lines: list[int] = field(default_factory=list)
    overruns: int = 0


def read_plan(folder: str | Path) -> dict[str, Any]:
    """``plan.yaml`` of a plan folder.

    Raises
    ------
    PlanError
        When the folder has no readable ``plan.yaml``.
    """
    path = Path(folder) / "plan.yaml"
    if not path.is_file():
        raise PlanError(f"{path}: no plan.yaml (make one with spa plan)")
    data = yaml.safe_load(path.read_text(encoding="utf-8"))
    if not isinstance(data, dict) or "runs" not in data:
        raise PlanError(f"{path}: not a plan (no runs)")
    return data


def parse_stream(lines: Iterable[str]) -> dict[int, RunCapture]:
    """The runs of a stream by index (a run started twice keeps its last start)."""
    runs: dict[int, RunCapture] = {}
    current: RunCapture | None = None
    for n, raw in enumerate(lines, start=1):
        line = raw.strip()
        if not line:
            continue
        if line.startswith("R "):
            idx = int(line.split()[1])
            current = runs[idx] = RunCapture(idx)
            continue
        if line.startswith("E "):
            parts = line.split()
            if current is not None and int(parts[1]) == current.index:
                current.end = parts[2] if len(parts) > 2 else "done"
            current = None
            continue
        if current is None:
            continue
        if line.startswith("O "):
            current.overruns += 1
            continue
        try:
            tick, adc, valve, q = line.split(",")
            current.rows.append((int(tick, 16), int(adc, 16), int(valve), int(q, 16)))
        except ValueError:
            current.bad_lines.append(n)
    return runs


def _table(
    cap: RunCapture, dt: float, cal: dict[str, Any], with_u: bool, setpoints: Any = None
) -> tuple[pd.DataFrame, int]:
    data = np.asarray(cap.rows, dtype=np.int64).reshape(-1, 4)
    step = np.diff(data[:, 0]) % 65536
    ticks = np.concatenate([[0], np.cumsum(step)])
    gaps = int(np.count_nonzero(step != 1))
    table = {
        "t": np.round(ticks * dt, 9),
        "p": (data[:, 1] - cal["zero_counts"]) * cal["bar_per_count"],
        "valve": data[:, 2].astype(np.int8),
    }
    if with_u or setpoints:
        table["u"] = data[:, 3] / Q15
    if setpoints:  # a closed loop's set-point, bar, at each tick the counter says it is at
        r = np.repeat([float(v) for _, v in setpoints], [int(n) for n, _ in setpoints])
        table["r"] = r[np.clip(ticks, 0, r.size - 1)]
    return pd.DataFrame(table), gaps


def record_stream(
    folder: str | Path, lines: Iterable[str], recorded: str | None = None
) -> list[str]:
    """Split a stream into the plan's run files; return one line per run and per problem.

    ``recorded``: when the session was recorded (ISO 8601; default: now). When a run was
    written and ``dataset.yaml`` has no ``recorded:`` yet, it gets this one
    (:func:`date_dataset`), so that the overview orders the sessions as they were recorded.

    Raises
    ------
    PlanError
        When a run file exists already (a recording is never overwritten).
    """
    root = Path(folder)
    plan = read_plan(root)
    dt = float(plan["tick"])
    cal = plan["calibration"]
    caps = parse_stream(lines)
    report = []
    by_index = {int(r["index"]): r for r in plan["runs"]}
    for idx in sorted(caps):
        if idx not in by_index:
            report.append(f"warning: stream run {idx} is not in plan.yaml: skipped")
    for idx, run in sorted(by_index.items()):
        cap = caps.get(idx)
        if cap is None or not cap.rows:
            report.append(f"missing: {run['id']} (run {idx}) is not in the stream")
            continue
        path = root / run["file"]
        if path.exists():
            raise PlanError(f"{path} exists: spa record never overwrites a recording")
        table, gaps = _table(cap, dt, cal, "modulator" in run, run.get("setpoints"))
        path.parent.mkdir(parents=True, exist_ok=True)
        table.to_csv(path, index=False, float_format="%.9g")
        notes = []
        if gaps:
            notes.append(f"{gaps} jump(s) of the tick counter (dropped lines)")
        if cap.overruns:
            notes.append(f"{cap.overruns} overrun(s): ticks that started a step late or more")
        if len(table) != int(run.get("logged_ticks", len(table))):
            notes.append(f"{len(table)} of {run['logged_ticks']} lines")
        if cap.end == "vent":
            notes.append("VENTED: the pressure passed the rated maximum")
        elif cap.end != "done":
            notes.append("no end line: the run was cut")
        if cap.bad_lines:
            notes.append(
                f"{len(cap.bad_lines)} unreadable line(s), first at stream line {cap.bad_lines[0]}"
            )
        status = "; ".join(notes) if notes else "ok"
        report.append(f"{path}: {len(table)} samples, {status}")
    if any(not line.startswith(("missing", "warning")) for line in report):
        from spa.plan.folder import now_stamp

        date_dataset(root / "dataset.yaml", recorded or now_stamp())
    return report


def date_dataset(spec: Path, when: str) -> bool:
    """Give the ``dataset.yaml`` that ``spa plan`` wrote its ``recorded:`` line, after
    ``origin:``; every other line is kept as it is (a lab's edits too). Nothing happens when
    it has one already.

    Returns
    -------
    bool
        Whether the line was added.

    Examples
    --------
    >>> import tempfile
    >>> f = Path(tempfile.mkdtemp()) / "dataset.yaml"
    >>> _ = f.write_text("name: a\\norigin: bench\\nruns: []\\n")
    >>> date_dataset(f, "2026-12-02T09:30+00:00"), date_dataset(f, "2027-01-01")
    (True, False)
    >>> print(f.read_text(), end="")
    name: a
    origin: bench
    recorded: '2026-12-02T09:30+00:00'
    runs: []
    """
    text = spec.read_text(encoding="utf-8")
    lines = text.splitlines(keepends=True)
    if any(line.startswith("recorded:") for line in lines):
        return False
    at = next((i + 1 for i, line in enumerate(lines) if line.startswith("origin:")), 0)
    lines.insert(at, f"recorded: '{when}'\n")
    spec.write_text("".join(lines), encoding="utf-8")
    return True
