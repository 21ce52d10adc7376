"""The site's executed pages, run once per state of what they use, before Sphinx reads.

A page with ``file_format: mystnb`` in its front matter runs at build time (the tutorial, the
notebook page, the figures page). myst-nb's ``cache`` mode keeps each page's outputs in a
jupyter-cache folder, keyed on the page's code cells; this module adds what the pages *use*
to the key: the folder is named after :func:`sources_key`, a digest of the package, the
workflow, the configs and the bundled example. So

- a rebuild with nothing changed starts no kernel, and the page shows the outputs that the
  current code computed;
- a change to anything a page uses (``spa/``, ``workflow/``, ``raw/example``, a page's own
  code) runs it again.

jupyter-cache keeps its index in SQLite, and Sphinx's parallel readers (``-j auto``) would
write to it at once (a known source of "database is locked"). :func:`prime` therefore runs
the pages whose outputs are missing in worker processes and writes the index from this one
process only, before Sphinx reads; the readers then only look their pages up. A page that
fails here is not cached: myst-nb runs it again as it reads, and reports the error as a
Sphinx warning with the cell's traceback, as it would without a cache.
"""

from __future__ import annotations

import hashlib
import multiprocessing
import re
import shutil
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

#: What the executed pages use, relative to the repository: a change to any file below one
#: of these runs them again.
USED = ("spa", "workflow", "config", "profiles", "raw/example", "Snakefile", "pyproject.toml",
        "requirements.lock")  # fmt: skip

_MYSTNB = re.compile(r"\A---\n(?:.*\n)*?file_format:\s*mystnb\s*\n(?:.*\n)*?---\n")


def sources_key(root: Path, used: tuple[str, ...] = USED) -> str:
    """SHA-256 (first 16 hex digits) of every file the executed pages use.

    Parameters
    ----------
    root : Path
        The repository.
    used : tuple of str
        Files and folders relative to ``root``; folders are read recursively, without
        ``__pycache__`` and compiled files.

    Returns
    -------
    str
        The digest of the files' relative paths and contents, in path order.
    """
    h = hashlib.sha256()
    for name in used:
        top = root / name
        files = [top] if top.is_file() else sorted(p for p in top.rglob("*") if p.is_file())
        for path in files:
            if "__pycache__" in path.parts or path.suffix in (".pyc", ".pyo"):
                continue
            h.update(path.relative_to(root).as_posix().encode() + b"\0" + path.read_bytes())
    return h.hexdigest()[:16]


def executed_pages(docs: Path, exclude: tuple[str, ...] = ("_build",)) -> list[Path]:
    """The Markdown pages of ``docs`` that myst-nb executes (``file_format: mystnb``).

    Examples
    --------
    >>> import tempfile
    >>> d = Path(tempfile.mkdtemp())
    >>> _ = (d / "run.md").write_text("---\\nfile_format: mystnb\\n---\\n# A\\n")
    >>> _ = (d / "text.md").write_text("# B\\n")
    >>> [p.name for p in executed_pages(d)]
    ['run.md']
    """
    return [
        p
        for p in sorted(docs.rglob("*.md"))
        if not set(p.relative_to(docs).parts) & set(exclude)
        and _MYSTNB.match(p.read_text(encoding="utf-8"))
    ]


def cache_folder(build: Path, key: str) -> Path:
    """The jupyter-cache folder for ``key`` under ``build``; the folders of other keys (the
    outputs of sources that are gone) are removed."""
    top = build / ".jupyter_cache"
    top.mkdir(parents=True, exist_ok=True)
    for old in top.iterdir():
        if old.name != key:
            shutil.rmtree(old, ignore_errors=True)
    return top / key


def read_page(page: Path, extensions: list[str], heading_anchors: int):
    """The notebook myst-nb makes of ``page`` as Sphinx reads it (so that its cache key is
    the one myst-nb looks up)."""
    from myst_nb.core.read import read_myst_markdown_notebook
    from myst_parser.config.main import MdParserConfig

    config = MdParserConfig(enable_extensions=set(extensions), heading_anchors=heading_anchors)
    return read_myst_markdown_notebook(
        page.read_text(encoding="utf-8"), config=config, add_source_map=True, path=page
    )


def _run(page: str, notebook, timeout: int):
    """Execute one page's notebook in its folder (a worker's job)."""
    from jupyter_cache.executors.utils import single_nb_execution

    result = single_nb_execution(
        notebook, cwd=str(Path(page).parent), timeout=timeout, allow_errors=False
    )
    return notebook, result.time, result.err is None


def prime(
    pages: list[Path],
    cache: Path,
    *,
    extensions: list[str],
    heading_anchors: int,
    timeout: int,
    workers: int = 2,
) -> list[Path]:
    """Run every page of ``pages`` whose outputs ``cache`` lacks, and cache those that ran.

    Parameters
    ----------
    pages : list of Path
        Executed pages (:func:`executed_pages`).
    cache : Path
        The jupyter-cache folder (:func:`cache_folder`).
    extensions, heading_anchors
        The site's MyST settings (``myst_enable_extensions``, ``myst_heading_anchors``).
    timeout : int
        Seconds a cell may run (``nb_execution_timeout``).
    workers : int
        Pages run at once, each in its own process and kernel.

    Returns
    -------
    list of Path
        The pages that ran (none when every page's outputs were cached). Those that failed
        are among them and stay uncached.
    """
    from jupyter_cache import get_cache
    from jupyter_cache.base import CacheBundleIn

    store = get_cache(str(cache))
    notebooks = {p: read_page(p, extensions, heading_anchors) for p in pages}
    missing = []
    for page, notebook in notebooks.items():
        try:
            store.match_cache_notebook(notebook)
        except KeyError:
            missing.append(page)
    if not missing:
        return []
    # fork: the workers start from this process as it is (Sphinx's own parallel readers do
    # the same); a spawned worker would re-run the command that started Sphinx.
    context = multiprocessing.get_context("fork")
    with ProcessPoolExecutor(max_workers=max(1, workers), mp_context=context) as pool:
        jobs = {p: pool.submit(_run, str(p), notebooks[p], timeout) for p in missing}
        for page, job in jobs.items():
            executed, seconds, ok = job.result()
            if ok:
                store.cache_notebook_bundle(
                    CacheBundleIn(executed, str(page), data={"execution_seconds": seconds}),
                    check_validity=False,
                    overwrite=True,
                )
    return missing
