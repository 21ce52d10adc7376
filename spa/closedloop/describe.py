"""``spa design-pi``: the PI gains for a valve and a modulator setting, as text or JSON."""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
import pandas as pd

from spa.closedloop.comparison import DEFAULTS
from spa.closedloop.design import DEFAULT_TAU_C, design_pi, local_models, simc
from spa.closedloop.experiments import LoopUnderTest, Staircase, run_staircase
from spa.model.modulators import Modulator
from spa.model.params import ValveParams

__all__ = ["design_summary", "format_design", "parse_modulator_spec"]


def parse_modulator_spec(spec: str) -> Modulator:
    """``"iipfm:t_l=0.02,gain=1.15"`` -> the Modulator.

    Raises
    ------
    ValueError
        For a malformed spec (the message shows the expected form) or a bad setting.

    Examples
    --------
    >>> parse_modulator_spec("iipfm:t_l=0.02,gain=1.15").label
    'iipfm-20ms-G1.15'
    """
    kind, _, rest = spec.partition(":")
    mapping: dict[str, Any] = {"type": kind.strip()}
    for item in filter(None, (s.strip() for s in rest.split(","))):
        name, eq, value = item.partition("=")
        if not eq:
            raise ValueError(
                f"modulator {spec!r}: expected KIND:NAME=VALUE,..., e.g. iipfm:t_l=0.02,gain=1.15"
            )
        try:
            mapping[name.strip()] = float(value)
        except ValueError:
            raise ValueError(f"modulator {spec!r}: {name} = {value!r} is not a number") from None
    return Modulator.from_mapping(mapping)


def design_summary(
    params: ValveParams,
    modulator: Modulator,
    *,
    tau_c: float = DEFAULT_TAU_C,
    levels: Sequence[float] | None = None,
    dt: float = 0.001,
    hold: float = 3.0,
) -> dict[str, Any]:
    """Local models, gains and the simulated staircase of the three controllers.

    Returns
    -------
    dict
        ``modulator``, ``tau_c``, ``local_models`` (one record per level: ``r``, ``xi_ff``,
        ``K``, ``tau``, ``theta``, ``kp``, ``ki``), ``controllers`` (name -> mapping) and
        ``staircase`` (name -> worst and best rise time and overshoot).
    """
    if levels is None:
        from spa.closedloop.comparison import setting_levels

        mod = modulator.bind(params)
        found, skipped, _ = setting_levels([mod], params, DEFAULTS)
        if mod.label not in found:
            raise ValueError(skipped.get(mod.label, f"{mod.label}: no levels on this valve"))
        levels = found[mod.label]
    lv = [float(v) for v in levels]
    designs = design_pi(modulator, params, levels=lv, tau_c=tau_c)
    m = local_models(lv, modulator, params)
    kp, ki = simc(m.gain, m.tau, m.dead_time, tau_c)
    table = pd.DataFrame(
        {
            "r": m.r,
            "xi_ff": m.xi,
            "K": m.gain,
            "tau": m.tau,
            "theta": m.dead_time,
            "kp": kp,
            "ki": ki,
        }
    )
    staircase = {}
    stairs = Staircase(lv, hold, dt)
    for name, ctrl in designs.items():
        _, steps = run_staircase(LoopUnderTest(modulator, ctrl, params), stairs)
        staircase[name] = {
            "rise_time_max": float(np.nanmax(steps["rise_time"])),
            "rise_time_min": float(np.nanmin(steps["rise_time"])),
            "overshoot_max": float(np.nanmax(steps["overshoot"])),
            "overshoot_min": float(np.nanmin(steps["overshoot"])),
        }
    return {
        "modulator": modulator.to_mapping(),
        "description": modulator.description,
        "tau_c": tau_c,
        "local_models": table.to_dict(orient="records"),
        "controllers": {name: c.to_mapping() for name, c in designs.items()},
        "staircase": staircase,
    }


def format_design(summary: Mapping[str, Any], as_json: bool = False) -> str:
    """The summary as JSON, or as text a person reads."""
    if as_json:
        return json.dumps(summary, indent=2, default=float)
    fixed = summary["controllers"]["fixed"]
    lines = [
        f"{summary['description']}, SIMC with tau_c = {summary['tau_c']:g} s",
        "local models (averaged analysis) and SIMC gains per set-point:",
        pd.DataFrame(summary["local_models"]).to_string(
            index=False, float_format=lambda x: f"{x:.4g}"
        ),
        f"fixed PI: Kp = {fixed['kp']:.4g} /bar, Ki = {fixed['ki']:.4g} /(bar*s)",
        "scheduled PI: the kp, ki columns above, interpolated in the set-point",
        "exact simulation of the set-point staircase up and down (rise 10-90 %, overshoot):",
    ]
    for name, s in summary["staircase"].items():
        lines.append(
            f"  {name:13s} rise {s['rise_time_min']:.3f}-{s['rise_time_max']:.3f} s, "
            f"overshoot {s['overshoot_min']:.1f}-{s['overshoot_max']:.1f} %"
        )
    return "\n".join(lines)
