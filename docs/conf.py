"""Sphinx configuration of spa's documentation site: ``make docs`` builds it offline into
``docs/_build/html``.

The API reference is generated from the docstrings (numpydoc) on every build: each public
module (one with ``__all__``) gets a page, and each public name one page, under the module
that defines it; a package's page links its names there (:mod:`docs._api`).
"""

from __future__ import annotations

import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from _api import write_api_pages  # noqa: E402

import spa  # noqa: E402

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
    "myst_parser",
]
source_suffix = {".rst": "restructuredtext", ".md": "markdown"}
exclude_patterns = ["_build", "**/.ipynb_checkpoints"]
root_doc = "index"

# The API pages, written before Sphinx reads the sources.
write_api_pages(HERE / "api")
autosummary_generate = True
autosummary_imported_members = False
autodoc_default_options = {"members": False}
autodoc_typehints = "none"  # numpydoc's Parameters section states the types
numpydoc_show_class_members = False
numpydoc_class_members_toctree = False
numpydoc_xref_param_type = False

# Markdown pages (the README's guide, docs/model.md, benchmarks/README.md) through MyST.
myst_enable_extensions = ["dollarmath", "amsmath"]
myst_heading_anchors = 3

html_theme = "alabaster"
html_title = f"spa {release}"
html_static_path: list[str] = []
html_theme_options = {"description": "soft pneumatic actuator, on/off valve, pulse modulators"}
# Offline: MathJax is loaded by the reader's browser; the build fetches nothing.
