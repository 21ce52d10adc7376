"""A run whose modulator setting cannot work on the valve is analysed as recorded.

The test dataset is a simulated valve whose delays add up to 45 ms (t_on 7 ms, t_off 38 ms,
like a gripper with a slow exhaust), run with PWM at 25 Hz (a 40 ms period, shorter than
the valve's delays) and ΔΣ at 15 ms: every setting of its sine and chirp runs cannot work on
the valve, so Eq. 9 gives no ``tau_m`` and there is no linear reference.
"""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import pandas as pd
import pytest

from spa.model.params import ValveParams
from spa.openloop.reference import SKIPPED_PART, reference_skip_reason

ROOT = Path(__file__).resolve().parents[1]
SLOW = ValveParams(c1=0.5, k2=1.2, tau2=0.6, t_on=0.007, t_off=0.038)
OVERLAY = """\
simulated:
  sim: null
  slow-exhaust:
    description: Valve whose delays (t_on + t_off = 45 ms) exceed a 25 Hz PWM period
    params: {{c1: 0.5, k2: 1.2, tau2: 0.6, t_on: 0.007, t_off: 0.038}}
    controller_dt: 0.001
    sensor: {{fs: 1000.0, noise: 0.005, quantum: 0.001}}
    modulators:
      - {{type: pwm, f_w: 25.0}}
      - {{type: dsm, period: 0.015}}
datasets: {{raw_dir: {raw}, include: [], exclude: []}}
"""


@pytest.fixture(scope="module")
def slow_run(tmp_path_factory):
    """The small config's pipeline on the slow-exhaust dataset alone."""
    base = tmp_path_factory.mktemp("slow_exhaust")
    (base / "raw").mkdir()
    overlay = base / "slow.yaml"
    overlay.write_text(OVERLAY.format(raw=base / "raw"))
    out = base / "results"
    res = subprocess.run(
        [sys.executable, "-m", "snakemake", "reproduce-all", "--configfile", "config/small.yaml",
         str(overlay), "--config", f"results={out}", "--cores", "2"],
        cwd=ROOT, capture_output=True, text=True, timeout=1200,
    )  # fmt: skip
    return res, out


def test_the_reason_names_each_setting_and_its_rule():
    why = reference_skip_reason(
        [{"type": "pwm", "f_w": 25.0}, {"type": "dsm", "period": 0.015}], SLOW
    )
    assert why.startswith("no setting of these runs gives a finite tau_m (Eq. 9) at xi = 0.5")
    assert "pwm-25Hz: unusable on this valve" in why and "dsm-15ms: unusable" in why
    assert reference_skip_reason([{"type": "pwm", "f_w": 5.0}], SLOW) == ""


def test_no_stage_fails_for_a_setting_that_cannot_work(slow_run):
    """Issue case 3: the sine (PWM 25 Hz) and chirp (ΔΣ 15 ms) runs ended the job with
    ``ValueError: no setting has a finite tau_m (Eq. 9) at xi = 0.5``; reproduce-all exited
    1 and the stage wrote no status of its own."""
    res, out = slow_run
    assert res.returncode == 0, (res.stdout + res.stderr)[-4000:]
    for stage in ("sine", "chirp"):
        status = json.loads((out / "slow-exhaust" / "status" / f"{stage}.json").read_text())
        assert status["ok"] is True, status
        assert set(status["skipped"]) == {SKIPPED_PART}
        assert "pwm-25Hz: unusable on this valve" in status["skipped"][SKIPPED_PART]


def test_the_runs_are_analysed_as_recorded_and_the_table_names_the_skip(slow_run):
    _, out = slow_run
    sine = pd.read_csv(out / "slow-exhaust" / "sine" / "linearity.csv")
    runs, ref = sine[sine["run"] != "linear"], sine[sine["run"] == "linear"]
    assert set(runs["setting"]) == {"pwm-25Hz", "dsm-15ms"}
    assert runs["rms"].map(math.isfinite).all() and runs["max_dev"].map(math.isfinite).all()
    assert len(ref) == 1 and str(ref["skipped"].iloc[0]).startswith(f"{SKIPPED_PART}: no setting")
    chirp = pd.read_csv(out / "slow-exhaust" / "chirp" / "bicoherence.csv")
    runs = chirp[chirp["run"] != "linear"]
    assert len(runs) == 2 and runs["significant_fraction"].map(math.isfinite).all()
    assert chirp[chirp["run"] == "linear"]["skipped"].notna().all()


def test_the_page_names_the_skipped_part_with_its_reason(slow_run):
    _, out = slow_run
    page = (out / "report" / "slow-exhaust.html").read_text()
    for stage in ("sine", "chirp"):
        assert f'<p class="note stage-partial">Stage <code>{stage}</code>' in page, (
            f"no note for {stage}"
        )
    assert "linear reference skipped: no setting of these runs gives a finite tau_m" in page
    assert "not known to be at fault" not in page
