"""The exported C header and the Python stepper against the exact closed-loop simulation.

One C harness (every kind x controller header, each under its own prefix) is compiled once
per session with the system compiler and driven through stdin: replaying the simulated
pressure it must give the simulation's valve commands exactly and its xi to 1e-12, and
closing the loop on the plant's closed forms (the same formulas as the simulation) the same
pressure, commands and xi.
"""

from __future__ import annotations

import itertools
import shutil
import subprocess
import sys

import numpy as np
import pytest

from spa.closedloop.controller import PIController
from spa.closedloop.design import design_pi
from spa.closedloop.experiments import staircase_reference
from spa.closedloop.export import (
    arduino_sketch,
    c_double,
    controller_header,
    write_controller,
)
from spa.closedloop.loop import closed_loop_arrays
from spa.closedloop.stepper import ControllerStepper
from spa.model.modulators import Modulator
from spa.model.modulators.kernels import KERNELS
from spa.model.params import ValveParams

DT = 1e-3
PARAMS = ValveParams(c1=0.5, k2=0.8, tau2=0.7, t_on=0.004, t_off=0.012)
SETTINGS = {
    "pwm": {"type": "pwm", "f_w": 30.0},
    "ipfm": {"type": "ipfm", "t_h": 0.01, "gain": 1.1},
    "iipfm": {"type": "iipfm", "t_l": 0.02, "gain": 1.15},
    "dsm": {"type": "dsm", "period": 0.0125},
    "lpwm": {"type": "lpwm", "f_w": 20.0, "c1": 0.5, "k2": 0.8, "tau2": 0.7},
}
LEVELS = [0.1, 0.35, 0.6]
CONTROLLERS = ("fixed", "scheduled", "scheduled_ff")
# "open": no feedback, xi = the set-point itself (a feed-forward through the nodes 0.1 ... 0.9),
# so that xi lands exactly on values whose sums and products hit the modulators' event
# tolerance (0.1 + 0.1 + ... , 0.3*period).
OPEN = (0.1, 0.3, 0.5, 0.7, 0.9)
CASES = list(itertools.product(SETTINGS, (*CONTROLLERS, "open")))
P0, I0 = 0.05, 0.1


def _controller(kind: str, name: str) -> PIController:
    if name == "open":
        return PIController(kp=0.0, ki=0.0, feedforward=(OPEN, OPEN))
    return design_pi(SETTINGS[kind], PARAMS, levels=LEVELS, tau_c=0.15)[name]


def _reference(name: str = "fixed") -> np.ndarray:
    return staircase_reference(OPEN if name == "open" else LEVELS, 0.6, DT)


_HARNESS = r"""
#include <stdio.h>
#include <math.h>
%(includes)s

static double seg(int on, double ps, double el, double c1, double k2, double tau2)
{
    double e = el > 0.0 ? el : 0.0, root;
    if (on) {
        return exp(-e / tau2) * (ps - k2) + k2;
    }
    root = sqrt(ps) - e / (2.0 * c1);
    root = root > 0.0 ? root : 0.0;
    return root * root;
}

static double run_end(int on, double ps, double active, double c1, double k2, double tau2)
{
    double root;
    if (on) {
        return k2 + (ps - k2) * exp(-active / tau2);
    }
    root = sqrt(ps) - active / (2.0 * c1);
    return root > 0.0 ? root * root : 0.0;
}

#define RUN(P, UP)                                                                          \
    static void run_##P(long n, int closed, double i0, double p0, const double *pl)         \
    {                                                                                       \
        P##_state s;                                                                        \
        P##_output o;                                                                       \
        long k, start = 0;                                                                  \
        int level = 0;                                                                      \
        double r, p = 0.0, ps = p0, hold = 0.0, active;                                     \
        P##_init(&s, i0);                                                                   \
        for (k = 0; k < n; ++k) {                                                           \
            if (scanf("%%lf", &r) != 1) return;                                             \
            if (!closed) {                                                                  \
                if (scanf("%%lf", &p) != 1) return;                                         \
            } else if (k == 0) {                                                            \
                p = p0;                                                                     \
            } else {                                                                        \
                p = seg(level == 1, ps, (double)k * UP##_DT - ((double)start * UP##_DT + hold), \
                        pl[0], pl[1], pl[2]);                                               \
            }                                                                               \
            o = P##_step(&s, r, p);                                                         \
            if (closed) {                                                                   \
                if (k == 0) {                                                               \
                    level = o.valve;                                                        \
                } else if (o.valve != level) {                                              \
                    active = (double)(k - start) * UP##_DT - hold;                          \
                    ps = run_end(level == 1, ps, active > 0.0 ? active : 0.0, pl[0], pl[1], \
                                 pl[2]);                                                    \
                    level = o.valve;                                                        \
                    start = k;                                                              \
                    hold = o.valve == 1 ? pl[3] : pl[4];                                    \
                }                                                                           \
            }                                                                               \
            printf("%%d %%.17g %%.17g\n", o.valve, o.xi, p);                                \
        }                                                                                   \
    }
%(runs)s

int main(void)
{
    int id, closed;
    long n;
    double i0, p0, pl[5];
    while (scanf("%%d %%d %%ld %%lf %%lf %%lf %%lf %%lf %%lf %%lf", &id, &closed, &n, &i0, &p0,
                 &pl[0], &pl[1], &pl[2], &pl[3], &pl[4]) == 10) {
        switch (id) {
%(cases)s
        default:
            return 2;
        }
        printf("end\n");
        fflush(stdout);
    }
    return 0;
}
"""


