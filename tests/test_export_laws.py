"""The exported C header for a valve with its own laws: LPWM's inverse of the laws in a table
within the flash budget the header states, compiled strictly, equal to the Python loop."""

from __future__ import annotations

import re
import shutil
import subprocess
from dataclasses import replace

import numpy as np
import pytest

from spa.closedloop.design import design_pi
from spa.closedloop.experiments import staircase_reference
from spa.closedloop.export import FLASH_BUDGET, controller_header, write_controller
from spa.closedloop.loop import closed_loop_arrays
from spa.closedloop.stepper import ControllerStepper
from spa.model.laws import Laws
from spa.model.modulators import Modulator
from spa.model.modulators.lpwm import law_weights

DT = 1e-3
LAWS = Laws(log_g=(0.0, 0.3, 0.5, 0.2), log_h=(0.0, -0.2, -0.4, -0.5), m=0.8)
VALVE = replace(
    __import__("spa").ValveParams(c1=0.5, k2=0.8, tau2=0.7, t_on=0.004, t_off=0.012), laws=LAWS
)
LEVELS = [0.15, 0.4, 0.6]
SETTINGS = {
    "lpwm": Modulator.from_mapping({"type": "lpwm", "f_w": 14.2}).bind(VALVE),
    "pwm": Modulator.from_mapping({"type": "pwm", "f_w": 20.0}),
}

_HARNESS = r"""
#include <stdio.h>
#include "ctrl.h"

int main(void)
{
    spa_ctrl_state s;
    spa_ctrl_output o;
    double r, p, i0;
    if (scanf("%lf", &i0) != 1) {
        return 2;
    }
    spa_ctrl_init(&s, i0);
    while (scanf("%lf %lf", &r, &p) == 2) {
        o = spa_ctrl_step(&s, r, p);
        printf("%d %.17g\n", o.valve, o.xi);
    }
    return 0;
}
"""


def _compile(folder, header: str):
    cc = shutil.which("cc")
    assert cc, "no C compiler 'cc' on the PATH (make test installs one)"
    (folder / "ctrl.h").write_text(header)
    (folder / "main.c").write_text(_HARNESS)
    exe = folder / "main"
    cmd = [cc, "-std=c99", "-O2", "-Wall", "-Wextra", "-pedantic", "-Werror",
           str(folder / "main.c"), "-o", str(exe), "-lm"]  # fmt: skip
    subprocess.run(cmd, check=True, capture_output=True, text=True)
    return exe


def _replay(exe, r, p, i0: float) -> np.ndarray:
    rows = (f"{float(a)!r} {float(b)!r}" for a, b in zip(r, p, strict=True))
    body = f"{i0!r}\n" + "\n".join(rows) + "\n"
    out = subprocess.run([str(exe)], input=body, capture_output=True, text=True, check=True)
    return np.loadtxt(out.stdout.splitlines(), ndmin=2)


@pytest.mark.parametrize("kind", sorted(SETTINGS))
@pytest.mark.parametrize("name", ["fixed", "scheduled_ff"])
def test_header_on_a_laws_valve_equals_the_python_loop(kind, name, tmp_path) -> None:
    mod = SETTINGS[kind]
    ctrl = design_pi(mod, VALVE, levels=LEVELS, tau_c=0.2)[name]
    header = controller_header(mod, ctrl, DT, params=VALVE)
    exe = _compile(tmp_path, header)
    r = staircase_reference(LEVELS, 1.5, DT)
    p, xi, u = closed_loop_arrays(r, DT, mod, ctrl, VALVE, 0.05, integral0=0.1)
    assert 0 < u.mean() < 1
    out = _replay(exe, r, p, 0.1)
    np.testing.assert_array_equal(out[:, 0], u)
    np.testing.assert_array_equal(out[:, 1], xi)
    stepper = ControllerStepper(mod, ctrl, DT, integral0=0.1, params=VALVE)
    steps = np.array([stepper.step(a, b) for a, b in zip(r, p, strict=True)])
    np.testing.assert_array_equal(steps[:, 0], u)


def test_header_carries_the_laws_table_within_the_flash_budget() -> None:
    mod = SETTINGS["lpwm"]
    ctrl = design_pi(mod, VALVE, levels=LEVELS, tau_c=0.2)["scheduled_ff"]
    header = controller_header(mod, ctrl, DT, params=VALVE)
    table = law_weights(mod.settings, VALVE)
    assert table is not None
    said = re.search(r"Flash: (\d+) bytes of constant tables \(budget (\d+) bytes\), of which "
                     r"(\d+) the table", header)  # fmt: skip
    assert said, header[:800]
    total, budget, laws = (int(v) for v in said.groups())
    assert budget == FLASH_BUDGET and total <= budget
    assert laws == 8 * (table.size + 0)  # the table; its length rides in the count slot
    # The constants array holds the table, each value written back to the same double.
    cfg = re.search(r"spa_ctrl_cfg\[(\d+)\]", header)
    assert cfg and int(cfg.group(1)) == 9 + table.size
    # The paper's laws: no table, and the same header as without the valve.
    paper = replace(VALVE, laws=None)
    assert "of which" not in controller_header(mod, ctrl, DT, params=paper)
    assert controller_header(mod, ctrl, DT, params=paper) == controller_header(mod, ctrl, DT)


def test_a_header_beyond_the_budget_is_refused() -> None:
    from spa.closedloop.controller import PIController

    n = FLASH_BUDGET // 8
    grid = tuple(np.linspace(0.05, 0.7, n))
    ctrl = PIController(kp=(1.0,) * n, ki=(2.0,) * n, schedule=grid)
    with pytest.raises(ValueError, match="flash budget"):
        controller_header(SETTINGS["pwm"], ctrl, DT, params=VALVE)


def test_write_controller_passes_the_valve(tmp_path) -> None:
    mod = SETTINGS["lpwm"]
    ctrl = design_pi(mod, VALVE, levels=LEVELS, tau_c=0.2)["fixed"]
    header, _ = write_controller(tmp_path, mod, ctrl, DT, params=VALVE)
    assert header.read_text() == controller_header(mod, ctrl, DT, params=VALVE)
