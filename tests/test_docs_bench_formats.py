"""The examples of docs/howto/bench-formats.md run: each section's ``dataset.yaml`` and the
files shown under it (a line naming the file, `` `charge.csv`: ``, then its text) are written
to a folder, which must validate and ingest with no error."""

from __future__ import annotations

import re
from pathlib import Path

import pytest
import yaml

from spa.datasets import check_dataset, ingest_dataset

PAGE = Path(__file__).resolve().parents[1] / "docs" / "howto" / "bench-formats.md"

#: A fenced block and the paragraph line before it.
_BLOCK = re.compile(r"(?:^|\n)([^\n]*)\n\n```(\w+)\n(.*?)\n```", re.S)
#: The line naming a file shown in the next block: ends with `name.ext`:
_FILE = re.compile(r"`([\w.-]+\.\w+)`:\s*$")

_HEAD = {"description": "An example of the bench-formats page.", "origin": "bench", "rig": {}}


def _examples() -> dict[str, tuple[str, dict[str, str]]]:
    """Section title -> (its dataset.yaml, {file name: text}), for sections holding one."""
    out = {}
    for section in re.split(r"\n## ", PAGE.read_text(encoding="utf-8"))[1:]:
        title = section.splitlines()[0]
        spec, files = None, {}
        for before, lang, body in _BLOCK.findall(section):
            named = _FILE.search(before)
            if lang == "yaml" and "runs:" in body:
                spec = body
            elif lang == "text" and named:
                files[named.group(1)] = body + "\n"
        if spec is not None:
            out[title] = (spec, files)
    return out


EXAMPLES = _examples()


def test_the_page_has_its_examples() -> None:
    assert len(EXAMPLES) >= 3
    for title, (spec, files) in EXAMPLES.items():
        runs = yaml.safe_load(spec)["runs"]
        assert {r["file"] for r in runs} == set(files), title  # every file shown


@pytest.mark.parametrize("title", list(EXAMPLES))
def test_each_example_validates_and_ingests(title: str, tmp_path: Path) -> None:
    spec, files = EXAMPLES[title]
    folder = tmp_path / "raw" / "example"
    folder.mkdir(parents=True)
    doc = {"name": "example", **_HEAD, **yaml.safe_load(spec)}
    (folder / "dataset.yaml").write_text(yaml.safe_dump(doc, sort_keys=False))
    for name, text in files.items():
        (folder / name).write_text(text)
    problems, summaries = check_dataset(folder)
    assert [str(p) for p in problems if p.is_error] == []
    assert len(summaries) == len(doc["runs"])
    assert len(ingest_dataset(folder, tmp_path / "results" / "runs")) == len(doc["runs"])
