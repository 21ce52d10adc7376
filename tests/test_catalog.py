"""The Snakemake workflow catalog's conventions: config/README.md naming
every key of the schema, .snakemake-workflow-catalog.yml, and `snakemake --report` with a
caption and a category for every table and figure (spa.pipeline.workflow_report)."""

from __future__ import annotations

import re
import subprocess
import sys
import zipfile
from pathlib import Path

import yaml

from spa.pipeline.outputs import STAGES
from spa.pipeline.stage_types import FIGURE, FIGURES, TABLE
from spa.pipeline.workflow_report import caption_file, caption_rst, report_flags, report_outputs

ROOT = Path(__file__).resolve().parents[1]


def _schema_keys(node: dict, prefix: str, defs: dict) -> set[str]:
    """Dotted paths of every named key of a JSON schema (``$ref``s followed)."""
    if "$ref" in node:
        node = defs[node["$ref"].rsplit("/", 1)[-1]]
    keys: set[str] = set()
    for name, sub in (node.get("properties") or {}).items():
        path = f"{prefix}.{name}" if prefix else name
        keys.add(path)
        if isinstance(sub, dict):
            keys |= _schema_keys(sub, path, defs)
    for sub in node.get("oneOf", []):
        keys |= _schema_keys(sub, prefix, defs)
    extra = node.get("additionalProperties")
    if isinstance(extra, dict):  # simulated: <name>: {...}
        keys |= {f"{prefix}.<name>"} | _schema_keys(extra, f"{prefix}.<name>", defs)
    return keys


def _config_keys(node: object, prefix: str = "") -> set[str]:
    """Dotted paths of every mapping key of a configuration (lists not entered)."""
    if not isinstance(node, dict):
        return set()
    keys = set()
    for name, sub in node.items():
        path = f"{prefix}.{name}" if prefix else str(name)
        keys.add(path)
        keys |= _config_keys(sub, path)
    return keys


def test_config_readme_names_every_key_of_the_schema_and_of_both_configs():
    schema = yaml.safe_load((ROOT / "workflow" / "schemas" / "config.schema.yaml").read_text())
    keys = _schema_keys(schema, "", schema["$defs"])
    assert {"seed", "analytic.sweeps.pwm.step", "simulated.<name>.sensor.ringing.damping"} <= keys
    for name in ("config.yaml", "small.yaml"):
        found = _config_keys(yaml.safe_load((ROOT / "config" / name).read_text()))
        found = {re.sub(r"^simulated\.[^.]+", "simulated.<name>", k) for k in found}
        assert found <= keys, (name, found - keys)  # the schema knows every key of the configs
    readme = (ROOT / "config" / "README.md").read_text()
    missing = sorted(k for k in keys if f"`{k}`" not in readme)
    assert missing == [], f"config/README.md does not name {missing}"


def test_catalog_file_and_standard_layout():
    # the product's layout keeps the Snakefile at the top (where profiles/default is found)
    assert (ROOT / "Snakefile").is_file()
    assert not (ROOT / "workflow" / "Snakefile").exists()
    catalog = yaml.safe_load((ROOT / ".snakemake-workflow-catalog.yml").read_text())
    usage = catalog["usage"]
    assert usage["software-stack-deployment"]["report"] is True
    assert {"desc", "flags"} <= set(usage["mandatory-flags"])
    assert "config/README.md" in usage["mandatory-flags"]["desc"]


def test_caption_files_match_the_registry():
    """workflow/report holds one caption per reported output, as spa.pipeline.workflow_report
    writes it (`python -m spa.pipeline.workflow_report workflow/report` after a caption changed)."""
    folder = ROOT / "workflow" / "report"
    items = report_outputs()
    captions = {p.name for p in folder.glob("*.rst")} - {"workflow.rst"}  # the front page
    assert {caption_file(s, o) for s, o in items} == captions
    for stage, out in items:
        assert (folder / caption_file(stage, out)).read_text() == caption_rst(stage, out)
    # every table and figure the HTML report shows is in snakemake's report too
    shown = {(s.name, o.key) for s in STAGES for o in s.outputs if o.shown}
    kinds = {(s.name, o.key) for s in STAGES for o in s.outputs if o.kind in (TABLE, FIGURE)}
    assert shown & kinds <= {(s.name, o.key) for s, o in items}
    flags = report_flags("validate_model", folder)["figures"]
    assert flags["subcategory"] == "{dataset}" and flags["category"] == "Validation"
    assert any(o.kind == FIGURES for _, o in items)


def test_caption_escapes_restructuredtext_markup():
    from docutils.core import publish_parts

    stage = next(s for s in STAGES if s.name == "staircase")
    out = next(o for o in stage.outputs if o.key == "table3")
    html = publish_parts(caption_rst(stage, out), writer="html")["body"]
    assert "paper_*" in html and "system-message" not in html


def test_snakemake_report_of_a_finished_run_has_the_captions(small_run, isolated_config, tmp_path):
    """`snakemake --report report.zip` on the small run: every category, captions filled in
    with the dataset's name."""
    report = tmp_path / "report.zip"
    res = subprocess.run(
        [sys.executable, "-m", "snakemake", "--report", str(report), "--configfile",
         "config/small.yaml", str(isolated_config), "--config", f"results={small_run}"],
        cwd=ROOT, capture_output=True, text=True, timeout=600,
    )  # fmt: skip
    assert res.returncode == 0, res.stderr[-3000:]
    with zipfile.ZipFile(report) as zf:
        page = next(n for n in zf.namelist() if n.endswith("report.html"))
        text = zf.read(page).decode("utf-8")
    for category in {s.category for s, _ in report_outputs()}:
        assert f'"{category}"' in text, category
    assert "Table 3: static linearity of the staircase" in text
    assert "Measured against model pressure for the lowest-FIT pulse run" in text
    assert 'dataset <tt class=\\"docutils literal\\">example</tt>' in text
    assert "snakemake.wildcards" not in text
    assert "Every table and figure has a caption" in text  # workflow/report/workflow.rst
