"""Write the API reference's reStructuredText pages from the packages' ``__all__``.

Each public module (no ``_`` in its dotted name, and an ``__all__``) gets ``api/<module>.rst``:
its docstring, then a table of its names. Every public name is documented once, on the page of
the module that defines it (the first non-package module whose ``__all__`` lists the same
object); a package that re-exports it links there. ``python -m spa`` (``spa.__main__``) is
never imported.
"""

from __future__ import annotations

import importlib
import pkgutil
from pathlib import Path
from types import ModuleType

import spa


def public_modules() -> list[ModuleType]:
    """``spa`` and every public module of it that has an ``__all__``, in name order."""
    found = [spa]
    for info in pkgutil.walk_packages(spa.__path__, "spa."):
        if any(part.startswith("_") for part in info.name.split(".")[1:]):
            continue
        module = importlib.import_module(info.name)
        if getattr(module, "__all__", None) is not None:
            found.append(module)
    return sorted(found, key=lambda m: m.__name__)


def homes(modules: list[ModuleType]) -> dict[tuple[str, str], str]:
    """``(module, name) -> module`` whose page documents ``name``."""
    defining = [m for m in modules if not hasattr(m, "__path__")]
    result = {}
    for module in modules:
        for name in module.__all__:
            obj = getattr(module, name)
            home = next(
                (
                    d.__name__
                    for d in defining
                    if name in d.__all__ and getattr(d, name, None) is obj
                ),
                module.__name__,
            )
            result[module.__name__, name] = home
    return result


def _title(text: str) -> str:
    return f"{text}\n{'=' * len(text)}\n"


def write_api_pages(folder: Path) -> list[str]:
    """Write ``folder/index.rst`` and one page per public module; return the modules."""
    modules = public_modules()
    home = homes(modules)
    folder.mkdir(parents=True, exist_ok=True)
    names = []
    for module in modules:
        mod = module.__name__
        names.append(mod)
        own = [n for n in module.__all__ if home[mod, n] == mod]
        linked = [n for n in module.__all__ if home[mod, n] != mod]
        lines = [_title(mod), f".. automodule:: {mod}\n", f".. currentmodule:: {mod}\n"]
        if own:
            lines += [".. autosummary::", "   :toctree: generated", ""]
            lines += [f"   {n}" for n in sorted(own)] + [""]
        if linked:
            lines += ["Re-exported here, documented where they are defined:", ""]
            lines += [".. currentmodule:: None", "", ".. autosummary::", ""]
            lines += [f"   ~{home[mod, n]}.{n}" for n in sorted(linked)] + [""]
        text = "\n".join(lines)
        path = folder / f"{mod}.rst"
        if not path.is_file() or path.read_text() != text:  # unchanged pages stay unchanged
            path.write_text(text)
    index = [
        _title("API reference"),
        "Generated from the docstrings: every public module of ``spa`` and every name in its",
        "``__all__``. The top level ``spa`` re-exports the most used ones.",
        "",
        ".. toctree::",
        "   :maxdepth: 1",
        "",
        *[f"   {m}" for m in names],
        "",
    ]
    text = "\n".join(index)
    if not (folder / "index.rst").is_file() or (folder / "index.rst").read_text() != text:
        (folder / "index.rst").write_text(text)
    return names
