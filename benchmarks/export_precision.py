"""Single- against double-precision controller.h over the closed-loop stage's staircase.

For every setting of the config's ``analytic.selected`` and every designed PI (fixed,
scheduled, scheduled with feed-forward) on the ``sim`` dataset's valve, both headers are
closed on the model's plant in C (:func:`spa.closedloop.precision.closed_loops`) over the
``closed_loop`` stage's staircase (levels below max_level_fraction*k2, up then down, hold
each) and compared step by step (:func:`spa.closedloop.precision.precision_agreement`).
Prints one Markdown row per loop.

    .venv/bin/python benchmarks/export_precision.py
"""

from __future__ import annotations

from pathlib import Path

import yaml

from spa.closedloop.choice import CONTROLLERS
from spa.closedloop.design import design_pi
from spa.closedloop.experiments import staircase_reference
from spa.closedloop.precision import closed_loops, precision_agreement
from spa.model.modulators import Modulator
from spa.model.params import ValveParams

ROOT = Path(__file__).resolve().parents[1]


def main() -> None:
    cfg = yaml.safe_load((ROOT / "config/config.yaml").read_text())
    params = ValveParams(**cfg["simulated"]["sim"]["params"])
    cl = cfg["closed_loop"]
    levels = [v for v in cl["levels"] if v < cl["max_level_fraction"] * params.k2]
    dt = float(cl["dt"])
    r = staircase_reference(levels, float(cl["hold"]), dt)
    print(f"valve {params}; staircase {levels} bar, {cl['hold']} s each, {r.size} steps")
    print("| setting | controller | mismatches | share | max abs dp (bar) | max abs dxi |")
    print("|---|---|---:|---:|---:|---:|")
    for mapping in cfg["analytic"]["selected"]:
        mod = Modulator.from_mapping(mapping)
        designs = design_pi(mod, params, levels=levels, tau_c=float(cl["tau_c"]))
        for name in CONTROLLERS:
            a = precision_agreement(closed_loops(mod, designs[name], params, r, dt))
            print(
                f"| {mod.label} | {name} | {a.mismatches} | {a.mismatches / a.steps:.3%} "
                f"| {a.max_pressure_difference:.2e} | {a.max_xi_difference:.2e} |"
            )


if __name__ == "__main__":
    main()