@pytest.fixture(scope="session")
def harness(tmp_path_factory):
    """The compiled harness: every case's header under the prefix ``c<i>``."""
    cc = shutil.which("cc")
    if cc is None:
        pytest.skip("no C compiler: `cc` is not on PATH (make test installs one)")
    folder = tmp_path_factory.mktemp("c_harness")
    includes, runs, cases = [], [], []
    for i, (kind, name) in enumerate(CASES):
        write_controller(
            folder, SETTINGS[kind], _controller(kind, name), DT, name=f"h{i}", prefix=f"c{i}"
        )
        includes.append(f'#include "h{i}.h"')
        runs.append(f"RUN(c{i}, C{i})")
        cases.append(f"        case {i}: run_c{i}(n, closed, i0, p0, pl); break;")
    src = folder / "harness.c"
    src.write_text(
        _HARNESS
        % {"includes": "\n".join(includes), "runs": "\n".join(runs), "cases": "\n".join(cases)}
    )
    exe = folder / "harness"
    cmd = [cc, "-std=c99", "-O2", "-Wall", "-Wextra", "-pedantic", "-Werror",
           "-Wno-unused-function", str(src), "-o", str(exe), "-lm"]  # fmt: skip
    subprocess.run(cmd, check=True, capture_output=True, text=True)
    return exe


def _i0(name: str) -> float:
    return 0.0 if name == "open" else I0


def _drive(exe, case: int, closed: bool, r, p=None) -> np.ndarray:
    pl = PARAMS
    head = f"{case} {int(closed)} {len(r)} {_i0(CASES[case][1])!r} {P0!r} "
    head += f"{pl.c1!r} {pl.k2!r} {pl.tau2!r} {pl.t_on!r} {pl.t_off!r}\n"
    cols = [r] if closed else [r, p]
    body = "\n".join(" ".join(repr(float(v)) for v in row) for row in zip(*cols, strict=True))
    out = subprocess.run(
        [str(exe)], input=head + body + "\n", capture_output=True, text=True, check=True
    ).stdout.split("\n")
    assert out[len(r)] == "end"
    return np.loadtxt(out[: len(r)], ndmin=2)


@pytest.mark.parametrize("case", range(len(CASES)), ids=[f"{k}-{c}" for k, c in CASES])
def test_c_header_equals_the_simulation(harness, case):
    kind, name = CASES[case]
    r = _reference(name)
    p, xi, u = closed_loop_arrays(
        r, DT, SETTINGS[kind], _controller(kind, name), PARAMS, P0, integral0=_i0(name)
    )
    assert 0 < u.mean() < 1  # switching
    assert np.any(xi == 1.0) if name != "open" else set(xi) == set(OPEN)  # saturating once
    replay = _drive(harness, case, False, r, p)
    np.testing.assert_array_equal(replay[:, 0], u)
    np.testing.assert_allclose(replay[:, 1], xi, rtol=0, atol=1e-12)
    closed = _drive(harness, case, True, r)
    np.testing.assert_array_equal(closed[:, 0], u)
    np.testing.assert_allclose(closed[:, 1], xi, rtol=0, atol=1e-12)
    np.testing.assert_allclose(closed[:, 2], p, rtol=0, atol=1e-12)


