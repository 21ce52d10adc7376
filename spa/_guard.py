"""Refuse to run with a folder named ``spa`` in the way of the package.

A clone of the repository in a folder named ``spa``, with Python started in that folder's
parent (a notebook, ``python -m snakemake``), makes ``import spa`` find the clone's folder:
it has no ``__init__.py``, so Python imports it as an empty namespace package, while the
editable install still provides ``spa.<module>``. ``spa.simulate`` or ``spa.__version__``
then fail far from the cause. The workflow (``workflow/rules/common.smk``) and the command
line call :func:`check_package` first, which names the folder and the fix.
"""

from __future__ import annotations

import sys
from types import ModuleType

__all__ = ["ShadowedPackageError", "check_package", "shadowing_folders"]


class ShadowedPackageError(RuntimeError):
    """``import spa`` found a folder without the package (see the module's docstring)."""


def shadowing_folders(module: ModuleType | None = None) -> list[str]:
    """The folders ``import spa`` found instead of the package; empty when it is the package.

    Parameters
    ----------
    module : module, optional
        The imported ``spa`` (default: ``sys.modules["spa"]``, importing it if needed).

    Examples
    --------
    >>> shadowing_folders()
    []
    >>> shadowing_folders(ModuleType("spa"))  # a module without a file: no folder to name
    ['(unknown)']
    """
    if module is None:
        import spa as module  # the module checked is the one Python imports
    if getattr(module, "__file__", None):
        return []
    return [str(p) for p in getattr(module, "__path__", [])] or ["(unknown)"]


def check_package(module: ModuleType | None = None) -> None:
    """Raise :class:`ShadowedPackageError` when ``import spa`` is not the package.

    Raises
    ------
    ShadowedPackageError
        Naming the folder that shadows the package and what to do.
    """
    folders = shadowing_folders(module)
    if folders:
        raise ShadowedPackageError(
            f"'import spa' found the folder {', '.join(folders)} (no __init__.py: an empty "
            "namespace package), not the spa package. This happens when the repository is "
            "cloned into a folder named 'spa' and Python runs in its parent folder. Run from "
            "inside the clone, or clone it under another name: git clone <url> spa-pipeline "
            f"(Python: {sys.executable})."
        )
