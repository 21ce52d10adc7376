"""The results' store: its folders, and the parts of a YAML output a stage reads.

Beside the declared outputs, ``<results>/.store`` keeps each stage's results by digest
(:mod:`spa.pipeline.reuse`), parts of a stage's work that depend on fewer settings
(:data:`MEMO`, :mod:`spa._memo`) and the parts of YAML files a stage reads (:data:`VIEWS`,
:func:`yaml_view`).
"""

from __future__ import annotations

import hashlib
import os
import tempfile
from collections.abc import Mapping
from pathlib import Path
from typing import Any

__all__ = ["MEMO", "STORE", "VIEWS", "project", "yaml_view"]

STORE = ".store"
"""The store's folder in the results folder."""

MEMO = "memo"
"""The store's folder of parts of a stage's work kept between runs (:mod:`spa._memo`)."""

VIEWS = "views"
"""The store's folder of the parts of YAML files a stage reads (:func:`yaml_view`)."""


def project(record: Any, fields: tuple[str, ...]) -> dict[str, Any]:
    """The part of a mapping named by dotted ``fields``; a field it lacks is left out.

    Examples
    --------
    >>> project({"a": {"b": 1, "c": 2}, "d": 3, "e": 4}, ("a.b", "d", "x.y"))
    {'a': {'b': 1}, 'd': 3}
    """
    out: dict[str, Any] = {}
    for field in fields:
        *parents, last = field.split(".")
        node: Any = record
        for name in parents:
            node = node.get(name) if isinstance(node, Mapping) else None
        if not isinstance(node, Mapping) or last not in node:
            continue
        target = out
        for name in parents:
            target = target.setdefault(name, {})
        target[last] = node[last]
    return out


def yaml_view(path: str | Path, fields: tuple[str, ...], folder: str | Path) -> Path:
    """A copy of the YAML file ``path`` holding ``fields`` alone (:func:`project`), for a
    stage that reads only those (:attr:`Stage.read_keys
    <spa.pipeline.stage_types.Stage.read_keys>`): it is given this copy instead of the file,
    so its digest covers exactly what it can see, and a change elsewhere in the file
    (the tuning's constraints echoed in its recommendation) leaves it reused.

    Parameters
    ----------
    path : path-like
        The YAML file; a missing one, or one that is not YAML, is returned as it is (the
        stage sees it, and its digest covers all of it).
    fields : tuple of str
        Dotted keys (``"recommended.setting"``).
    folder : path-like
        Where the copies go (``<results>/.store/views``): named by the sha256 of their
        content, so the same part gives the same path and the same digest.

    Returns
    -------
    pathlib.Path
    """
    import yaml

    from spa.io import dump_yaml, read_yaml

    source = Path(path)
    try:
        record = read_yaml(source)
    except (OSError, yaml.YAMLError):  # missing or not YAML: the stage sees the file itself
        return source
    part = project(record if isinstance(record, Mapping) else {}, fields)
    text = str(dump_yaml(part, sort_keys=True, allow_unicode=True))
    target = Path(folder) / f"{hashlib.sha256(text.encode()).hexdigest()}.yaml"
    if not target.is_file():
        target.parent.mkdir(parents=True, exist_ok=True)
        handle, name = tempfile.mkstemp(prefix=".view-", dir=target.parent)
        os.close(handle)
        tmp = Path(name)
        tmp.write_text(text, encoding="utf-8")
        os.replace(tmp, target)
    return target
