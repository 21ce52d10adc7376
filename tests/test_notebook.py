"""examples/quickstart.ipynb runs top to bottom (nbclient), so a change that breaks it fails
CI; it is committed without outputs."""

from __future__ import annotations

from pathlib import Path

import nbformat
from nbclient import NotebookClient

ROOT = Path(__file__).resolve().parents[1]
NOTEBOOK = ROOT / "examples" / "quickstart.ipynb"


def test_notebook_is_committed_without_outputs():
    nb = nbformat.read(NOTEBOOK, as_version=4)
    nbformat.validate(nb)
    code = [c for c in nb.cells if c.cell_type == "code"]
    assert code and all(c.outputs == [] and c.execution_count is None for c in code)


def test_quickstart_notebook_runs(tmp_path, monkeypatch):
    monkeypatch.setenv("MPLBACKEND", "module://matplotlib_inline.backend_inline")  # figures inline
    raw = sorted((ROOT / "raw" / "example").rglob("*"))
    before = {p: p.stat().st_mtime_ns for p in raw}
    nb = nbformat.read(NOTEBOOK, as_version=4)
    client = NotebookClient(
        nb,
        timeout=120,
        kernel_name="python3",
        resources={"metadata": {"path": str(ROOT / "examples")}},
    )
    client.execute()  # raises CellExecutionError, with the cell and its traceback, on failure
    text = "\n".join(
        o.get("text", "") + str(o.get("data", {}).get("text/plain", ""))
        for c in nb.cells
        if c.cell_type == "code"
        for o in c.outputs
    )
    assert "averaged-model equilibrium:" in text
    assert "c1" in text and "95 % lo" in text  # the identified parameters' table
    assert "Use " in text  # the tuning's recommendation sentence
    images = [o for c in nb.cells for o in c.get("outputs", []) if "image/png" in o.get("data", {})]
    assert len(images) == 1  # the figure
    assert sorted((ROOT / "raw" / "example").rglob("*")) == raw  # raw/ read-only
    assert {p: p.stat().st_mtime_ns for p in raw} == before