@pytest.mark.parametrize(("kind", "name"), CASES)
def test_python_stepper_equals_the_simulation(kind, name):
    ctrl = _controller(kind, name)
    r = _reference(name)
    p, xi, u = closed_loop_arrays(r, DT, SETTINGS[kind], ctrl, PARAMS, P0, integral0=_i0(name))
    stepper = ControllerStepper(SETTINGS[kind], ctrl, DT, integral0=_i0(name))
    out = np.array([stepper.step(rk, pk) for rk, pk in zip(r, p, strict=True)])
    np.testing.assert_array_equal(out[:, 0], u)
    np.testing.assert_allclose(out[:, 1], xi, rtol=0, atol=1e-12)
    stepper.reset(_i0(name))  # a reset starts the same sequence again
    assert stepper.step(r[0], p[0]) == (int(u[0]), float(out[0, 1]))


def test_every_kernel_has_its_c_law():
    for kind, module in KERNELS.items():
        text = module.C_STEP
        assert "${p}_mod_step(long long k, double xi" in text, kind


def test_header_is_self_contained_and_names_its_prefix():
    ctrl = _controller("iipfm", "scheduled_ff")
    h = controller_header(SETTINGS["iipfm"], ctrl, DT, prefix="valve_a", note="bench 3")
    includes = [line for line in h.splitlines() if line.startswith("#include")]
    assert includes == ["#include <math.h>"]
    assert "#define VALVE_A_DT 0.001" in h and "bench 3" in h
    assert "spa_ctrl" not in h and "${" not in h
    # the schedule's grid and the feed-forward table read back exactly
    grid = ctrl.arrays()[0]
    line = next(x for x in h.splitlines() if x.startswith("static const double valve_a_grid"))
    values = [float(v) for v in line.split("{")[1].rstrip("};").split(",")]
    assert values == grid.tolist()


@pytest.mark.parametrize("x", [0.1, 1e-9, 2.0, 1 / 3, 123456789.123, 5e-324, -0.7])
def test_c_double_reads_back_exactly(x):
    text = c_double(x)
    assert float(text) == x and ("." in text or "e" in text)


def test_bad_arguments_are_named():
    ctrl = PIController(1.0, 2.0)
    with pytest.raises(ValueError, match="prefix"):
        controller_header(SETTINGS["pwm"], ctrl, DT, prefix="1bad")
    with pytest.raises(ValueError, match="controller"):
        controller_header(SETTINGS["pwm"], {"kp": 1.0}, DT)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="c_double"):
        c_double(float("nan"))
    with pytest.raises(ValueError, match="controller"):
        ControllerStepper(SETTINGS["pwm"], None, DT)  # type: ignore[arg-type]


def test_sketch_includes_the_header_and_steps_at_its_rate(tmp_path):
    h, ino = write_controller(tmp_path, SETTINGS["dsm"], PIController(1.0, 2.0), DT, name="x")
    text = ino.read_text()
    assert '#include "x.h"' in text and "SPA_CTRL_DT" in text
    assert h.read_text().startswith("/* SPA_CTRL:")
    assert "read_pressure_bar()" in arduino_sketch() and "digitalWrite" in arduino_sketch()


def test_cli_writes_the_header(tmp_path):
    params = tmp_path / "params.yaml"
    params.write_text("c1: 0.5\nk2: 0.8\ntau2: 0.7\nt_on: 0.004\nt_off: 0.012\n")
    out = tmp_path / "out"
    cmd = [sys.executable, "-m", "spa", "export-controller", str(params), "--modulator",
           "iipfm:t_l=0.02,gain=1.15", "--controller", "scheduled_ff", "--levels",
           "0.1,0.35,0.6", "--tau-c", "0.15", "--out", str(out)]  # fmt: skip
    res = subprocess.run(cmd, capture_output=True, text=True, check=False)
    assert res.returncode == 0, res.stdout + res.stderr
    expected = controller_header(
        Modulator.from_mapping(SETTINGS["iipfm"]), _controller("iipfm", "scheduled_ff"), DT
    )
    body = (out / "controller.h").read_text()
    assert body[body.index("#ifndef") :] == expected[expected.index("#ifndef") :]
    assert (out / "controller.ino").is_file()
    bad = subprocess.run([*cmd[:-2], "--controller", "pid"], capture_output=True, text=True)
    assert bad.returncode != 0


