"""The plan's folder ``raw/<name>/``: ``plan.yaml`` (the runs, their order, the seed, the
sizes and margins), ``dataset.yaml`` already describing the runs spa record will write,
``checklist.md`` and the player (``player/player.h``, ``harness.c``, ``player.ino``).

It is written into a new folder only: an existing folder (a dataset) is refused.
"""

from __future__ import annotations

import math
import re
from pathlib import Path
from typing import Any

import numpy as np

from spa.io import dump_yaml
from spa.plan.design import SessionDesign
from spa.plan.limits import LINE_BYTES, PlanError, baud_needed
from spa.plan.player import TICK_ORDER, harness_source, player_header, player_sketch

__all__ = ["calibration_for", "checklist", "dataset_yaml", "plan_yaml", "write_plan"]

_NAME = re.compile(r"[A-Za-z0-9._-]+")


def calibration_for(p_max: float, bits: int = 10) -> dict[str, Any]:
    """The declared sensor calibration: a ratiometric sensor whose 10-90 % span covers
    1.25 times the rated maximum (rounded up to a 1-2-5 value), read by a ``bits`` ADC.

    Examples
    --------
    >>> calibration_for(1.0)
    {'adc_bits': 10, 'zero_counts': 102, 'bar_per_count': 0.00244140625, 'full_scale_bar': 2.0}
    """
    span = 1.25 * p_max
    decade = 10 ** math.floor(math.log10(span))
    full = next(m * decade for m in (1, 2, 2.5, 5, 10) if m * decade >= span - 1e-12)
    counts = 2**bits
    return {
        "adc_bits": bits,
        "zero_counts": round(0.1 * counts),
        "bar_per_count": full / (0.8 * counts),
        "full_scale_bar": float(full),
    }


def _adc_max(cal: dict[str, Any], p_max: float) -> int:
    return int(cal["zero_counts"] + math.floor(p_max / cal["bar_per_count"]))


def now_stamp() -> str:
    """This minute, UTC, as ISO 8601 (``2026-12-02T16:59+00:00``): a session's ``planned:``
    and ``recorded:`` when nothing else says when."""
    import datetime

    return datetime.datetime.now(datetime.UTC).isoformat(timespec="minutes")


def plan_yaml(
    design: SessionDesign,
    name: str,
    cal: dict[str, Any],
    extra: dict[str, Any],
    planned: str | None = None,
) -> dict[str, Any]:
    """``plan.yaml``'s content; ``planned`` is when (ISO 8601, default: now)."""
    dt = design.dt
    runs = []
    for i, run in enumerate(design.runs):
        entry: dict[str, Any] = {
            "index": i,
            "id": run.id,
            "kind": run.kind,
            "file": run.file,
            "block": run.block,
            "seconds": round(run.ticks * dt, 6),
            "logged_ticks": int(run.logged().sum()),
        }
        if run.modulator is not None:
            entry["modulator"] = run.modulator.to_mapping()
        if run.closed:
            # [ticks, bar] as the player holds them: its segments' numbers are floats
            entry["setpoints"] = [[int(g.ticks), float(np.float32(g.a))] for g in run.segments]
        entry["notes"] = run.notes
        runs.append(entry)
    return {
        "name": name,
        "planned": planned or now_stamp(),
        "stage": "pilot" if design.pilot else "full",
        "seed": design.seed,
        "order": "identification first (start), modulated runs in random order from the seed, "
        "identification again at the end (drift check)"
        if not design.pilot
        else "pilot: identification only; re-plan from its params.yaml",
        "tick": dt,
        "tick_order": list(TICK_ORDER),
        "valve_edges": "on_tick",
        "line": {
            "bytes": LINE_BYTES,
            "format": "tick(hex, mod 65536),adc(hex),valve,xi(Q15 hex)",
            "baud_needed": round(baud_needed(dt)),
            "link": design.link,
        },
        "calibration": cal,
        "vent_above_counts": _adc_max(cal, design.limits.p_max),
        "rest_between_runs": design.rest,
        "duration_s": round(design.duration, 1),
        "prior": {
            k: float(getattr(design.prior, k)) for k in ("c1", "k2", "tau2", "t_on", "t_off")
        },
        "limits": design.limits.to_mapping(),
        "settings": {k: {kk: v for kk, v in s.items()} for k, s in design.settings.items()},
        "refused": dict(design.refused),
        "resolution": list(design.margins.get("warnings", [])),
        **extra,
        "runs": runs,
    }


def plan_stage(design: SessionDesign) -> str:
    """``pilot`` or ``full``."""
    return "pilot" if design.pilot else "full"


