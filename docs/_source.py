"""Where the source comes from, written from ``pyproject.toml``'s ``[project.urls]``.

One place holds the repository's address: ``[project.urls]`` (``Repository``, else
``Source``, else ``Homepage``). From it the install page's "Get the source" section
(``docs/getting-started/_source.md``, written before Sphinx reads the sources) and the icon
link in the site's header are made. Without an address there, the section says how the
source is obtained instead, and the header has no link: no address is ever made up.
"""

from __future__ import annotations

import tomllib
from pathlib import Path

#: ``[project.urls]`` keys that name the source repository, most specific first.
KEYS: tuple[str, ...] = ("Repository", "Source", "Source Code", "Homepage")
#: The folder the install page clones into (not ``spa``: it would shadow the package).
FOLDER = "spa-pipeline"


def repository_url(pyproject: Path) -> str | None:
    """The repository's address from ``[project.urls]``, or None where none is set."""
    urls = tomllib.loads(pyproject.read_text(encoding="utf-8")).get("project", {}).get("urls", {})
    for key in KEYS:
        if isinstance(urls.get(key), str) and urls[key].strip():
            return urls[key].strip()
    return None


def source_section(url: str | None) -> str:
    """The Markdown of the install page's step "Get the source"."""
    if url:
        return (
            f"Clone the repository into a folder **not** named `spa` ({FOLDER} here):\n\n"
            f"```bash\ngit clone {url} {FOLDER} && cd {FOLDER}\n```\n"
        )
    return (
        "This copy of spa has no public address yet (`pyproject.toml` sets no\n"
        "`[project.urls]`), so the source comes from whoever gave you this documentation: a\n"
        "`git clone` of their repository, or an archive of it (`git archive`, a `.zip`).\n"
        f"Put it in a folder **not** named `spa` ({FOLDER} here) and work inside that folder;\n"
        "every command below runs there.\n"
    )


def icon_links(url: str | None) -> list[dict[str, str]]:
    """The header's icon links (pydata-sphinx-theme's ``icon_links``): the repository's."""
    if not url:
        return []
    icon = "fa-brands fa-github" if "github.com" in url else "fa-solid fa-code-branch"
    return [{"name": "Source repository", "url": url, "icon": icon, "type": "fontawesome"}]


def write_source_section(pyproject: Path, path: Path) -> Path:
    """Write :func:`source_section` for ``pyproject`` to ``path`` unless it already holds it."""
    text = source_section(repository_url(pyproject))
    if not path.is_file() or path.read_text(encoding="utf-8") != text:
        path.write_text(text, encoding="utf-8")
    return path