LAB = "c1: 0.533\nk2: 0.837\ntau2: 0.826\nt_on: 0.0155\nt_off: 0.0092\n"


def _export(args, cwd=None):
    cmd = [sys.executable, "-m", "spa", "export-controller", *args]
    return subprocess.run(cmd, capture_output=True, text=True, check=False, cwd=cwd)


def test_cli_lpwm_inverts_the_identified_valve(tmp_path):
    params = tmp_path / "params.yaml"
    params.write_text(LAB)
    out = tmp_path / "out"
    res = _export([str(params), "--modulator", "lpwm:f_w=14.2", "--controller", "fixed",
                   "--levels", "0.2,0.4,0.6", "--tau-c", "0.2", "--out", str(out)])  # fmt: skip
    assert res.returncode == 0, res.stdout + res.stderr
    body = (out / "controller.h").read_text()
    valve = ValveParams(c1=0.533, k2=0.837, tau2=0.826, t_on=0.0155, t_off=0.0092)
    mod = Modulator.from_mapping({"type": "lpwm", "f_w": 14.2}).bind(valve)
    ctrl = design_pi(mod, valve, levels=[0.2, 0.4, 0.6], tau_c=0.2)["fixed"]
    expected = controller_header(mod, ctrl, DT)
    assert body[body.index("#ifndef") :] == expected[expected.index("#ifndef") :]
    # the constants it inverts are the identified ones, and the comment lists them
    assert "t_on = 0.0155, t_off = 0.0092" in body
    nominal = KERNELS["lpwm"].configure({"f_w": 14.2}, DT)
    bound = KERNELS["lpwm"].configure(dict(mod.settings), DT)
    assert not np.array_equal(nominal, bound)


def test_cli_defaults_to_the_stage_choice_in_a_results_folder(tmp_path):
    ds = tmp_path / "results" / "lab"
    (ds / "identification").mkdir(parents=True)
    (ds / "closed_loop").mkdir()
    params = ds / "identification" / "params.yaml"
    params.write_text(LAB)
    (ds / "closed_loop" / "controllers.yaml").write_text(
        "tau_c: 0.3\nsetting: {type: pwm, f_w: 20.0}\ncontroller: fixed\n"
        "controllers:\n  pwm-20Hz: {levels: [0.2, 0.4, 0.6]}\n"
    )
    out = tmp_path / "out"
    res = _export([str(params), "--out", str(out)])
    assert res.returncode == 0, res.stdout + res.stderr
    body = (out / "controller.h").read_text()
    assert body.startswith("/* SPA_CTRL: fixed PI -> PWM")
    assert "tau_c = 0.3 s" in body
    # a user's choice still wins; outside a results folder the default is scheduled_ff
    res = _export([str(params), "--controller", "scheduled", "--out", str(out)])
    assert (out / "controller.h").read_text().startswith("/* SPA_CTRL: gain-scheduled PI ->")
    alone = tmp_path / "params.yaml"
    alone.write_text(LAB)
    res = _export([str(alone), "--modulator", "pwm:f_w=20", "--out", str(out)])
    assert res.returncode == 0, res.stdout + res.stderr
    assert "gain-scheduled PI with feed-forward" in (out / "controller.h").read_text()


def test_sketch_setpoint_lies_in_the_held_range(tmp_path):
    params = tmp_path / "params.yaml"
    params.write_text("c1: 0.4\nk2: 4.0\ntau2: 1.0\nt_on: 0.004\nt_off: 0.01\n")
    res = _export([str(params), "--modulator", "pwm:f_w=20", "--out", str(tmp_path)])
    assert res.returncode == 0, res.stdout + res.stderr
    sketch = (tmp_path / "controller.ino").read_text()
    value = float(sketch.split("double setpoint_bar() {\n  return ")[1].split(";")[0])
    assert 0.4 < value < 3.6  # inside the range PWM holds on a 4 bar valve, not 0.4
