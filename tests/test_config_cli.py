"""Configuration given on the Snakemake command line (``--config``) reads as the user means it."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import yaml

from spa.pipeline.config import coerce_numbers, config_errors

ROOT = Path(__file__).resolve().parents[1]
SCHEMA = yaml.safe_load((ROOT / "workflow/schemas/config.schema.yaml").read_text())


def _config() -> dict:
    return yaml.safe_load((ROOT / "config/config.yaml").read_text())


def test_the_readme_tuning_example_runs_as_a_dry_run(tmp_path):
    """Issue case 5: the README's ``--config seed=7 "tuning={score: J_exact, max_chattering:
    0.03}"`` stopped with ``tuning.max_chattering: '0.03' is not of type 'number', 'null'``
    (Snakemake reads a nested ``--config`` mapping with YAML's base loader: all strings)."""
    res = subprocess.run(
        [sys.executable, "-m", "snakemake", "reproduce-all", "-n", "--config", "seed=7",
         "tuning={score: J_exact, max_chattering: 0.03}", f"results={tmp_path / 'res'}"],
        cwd=ROOT, capture_output=True, text=True, timeout=600,
    )  # fmt: skip
    text = res.stdout + res.stderr
    assert res.returncode == 0, text[-3000:]
    assert "is not of type" not in text


def test_nested_strings_read_as_the_yaml_values_the_schema_wants():
    """What Snakemake's base loader hands over for nested values: numbers, null, lists of
    numbers and mappings as strings; each is read as YAML where the schema takes no string."""
    cfg = _config()
    cfg["tuning"].update(
        {"max_chattering": "0.03", "min_pulse_width": "null", "ranges": {"pwm": ["5", "50.0"]},
         "gain_sweep": {"start": "1.0", "stop": "1.3", "step": "1e-2"}, "score": "J_exact"}
    )  # fmt: skip
    coerce_numbers(cfg, SCHEMA)
    assert cfg["tuning"]["max_chattering"] == 0.03
    assert cfg["tuning"]["min_pulse_width"] is None
    assert cfg["tuning"]["ranges"]["pwm"] == [5, 50.0]
    assert cfg["tuning"]["gain_sweep"] == {"start": 1.0, "stop": 1.3, "step": 0.01}
    assert cfg["tuning"]["score"] == "J_exact"
    assert config_errors(cfg, SCHEMA) == []


def test_a_string_the_schema_cannot_take_is_still_reported():
    cfg = _config()
    cfg["tuning"]["max_chattering"] = "a lot"
    cfg["figures"] = "some"
    coerce_numbers(cfg, SCHEMA)
    errors = config_errors(cfg, SCHEMA)
    assert any(e.startswith("tuning.max_chattering: 'a lot' is not of type") for e in errors)
    assert any(e.startswith("figures:") for e in errors)
