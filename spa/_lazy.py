"""Lazy re-exports for a package's ``__init__`` (PEP 562).

A package lists its public names and the module defining each; a name is imported on first
use, so that importing one module of a stage does not import every other (a workflow job
pays only for what it uses: ``benchmarks/bench_imports.py``).
"""

from __future__ import annotations

import importlib
import importlib.util
from collections.abc import Callable, Mapping
from typing import Any


def lazy_exports(
    package: str, exports: Mapping[str, str]
) -> tuple[Callable[[str], Any], Callable[[], list[str]]]:
    """The ``__getattr__`` and ``__dir__`` of a package that re-exports names lazily.

    Parameters
    ----------
    package : str
        The package's ``__name__``.
    exports : mapping
        Public name → the module that defines it.

    Returns
    -------
    getattr, dir : callable
        Assign them to the package's ``__getattr__`` and ``__dir__``. ``getattr`` also
        imports a submodule of the package by name (``spa.openloop.chirp``).

    Examples
    --------
    >>> getattr_, dir_ = lazy_exports("spa.model", {"ValveParams": "spa.model.params"})
    >>> getattr_("ValveParams").__name__
    'ValveParams'
    >>> "ValveParams" in dir_()
    True
    """
    namespace = importlib.import_module(package).__dict__

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

    return __getattr__, __dir__
