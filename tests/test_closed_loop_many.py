"""The box's staircases in one compiled call equal the plant-by-plant loops, compiled and
plain Python."""

from __future__ import annotations

import numpy as np
import pytest

from spa.closedloop.design import design_pi
from spa.closedloop.experiments import staircase_reference
from spa.closedloop.loop import closed_loop_arrays, closed_loop_many
from spa.identification.identified import corners
from spa.model.modulators import Modulator
from spa.model.params import ValveParams

BOX = {"k2": (0.8, 0.9), "t_on": (0.002, 0.006), "c1": (0.5, 0.56)}


@pytest.mark.parametrize(
    "setting",
    [{"type": "pwm", "f_w": 20.0}, {"type": "iipfm", "t_l": 0.02, "gain": 1.15},
     {"type": "lpwm", "f_w": 20.0}],
)  # fmt: skip
def test_many_equals_one_by_one(setting):
    est = ValveParams()
    mod = Modulator.from_mapping(setting).bind(est)
    ctrl = design_pi(mod, est, levels=[0.2, 0.5])["scheduled_ff"]
    valves = [est, *corners(est, BOX)]
    r = staircase_reference([0.2, 0.5], 0.4, 1e-3)
    p0 = np.linspace(0.1, 0.3, len(valves))
    i0 = np.linspace(0.0, 0.2, len(valves))
    many = closed_loop_many(r, 1e-3, mod, ctrl, valves, p0, i0)
    plain = closed_loop_many(r, 1e-3, mod, ctrl, valves, p0, i0, compiled=False)
    for j, valve in enumerate(valves):
        one = closed_loop_arrays(r, 1e-3, mod, ctrl, valve, p0[j], integral0=i0[j])
        for a, b, c in zip(many, plain, one, strict=True):
            np.testing.assert_array_equal(a[j], c)
            np.testing.assert_array_equal(b[j], c)
