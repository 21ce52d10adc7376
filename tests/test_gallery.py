"""The gallery (docs/gallery/): at least five runnable examples covering what the site
promises (each modulator simulated, identification from a bench's files, a tuning sweep, a
closed-loop design with its C export, the bicoherence of a chirp); each runs in a fresh
interpreter and draws its picture, as the site's build runs it."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
GALLERY = ROOT / "docs" / "gallery"
sys.path.append(str(ROOT / "docs"))

from _gallery import example_page, examples, index_page, run_example, title_and_text  # noqa: E402

#: What each required example must call.
REQUIRED = {
    "every modulator simulated": ("kinds()", "spa.simulate"),
    "identification from a bench's files": ("spa.identify_runs", "spa.ingest_dataset"),
    "a tuning sweep": ("spa.tune",),
    "a closed-loop design and its C export": ("spa.design_pi", "spa.export_designed"),
    "the bicoherence of a chirp": ("chirp_input", "spa.chirp_analysis"),
}


def test_the_gallery_has_five_examples_covering_its_topics():
    scripts = examples(GALLERY)
    assert len(scripts) >= 5
    sources = [s.read_text(encoding="utf-8") for s in scripts]
    for topic, calls in REQUIRED.items():
        assert any(all(c in src for c in calls) for src in sources), topic
    for script in scripts:
        title, text = title_and_text(script)
        assert title and text, f"{script.name}: a title and what it shows, in its docstring"


@pytest.mark.parametrize("script", examples(GALLERY), ids=lambda p: p.stem)
def test_each_example_runs_and_draws_its_picture(script, tmp_path):
    image = tmp_path / f"{script.stem}.png"
    output = run_example(script, image, ROOT)
    assert image.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert image.stat().st_size > 10_000  # a drawn figure, not an empty canvas
    page = example_page(script, output)
    assert page.startswith(f"# {title_and_text(script)[0]}\n")
    assert f"_images/{script.stem}.png" in page and f"literalinclude}} {script.name}" in page


def test_the_index_links_every_example_with_its_thumbnail():
    scripts = examples(GALLERY)
    index = index_page(scripts)
    for script in scripts:
        assert "[![" in index and f"](_images/{script.stem}.png)]({script.stem}.md)" in index