def dataset_yaml(design: SessionDesign, name: str) -> dict[str, Any]:
    """``dataset.yaml``'s content: every analysed run, as spa record writes it."""
    runs = []
    for run in design.runs:
        if not run.analysed:
            continue
        entry: dict[str, Any] = {"id": run.id, "kind": run.kind, "file": run.file}
        if run.modulator is not None:
            entry["modulator"] = run.modulator.to_mapping()
        else:
            entry["columns"] = {"u": None}
        entry["notes"] = run.notes
        runs.append(entry)
    return {
        "name": name,
        "description": f"Bench session planned by spa plan ({plan_stage(design)}); "
        "recorded by spa record",
        "origin": "bench",
        "rig": {
            "valve": "TODO: the valve",
            "actuator": f"TODO: the actuator (rated {design.limits.p_max:g} bar)",
            "sensors": "pressure sensor on the player's ADC (calibration in plan.yaml)",
            "controller": f"spa plan player, tick {design.dt * 1e3:g} ms",
        },
        "units": {"time": "s", "pressure": "bar"},
        "columns": {"t": "t", "p": "p", "valve": "valve", "u": "u"},
        "sample_step": design.dt,
        "valve_edges": "on_tick",
        "runs": runs,
    }


def gauge(p: float) -> str:
    """A pressure as a regulator's gauge shows it: to 0.01 bar below 10 bar, 0.1 bar above.

    Examples
    --------
    >>> gauge(1.49979), gauge(2.0), gauge(12.34)
    ('1.50', '2.00', '12.3')
    """
    return f"{p:.2f}" if p < 10 else f"{p:.1f}"


def checklist(design: SessionDesign, name: str, cal: dict[str, Any]) -> str:
    """The session's checklist, one screen."""
    lim = design.limits
    minutes = design.duration / 60
    n = len(design.runs)
    baud = f"{lim.baud:.0f}" if lim.baud is not None else "the logger's"
    lines = [
        f"# Session {name}: {n} runs, about {minutes:.0f} min",
        "",
        f"- [ ] Regulator at {gauge(min(design.prior.k2, lim.p_max))} bar, no higher than the "
        f"rated {lim.p_max:g} bar",
        "- [ ] Actuator on, no leak; valve on VALVE_PIN (HIGH = charge)",
        f"- [ ] Sensor on SENSOR_PIN: {cal['zero_counts']} counts at 0 bar, "
        f"{cal['bar_per_count'] * 1e3:.4g} mbar/count",
        f"- [ ] player/player.ino flashed; serial at {baud} baud",
        *(
            ["- [ ] player/controller.h beside player.h: the closed-loop runs play it"]
            if any(run.closed for run in design.runs)
            else []
        ),
        f"- [ ] Capture: spa record raw/{name} --stream <port>",
        f"- [ ] Shut-off in reach: the player vents above {lim.p_max:g} bar, after",
        "      each run and when the link stalls",
        f"- [ ] Let it play: zero, preconditioning, then {n - 2} runs",
        f"- [ ] Then: spa validate raw/{name}",
        f"      and spa identify raw/{name}",
    ]
    if design.pilot:
        lines.append(
            f"- [ ] Re-plan: spa plan raw/<next> --params results/{name}/identification/params.yaml"
        )
    if design.refused:
        lines += ["", "Not planned (the limits refuse them):"]
        lines += [f"- {k}: {v}"[:80] for k, v in design.refused.items()]
    return "\n".join(lines) + "\n"


def write_plan(
    folder: str | Path,
    design: SessionDesign,
    *,
    extra: dict[str, Any] | None = None,
    adc_bits: int = 10,
    controller: str | None = None,
    planned: str | None = None,
) -> list[Path]:
    """Write the plan into the new folder ``folder`` (its name is the dataset's).

    ``planned``: when the session was planned (ISO 8601; default: now), ``plan.yaml``'s
    ``planned:``.

    ``controller``: the exported controller's header (``controller.h`` text), written beside
    the player for the closed-loop runs (a verification session's).

    Raises
    ------
    PlanError
        If ``folder`` exists (a plan never writes into an existing dataset) or its name is
        not filename-safe.
    """
    out = Path(folder)
    name = out.name
    if not _NAME.fullmatch(name):
        raise PlanError(f"{out}: the folder's name must use letters, digits, '.', '_', '-'")
    if out.exists():
        raise PlanError(
            f"{out} exists: a plan is written into a new folder only (never into a dataset)"
        )
    cal = calibration_for(design.limits.p_max, adc_bits)
    closed = [run.id for run in design.runs if run.closed]
    if closed and controller is None:
        raise PlanError(f"runs {', '.join(closed)} close the loop: the plan needs controller.h")
    out.mkdir(parents=True)
    (out / "player").mkdir()
    files = {
        "plan.yaml": dump_yaml(
            plan_yaml(design, name, cal, extra or {}, planned), sort_keys=False, width=100
        ),
        "dataset.yaml": dump_yaml(dataset_yaml(design, name), sort_keys=False, width=100),
        "checklist.md": checklist(design, name, cal),
        "player/player.h": player_header(
            name,
            design.runs,
            design.dt,
            _adc_max(cal, design.limits.p_max),
            design.limits.p_max,
            round(design.rest / design.dt),
            cal,
        ),
        "player/harness.c": harness_source(),
        "player/player.ino": player_sketch(name, int(design.limits.baud or 115200)),
    }
    if controller is not None:
        files["player/controller.h"] = controller
    paths = []
    for rel, text in files.items():
        path = out / rel
        path.write_text(text, encoding="utf-8")
        paths.append(path)
    return paths
