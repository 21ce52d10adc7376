"""The exported header in a firmware build: warning-free when unused, and in single precision."""

from __future__ import annotations

import shutil
import subprocess
import sys

import numpy as np
import pytest

from spa.closedloop.design import design_pi
from spa.closedloop.experiments import staircase_reference
from spa.closedloop.export import c_float, controller_header
from spa.closedloop.loop import closed_loop_arrays
from spa.closedloop.precision import closed_loops, precision_agreement
from spa.model.params import ValveParams

DT = 1e-3
PARAMS = ValveParams(c1=0.533, k2=0.837, tau2=0.826, t_on=0.003, t_off=0.010)
SETTINGS = {
    "pwm": {"type": "pwm", "f_w": 20.0},
    "ipfm": {"type": "ipfm", "t_h": 0.02},
    "iipfm": {"type": "iipfm", "t_l": 0.02, "gain": 1.15},
    "dsm": {"type": "dsm", "period": 0.02},
    "lpwm": {"type": "lpwm", "f_w": 20.0, "c1": 0.533, "k2": 0.837, "tau2": 0.826},
}
LEVELS = [0.05, 0.25, 0.45, 0.65]
FLAGS = ["-std=c99", "-Wall", "-Wextra", "-pedantic", "-Werror"]


def _cc() -> str:
    cc = shutil.which("cc")
    if cc is None:
        pytest.skip("no C compiler: `cc` is not on PATH (make test installs one)")
    return cc


def _design(kind: str, name: str = "scheduled_ff"):
    return design_pi(SETTINGS[kind], PARAMS, levels=LEVELS, tau_c=0.2)[name]


@pytest.mark.parametrize("precision", ["double", "single"])
@pytest.mark.parametrize("kind", list(SETTINGS))
def test_a_file_that_includes_the_header_and_calls_nothing_compiles(tmp_path, kind, precision):
    """Issue case 6: with ``static`` functions a translation unit that includes the header and
    does not call both failed ``-Werror`` ("'spa_ctrl_step' defined but not used")."""
    cc = _cc()
    (tmp_path / "controller.h").write_text(
        controller_header(SETTINGS[kind], _design(kind), DT, precision=precision)
    )
    src = tmp_path / "main.c"
    src.write_text('#include "controller.h"\n\nint main(void)\n{\n    return 0;\n}\n')
    res = subprocess.run(
        [cc, *FLAGS, "-c", str(src), "-o", str(tmp_path / "main.o")],
        capture_output=True, text=True, check=False,
    )  # fmt: skip
    assert res.returncode == 0, res.stderr


def test_every_function_is_static_inline_and_single_is_float():
    double = controller_header(SETTINGS["iipfm"], _design("iipfm"), DT)
    single = controller_header(SETTINGS["iipfm"], _design("iipfm"), DT, precision="single")
    for text in (double, single):
        heads = [ln for ln in text.splitlines() if ln.startswith("static") and "(" in ln]
        assert heads and all(ln.startswith("static inline ") for ln in heads), heads
    assert "spa_ctrl_step(spa_ctrl_state *s, float r, float p)" in single
    assert "static const float spa_ctrl_kp[" in single and "float xi;" in single
    assert "spa_ctrl_step(spa_ctrl_state *s, double r, double p)" in double
    assert "float" not in double
    # the modulator keeps its clock in double in both
    assert "static const double spa_ctrl_cfg[" in single
    line = next(x for x in single.splitlines() if x.startswith("static const float spa_ctrl_kp"))
    values = [v.strip().rstrip("f") for v in line.split("{")[1].rstrip("};").split(",")]
    expected = np.float32(_design("iipfm").arrays()[1])
    np.testing.assert_array_equal(np.float32([float(v) for v in values]), expected)
    with pytest.raises(ValueError, match="precision"):
        controller_header(SETTINGS["pwm"], _design("pwm"), DT, precision="half")


@pytest.mark.parametrize("x", [0.1, 1e-9, 2.0, 1 / 3, -0.7, 3.4e38])
def test_c_float_reads_back_as_the_nearest_float(x):
    text = c_float(x)
    assert text.endswith("f") and np.float32(float(text[:-1])) == np.float32(x)
    with pytest.raises(ValueError, match="c_float"):
        c_float(1e39)


@pytest.mark.parametrize("kind", list(SETTINGS))
def test_single_precision_loop_stays_near_the_double_one(kind):
    """Closed on the model's plant over a staircase, the float PI's commands differ from the
    double one's at some steps (a pulse moved by one step), the pressure by a little: at most
    3 % of k2 and its xi by at most 0.1, over the staircase (docs/howto/controller-on-bench.md
    gives the numbers over the stage's staircase)."""
    _cc()
    r = staircase_reference(LEVELS, 2.0, DT)
    a = precision_agreement(closed_loops(SETTINGS[kind], _design(kind), PARAMS, r, DT))
    assert a.steps == r.size
    assert a.max_pressure_difference <= 0.03 * PARAMS.k2
    assert a.max_xi_difference <= 0.1
    assert a.mismatches <= 0.25 * a.steps


def test_the_harness_double_loop_is_the_simulation():
    """The comparison's reference: the harness's double-precision loop on its C plant gives
    :func:`spa.closedloop.loop.closed_loop_arrays`' commands, xi and pressure."""
    _cc()
    r = staircase_reference(LEVELS[:3], 1.0, DT)
    out = closed_loops(SETTINGS["dsm"], _design("dsm"), PARAMS, r, DT)
    p, xi, u = closed_loop_arrays(r, DT, SETTINGS["dsm"], _design("dsm"), PARAMS, 0.0)
    assert 0 < u.mean() < 1
    np.testing.assert_array_equal(out[:, 0], u)
    np.testing.assert_allclose(out[:, 4], xi, rtol=0, atol=1e-12)
    np.testing.assert_allclose(out[:, 2], p, rtol=0, atol=1e-12)


def test_cli_writes_the_single_precision_header(tmp_path):
    params = tmp_path / "params.yaml"
    params.write_text("c1: 0.533\nk2: 0.837\ntau2: 0.826\nt_on: 0.003\nt_off: 0.010\n")
    out = tmp_path / "out"
    cmd = [sys.executable, "-m", "spa", "export-controller", str(params), "--modulator",
           "pwm:f_w=20", "--levels", "0.05,0.25,0.45,0.65", "--precision", "single",
           "--out", str(out)]  # fmt: skip
    res = subprocess.run(cmd, capture_output=True, text=True, check=False)
    assert res.returncode == 0, res.stdout + res.stderr
    body = (out / "controller.h").read_text()
    expected = controller_header(SETTINGS["pwm"], _design("pwm"), DT, precision="single")
    assert body[body.index("#ifndef") :] == expected[expected.index("#ifndef") :]


def test_the_stage_option_is_a_config_key():
    """``closed_loop.precision`` chooses the stage's header: double or single, nothing else."""
    from pathlib import Path

    import yaml

    from spa.pipeline.config import config_errors

    root = Path(__file__).resolve().parents[1]
    schema = yaml.safe_load((root / "workflow/schemas/config.schema.yaml").read_text())
    cfg = yaml.safe_load((root / "config/config.yaml").read_text())
    assert cfg["closed_loop"]["precision"] == "double"
    cfg["closed_loop"]["precision"] = "single"
    assert config_errors(cfg, schema) == []
    cfg["closed_loop"]["precision"] = "half"
    assert config_errors(cfg, schema) == [
        "closed_loop.precision: 'half' is not one of ['double', 'single']"
    ]
