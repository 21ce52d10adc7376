"""YAML the pipeline wrote, read safely with libyaml's parser when PyYAML has it (about ten
times faster than the pure-Python one). Below every other module, so that any of them can
read a ``params.yaml`` (:mod:`spa.io` re-exports :func:`read_yaml`)."""

from __future__ import annotations

from pathlib import Path
from typing import IO, Any

__all__ = ["load_yaml", "read_yaml"]


def load_yaml(stream: str | IO[str]) -> Any:
    """``yaml.safe_load`` with libyaml's parser where PyYAML has it (the same data).

    Examples
    --------
    >>> load_yaml("a: [1, 2.5]")
    {'a': [1, 2.5]}
    """
    import yaml

    return yaml.load(stream, Loader=getattr(yaml, "CSafeLoader", yaml.SafeLoader))


def read_yaml(path: str | Path) -> Any:
    """A YAML file the pipeline wrote, read with :func:`load_yaml` (the report, the closed
    loop and every config check read a few per dataset)."""
    with open(path, encoding="utf-8") as fh:
        return load_yaml(fh)
