"""The gallery: runnable examples (``docs/gallery/*.py``), each drawn when the site is built.

Each example is a plain script: its docstring's first line is its title, the rest says what
it shows, and it saves its figure to the path given as its one argument. Before Sphinx reads
the sources, :func:`write_gallery` runs every script in a fresh interpreter, keeps its
figure (``docs/gallery/_images/<name>.png``, the thumbnail and the page's picture) and what
it printed, and writes one page per example and the gallery's index. An example that fails
fails the build. The generated files are not kept in git.
"""

from __future__ import annotations

import ast
import os
import subprocess
import sys
import tempfile
from pathlib import Path


def examples(folder: Path) -> list[Path]:
    """The example scripts of ``folder``, by name."""
    return sorted(p for p in folder.glob("*.py") if not p.name.startswith("_"))


def title_and_text(script: Path) -> tuple[str, str]:
    """The script's title (its docstring's first line, without the full stop) and the rest."""
    doc = ast.get_docstring(ast.parse(script.read_text(encoding="utf-8"))) or script.stem
    first, _, rest = doc.partition("\n")
    return first.strip().rstrip("."), rest.strip()


def run_example(script: Path, image: Path, root: Path) -> str:
    """Run ``script`` in a fresh interpreter in a scratch folder; return what it printed.

    Raises
    ------
    RuntimeError
        When the script fails or draws no figure; the message names the script.
    """
    env = dict(os.environ, MPLBACKEND="Agg", SPA_PROGRESS="0")
    env["PYTHONPATH"] = os.pathsep.join(p for p in (str(root), env.get("PYTHONPATH", "")) if p)
    with tempfile.TemporaryDirectory(prefix="spa-gallery-") as scratch:
        argv = [sys.executable, str(script.resolve()), str(image.resolve())]
        res = subprocess.run(argv, cwd=scratch, env=env,
                             capture_output=True, text=True, timeout=600)  # fmt: skip
    if res.returncode != 0 or not image.is_file():
        raise RuntimeError(f"gallery example {script.name} failed:\n{res.stderr[-3000:]}")
    return res.stdout.strip()


def example_page(script: Path, output: str) -> str:
    """The Markdown page of one example: what it shows, its picture, its code, its output."""
    title, text = title_and_text(script)
    lines = [f"# {title}", "", text, "", f"![{title}](_images/{script.stem}.png)", "",
             f"Run it from the source folder: `python docs/gallery/{script.name}`.", "",
             f"```{{literalinclude}} {script.name}", ":language: python", "```", ""]  # fmt: skip
    if output:
        lines += ["What it prints:", "", "```text", output, "```", ""]
    return "\n".join(lines)


def index_page(scripts: list[Path]) -> str:
    """The gallery's index: each example's thumbnail, linked to its page."""
    lines = [
        "# Gallery",
        "",
        "Short, runnable examples of spa from Python, each with the picture it draws. Every",
        "picture here was made by running its example when this site was built.",
        "",
    ]
    for script in scripts:
        title, _ = title_and_text(script)
        lines += [f"## {title}", "", f"[![{title}](_images/{script.stem}.png)]({script.stem}.md)",
                  "", f"{{doc}}`The example <{script.stem}>`.", ""]  # fmt: skip
    lines += ["```{toctree}", ":hidden:", "", *(s.stem for s in scripts), "```", ""]
    return "\n".join(lines)


def _write(path: Path, text: str) -> None:
    if not path.is_file() or path.read_text(encoding="utf-8") != text:
        path.write_text(text, encoding="utf-8")


def write_gallery(folder: Path, root: Path) -> list[Path]:
    """Run every example of ``folder`` and write its page and the index; return the pages."""
    (folder / "_images").mkdir(exist_ok=True)
    scripts = examples(folder)
    pages = []
    for script in scripts:
        output = run_example(script, folder / "_images" / f"{script.stem}.png", root)
        page = folder / f"{script.stem}.md"
        _write(page, example_page(script, output))
        pages.append(page)
    _write(folder / "index.md", index_page(scripts))
    return pages
