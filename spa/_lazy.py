"""Lazy re-exports for a package's ``__init__`` (PEP 562).

A package names the submodules whose public names (their ``__all__``) it re-exports; a name
is imported on first use, so that importing one module of a stage does not import every
other (a workflow job pays only for what it uses: ``benchmarks/bench_imports.py``). The
``__all__`` lists are read from the submodules' source, not by importing them, so each
public name is listed once, in the module that defines it.
"""

from __future__ import annotations

import ast
import importlib
import importlib.util
import re
import sys
import types
from collections.abc import Callable, Iterable, Mapping
from pathlib import Path
from typing import Any

_ALL = re.compile(r"^__all__\s*=\s*([\[(][^\])]*[\])])[ \t]*(?:#[^\n]*)?$", re.MULTILINE)
"""A literal ``__all__ = [...]`` (or a tuple) alone on its lines: its brackets, whole."""


def declared_names(path: Path) -> list[str]:
    """The names in the literal ``__all__ = [...]`` of a module's source file.

    The assignment is found by its text and only its list is parsed (a package's import
    parses a dozen modules' lists: the whole source would cost a job about a tenth of a
    second); where its text is not a plain list of strings, the whole module is parsed.

    Examples
    --------
    >>> import spa.model.params
    >>> declared_names(Path(spa.model.params.__file__))
    ['DELAY_CONVENTIONS', 'PHYSICAL_RANGE', 'ValveParams']
    """
    source = path.read_text(encoding="utf-8")
    match = _ALL.search(source)
    if match is not None:
        try:
            names = ast.literal_eval(match.group(1))
        except (ValueError, SyntaxError):
            names = None
        if isinstance(names, list | tuple) and all(isinstance(n, str) for n in names):
            return list(names)
    return _parsed_names(source, path)


def _parsed_names(source: str, path: Path) -> list[str]:
    """``declared_names`` by parsing the whole module: the literal ``__all__`` at its top level."""
    for node in ast.parse(source).body:
        if (
            isinstance(node, ast.Assign)
            and any(isinstance(t, ast.Name) and t.id == "__all__" for t in node.targets)
            and isinstance(node.value, ast.List | ast.Tuple)
        ):
            return [ast.literal_eval(elt) for elt in node.value.elts]
    raise ValueError(f"{path}: no literal __all__ list to re-export")


class _LazyPackage(types.ModuleType):
    """A package whose public names win over its submodules of the same name.

    Importing a submodule sets it as an attribute of its package: after
    ``import spa.identification.identify``, ``spa.identification.identify`` would be the module,
    not the function the package exports. A package with eager imports overwrote it; this one
    keeps the exported name instead.
    """

    _spa_exports: dict[str, str]

    def __setattr__(self, name: str, value: Any) -> None:
        exports = self.__dict__.get("_spa_exports", {})
        if (
            isinstance(value, types.ModuleType)
            and name in exports
            and value.__name__ == f"{self.__name__}.{name}"
        ):
            return
        super().__setattr__(name, value)


def lazy_exports(
    package: str, modules: Iterable[str], extra: Mapping[str, str] | None = None
) -> tuple[dict[str, str], Callable[[str], Any], Callable[[], list[str]]]:
    """The export map, ``__getattr__`` and ``__dir__`` of a package that re-exports lazily.

    Parameters
    ----------
    package : str
        The package's ``__name__``.
    modules : iterable of str
        Submodules (short names) whose ``__all__`` the package re-exports; a name declared by
        two of them is taken from the first.
    extra : mapping, optional
        More public names → the module (full name) that defines each.

    Returns
    -------
    exports : dict
        Public name → the module that defines it (its keys are the package's ``__all__``).
    getattr, dir : callable
        Assign them to the package's ``__getattr__`` and ``__dir__``. ``getattr`` also
        imports a submodule of the package by name (``spa.openloop.chirp``).

    Examples
    --------
    >>> exports, getattr_, dir_ = lazy_exports("spa.model", ["params"])
    >>> sorted(exports), exports["ValveParams"]
    (['DELAY_CONVENTIONS', 'PHYSICAL_RANGE', 'ValveParams'], 'spa.model.params')
    >>> getattr_("ValveParams").__name__
    'ValveParams'
    """
    namespace = importlib.import_module(package).__dict__
    folder = Path(namespace["__file__"]).parent
    exports: dict[str, str] = {}
    for module in modules:
        for name in declared_names(folder / f"{module}.py"):
            exports.setdefault(name, f"{package}.{module}")
    exports.update(extra or {})
    package_module = sys.modules[package]
    package_module.__class__ = _LazyPackage
    package_module.__dict__["_spa_exports"] = exports

    def __getattr__(name: str) -> Any:
        module = exports.get(name)
        if module is not None:
            value = getattr(importlib.import_module(module), name)
        elif importlib.util.find_spec(f"{package}.{name}") is not None:
            value = importlib.import_module(f"{package}.{name}")
        else:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        namespace[name] = value
        return value

    def __dir__() -> list[str]:
        return sorted({*namespace, *exports})

    return exports, __getattr__, __dir__
