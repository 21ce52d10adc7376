"""Sphinx configuration of spa's documentation site: ``make docs`` builds it offline into
``docs/_build/html``.

The site is in four parts, by what the reader is doing: getting started (a tutorial whose
pages run at build time, with myst-nb, on the bundled example), how-to guides, explanation
and reference. The reference's API page is written by hand, grouped by task (like
scipy.signal's); its entries are checked against the public ``__all__`` lists by
``tests/test_docs_site.py``. The CLI page is generated from ``spa.cli``'s parser
(:mod:`docs._cli`).
"""

from __future__ import annotations

import os
import re
import sys
import tempfile
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path[:0] = [str(ROOT), str(HERE)]  # this checkout's spa, whatever the venv points at

from _cli import write_cli_page  # noqa: E402
from _execute import cache_folder, executed_pages, prime, sources_key  # noqa: E402
from _gallery import write_gallery  # noqa: E402
from _source import icon_links, repository_url, write_source_section  # noqa: E402
from _summaries import extend_abbreviations  # noqa: E402

import spa  # noqa: E402

# The executed pages (and the commands they start) import this checkout's spa.
os.environ["PYTHONPATH"] = os.pathsep.join(
    p for p in (str(ROOT), os.environ.get("PYTHONPATH", "")) if p
)
# ... and find this environment's commands (spa, snakemake) first.
os.environ["PATH"] = os.pathsep.join((str(Path(sys.executable).parent), os.environ["PATH"]))
os.environ.setdefault("MPLBACKEND", "Agg")
os.environ.setdefault("SPA_PROGRESS", "0")
# The executed pages' kernels run quietly (ipykernel warns on stderr about its TCP transport).
_IPYTHON = Path(tempfile.mkdtemp(prefix="spa-docs-ipython-"))
(_IPYTHON / "profile_default").mkdir()
(_IPYTHON / "profile_default" / "ipython_kernel_config.py").write_text(
    'c.IPKernelApp.log_level = "ERROR"\n'
)
os.environ["IPYTHONDIR"] = str(_IPYTHON)

project = "spa"
author = "spa contributors"
copyright = "2025, spa contributors"
version = release = spa.__version__

extensions = [
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "sphinx.ext.mathjax",
    "sphinx.ext.viewcode",
    "numpydoc",
    "myst_nb",  # Markdown through MyST, and the executed tutorial pages
]
source_suffix = {".rst": "restructuredtext", ".md": "myst-nb"}
# docs/model.md is included by explanation/model.md; the generated pages of the old layout
# (docs/api/) are not part of the site.
exclude_patterns = [
    "_build", "**/.ipynb_checkpoints", "model.md", "api", "**/_work", "getting-started/_source.md"
]  # fmt: skip
root_doc = "index"

# The CLI page, written before Sphinx reads the sources.
write_cli_page(HERE / "reference" / "cli.md")
# Where the source comes from: [project.urls] of pyproject.toml, the one place that says.
REPOSITORY = repository_url(ROOT / "pyproject.toml")
write_source_section(ROOT / "pyproject.toml", HERE / "getting-started" / "_source.md")
# The gallery: every example of docs/gallery/ run now, its picture and page written.
write_gallery(HERE / "gallery", ROOT)

autosummary_generate = True
extend_abbreviations()  # a summary does not stop at "(Eq." or "(App."
autosummary_imported_members = False
autodoc_default_options = {"members": False}
autodoc_typehints = "none"  # numpydoc's Parameters section states the types
numpydoc_show_class_members = False
numpydoc_class_members_toctree = False
numpydoc_xref_param_type = False

# Markdown (MyST); the pages of docs/getting-started and explanation/figures run at build
# time, offline, on the bundled example; an error in a cell fails the build.
myst_enable_extensions = ["dollarmath", "amsmath", "colon_fence", "deflist"]
myst_heading_anchors = 3
# Each executed page runs once per state of what it uses (docs/_execute.py): its outputs are
# cached under a digest of spa/, workflow/, the configs and raw/example, so a rebuild with
# nothing changed starts no kernel and a change to any of them runs the pages again.
nb_execution_mode = "cache"
nb_execution_timeout = 600
nb_execution_raise_on_error = True
nb_execution_show_tb = True
nb_merge_streams = True
nb_execution_cache_path = os.environ.get("SPA_DOCS_NB_CACHE") or str(
    cache_folder(HERE / "_build", sources_key(ROOT))
)  # SPA_DOCS_NB_CACHE: another folder (benchmarks/bench_docs_load.py runs every build cold)
prime(
    executed_pages(HERE, exclude=("_build", "_work", ".ipynb_checkpoints")),
    Path(nb_execution_cache_path),
    extensions=myst_enable_extensions,
    heading_anchors=myst_heading_anchors,
    timeout=nb_execution_timeout,
)

html_theme = "pydata_sphinx_theme"
html_title = f"spa {release}"
html_static_path: list[str] = []
html_theme_options = {
    "navbar_align": "left",
    "show_toc_level": 2,
    "navigation_with_keys": False,
    "secondary_sidebar_items": ["page-toc"],
    "footer_start": ["copyright"],
    "footer_end": [],
    "icon_links": icon_links(REPOSITORY),  # none until [project.urls] names the repository
}
html_sidebars = {"index": []}
# Offline: MathJax is loaded by the reader's browser; the build fetches nothing.

#: A development note in an included file's heading, e.g. "(issue 17)": not for the site.
_ISSUE_NOTE = re.compile(r"[ \t]*\((?:see )?issue \d+[^)\n]*\)")


def _strip_issue_notes(app, relative_path, parent_docname, content):
    """Drop "(issue N ...)" notes from the Markdown files the site includes."""
    content[0] = _ISSUE_NOTE.sub("", content[0])


def setup(app):
    app.connect("include-read", _strip_issue_notes)
