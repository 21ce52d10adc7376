"""The documentation is written in our own words: no long run of words taken from the notes.

docs/ and the README were written from reference notes kept beside the repository
(``../shared``: the model's clean equations, a style guide and the paper's text). A run of
``RUN`` or more identical words (case and punctuation ignored) shared with any of them is a
passage copied rather than restated.

The notes are not the repository's to copy, so the check reads a digest of them that is:
``tests/notes-runs.txt``, one 40-bit BLAKE2b digest per run of ``RUN`` words of the
notes (no word of theirs). Every page is checked against it on every machine. Where the notes
are beside the checkout (``../shared``, or the folder ``SPA_SHARED`` names), a test checks
that the digest file is theirs; ``python tests/test_docs.py --write`` rewrites it.
"""

from __future__ import annotations

import os
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
RUN = 10  # words


def shared_folder() -> Path | None:
    """The reference notes' folder, or None where this checkout has none beside it."""
    for candidate in (os.environ.get("SPA_SHARED"), ROOT.parent / "shared"):
        if candidate and (Path(candidate) / "MODEL.md").is_file():
            return Path(candidate)
    return None


def words(text: str) -> list[str]:
    """Lower-case words, punctuation and underscores ignored (``t_on`` is ``t on``)."""
    return re.findall(r"[^\W_]+", text.lower())


def without_math(text: str) -> str:
    """A page's text with its math (``$...$``, ``$$...$$``) left out: an equation restated
    is the same equation, and its symbols are not a passage of words."""
    text = re.sub(r"\$\$.*?\$\$", " ", text, flags=re.S)
    return re.sub(r"(?<![\\$])\$[^$\n]+\$", " ", text)


#: The digests of the notes' runs of words, in the repository.
DIGESTS = ROOT / "tests" / "notes-runs.txt"


def digest(run: tuple[str, ...]) -> str:
    """A run of words' 40-bit BLAKE2b digest, in hex.

    Examples
    --------
    >>> digest(("the", "valve"))
    'b7bd6cb60d'
    """
    import hashlib

    return hashlib.blake2b(" ".join(run).encode(), digest_size=5).hexdigest()


def notes_digests(folder: Path) -> list[str]:
    """The sorted digests of every run of :data:`RUN` words of the notes in ``folder``."""
    notes = [folder / "MODEL.md", folder / "STYLE.md", *sorted((folder / "paper").glob("*.txt"))]
    found: set[str] = set()
    for path in notes:
        found |= {digest(r) for r in runs(path.read_text(encoding="utf-8", errors="replace"))}
    return sorted(found)


def read_digests() -> set[str]:
    """:data:`DIGESTS` as a set (comment lines left out)."""
    lines = DIGESTS.read_text(encoding="ascii").splitlines()
    return {line for line in lines if line and not line.startswith("#")}


def runs(text: str, n: int = RUN) -> set[tuple[str, ...]]:
    """Every run of ``n`` consecutive words of ``text``."""
    w = words(text)
    return {tuple(w[i : i + n]) for i in range(len(w) - n + 1)}


def shared_runs(text: str, sources: dict[str, str], n: int = RUN) -> list[str]:
    """The runs of ``n`` words ``text`` shares with each source, as ``source: words``."""
    mine = runs(text, n)
    found = []
    for name, source in sources.items():
        found += [f"{name}: {' '.join(r)}" for r in sorted(mine & runs(source, n))]
    return found


def test_the_checker_finds_a_run_of_ten_words_and_not_of_nine():
    source = {"notes": "The valve, when OPEN, fills the actuator from the supply at once."}
    ten = "we say: the valve when open fills the actuator from the supply, we think"
    nine = "we say: a valve when open fills the actuator from the supply, we think"
    assert shared_runs(ten, source) == [
        "notes: the valve when open fills the actuator from the supply"
    ]
    assert shared_runs(nine, source) == []
    assert words("t_on = 3 ms; P+ - P-") == ["t", "on", "3", "ms", "p", "p"]
    assert words(without_math(r"at $\xi/f_W$, $$J = \sum_i e_i$$ here")) == ["at", "here"]


def documents() -> list[Path]:
    """Every text file under docs/, and the README."""
    text = {".md", ".py", ".rst", ".txt"}
    docs = sorted(p for p in (ROOT / "docs").rglob("*") if p.is_file() and p.suffix in text)
    # the sources, not what a build wrote beside them (ignored by git): the same cases on a
    # fresh clone and after `make docs`
    built = ("_build", "generated", "jupyter_execute", "api")
    docs = [p for p in docs if not set(p.relative_to(ROOT / "docs").parts[:-1]) & set(built)]
    generated = {"reference/cli.md", "getting-started/_source.md"}
    docs = [p for p in docs if p.relative_to(ROOT / "docs").as_posix() not in generated
            and not (p.parent.name == "gallery" and p.suffix == ".md")]  # fmt: skip
    return [*docs, ROOT / "README.md"]


@pytest.mark.parametrize("doc", documents(), ids=lambda p: str(p.relative_to(ROOT)))
def test_no_run_of_ten_words_is_copied_from_the_reference_notes(doc):
    notes = read_digests()
    mine = runs(without_math(doc.read_text(encoding="utf-8")))
    copied = sorted(" ".join(r) for r in mine if digest(r) in notes)
    assert not copied, f"{doc.name} repeats {len(copied)} runs of {RUN} words:\n" + "\n".join(
        copied
    )


def test_the_digest_finds_a_copied_run_and_not_a_restated_one():
    """A run of the notes' own words is in the digest file; the same run with one word
    changed is not (the digest file is what the check above reads)."""
    notes = read_digests()
    assert len(notes) > 5000
    text = "the valve when open fills the actuator from the supply at once"
    assert digest(tuple(words(text))[:RUN]) not in notes  # our own sentence


def test_the_digest_file_is_the_notes_where_they_are_beside_the_checkout():
    folder = shared_folder()
    if folder is None:
        pytest.skip("the notes are not beside this checkout: the digest file stands for them")
    assert notes_digests(folder) == sorted(read_digests()), (
        "tests/notes-runs.txt is not the notes' digest: python tests/test_docs.py --write"
    )
    paper = sorted((folder / "paper").glob("*.txt"))[0].read_text(encoding="utf-8")
    some = sorted(runs(paper))[len(paper) % 97]
    assert digest(some) in read_digests()


if __name__ == "__main__":  # python tests/test_docs.py --write
    import sys

    if sys.argv[1:] != ["--write"] or shared_folder() is None:
        sys.exit("usage: python tests/test_docs.py --write (with the notes in ../shared)")
    header = [
        f"# The 40-bit BLAKE2b digest of every run of {RUN} words of the reference notes",
        "# (MODEL.md, STYLE.md, the paper's text), lower case, punctuation left out:",
        "# tests/test_docs.py checks the documentation against them. Written by",
        "# python tests/test_docs.py --write",
    ]
    DIGESTS.write_text("\n".join(header + notes_digests(shared_folder())) + "\n", encoding="ascii")
