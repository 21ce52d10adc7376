"""The figures README.md and benchmarks/README.md quote are their CSVs' (benchmarks/figures.py)."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
_spec = importlib.util.spec_from_file_location("figures", ROOT / "benchmarks" / "figures.py")
figures = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(figures)


@pytest.mark.parametrize("doc", figures.DOCUMENTS, ids=lambda p: p.name + ":" + p.parent.name)
def test_every_marked_figure_is_its_csvs(doc):
    text = doc.read_text(encoding="utf-8")
    assert len(figures.MARKER.findall(text)) >= 5, f"{doc}: fewer marked figures than expected"
    assert figures.problems(text, doc.name) == []


def test_a_number_edited_by_hand_fails_the_check():
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    m = figures.MARKER.search(text)
    edited = text[: m.start("value")] + m["value"] + "1" + text[m.end("value") :]
    found = figures.problems(edited, "README.md")
    assert len(found) == 1 and m["name"] in found[0] and "its CSV gives" in found[0]
    # and --write puts the CSV's figure back
    assert figures.render(edited) == text


def test_a_marker_naming_no_figure_is_named():
    found = figures.problems("x <!-- fig no.such.figure -->3<!-- /fig -->\n", "doc.md")
    assert found == ["doc.md:1: no.such.figure is no figure of benchmarks/figures.py"]


def test_every_figure_renders_from_the_repositorys_csvs():
    for name, make in figures.FIGURES.items():
        value = make()
        assert value and "nan" not in value, name
