"""The safe YAML loader of ``dataset.yaml``: duplicate keys refused, YAML 1.2 floats, and bounds
on size, aliases, expanded values and depth (hostile files are refused in bounded time and
memory)."""

from __future__ import annotations

import datetime as _dt
import math
import re
from collections.abc import Mapping
from typing import Any

import yaml

#: Bounds on a ``dataset.yaml``: a description is a few kB; these stop hostile or broken
#: files (an alias "billion laughs" bomb, thousands of nested brackets, a huge file) in
#: bounded time and memory, with a message.
MAX_SPEC_BYTES = 1 << 20


MAX_ALIASES = 100


MAX_DEPTH = 20


MAX_NODES = 100_000  # values once every alias is expanded


class _SpecTooComplex(yaml.YAMLError):
    """A dataset.yaml over one of the bounds above."""


def _expanded_size(node: yaml.Node, memo: dict[int, int]) -> int:
    """Values in a composed YAML tree with every alias expanded (each shared node counted once
    per reference), in time linear in the number of distinct nodes."""
    key = id(node)
    if key not in memo:
        memo[key] = 1  # a cycle counts once
        if isinstance(node, yaml.MappingNode):
            children = [n for pair in node.value for n in pair]
        elif isinstance(node, yaml.SequenceNode):
            children = list(node.value)
        else:
            children = []
        memo[key] = 1 + sum(min(_expanded_size(c, memo), MAX_NODES + 1) for c in children)
    return memo[key]


class _UniqueKeyLoader(yaml.SafeLoader):
    """Safe YAML loader that rejects a key given twice in one mapping.

    Floats are read as YAML 1.2 reads them, so ``20e-3`` is a number (YAML 1.1, PyYAML's
    default, needs ``20.0e-3`` and would give the string ``'20e-3'``). At most
    :data:`MAX_ALIASES` aliases (``*name``) and :data:`MAX_DEPTH` levels of nesting.
    """

    def __init__(self, stream: str) -> None:
        super().__init__(stream)
        self._aliases = 0
        self._depth = 0

    def get_single_node(self) -> Any:
        node = super().get_single_node()
        if node is not None and _expanded_size(node, {}) > MAX_NODES:
            raise _SpecTooComplex(
                f"more than {MAX_NODES} values once its aliases are expanded (an alias bomb?)"
            )
        return node

    def compose_node(self, parent: Any, index: Any) -> Any:
        if self.check_event(yaml.AliasEvent):
            self._aliases += 1
            if self._aliases > MAX_ALIASES:
                raise _SpecTooComplex(f"more than {MAX_ALIASES} aliases (*name)")
        self._depth += 1
        try:
            if self._depth > MAX_DEPTH:
                raise _SpecTooComplex(f"nested more than {MAX_DEPTH} levels deep")
            return super().compose_node(parent, index)
        finally:
            self._depth -= 1


_UniqueKeyLoader.yaml_implicit_resolvers = {
    k: [r for r in v if r[0] != "tag:yaml.org,2002:float"]
    for k, v in yaml.SafeLoader.yaml_implicit_resolvers.items()
}


_UniqueKeyLoader.add_implicit_resolver(
    "tag:yaml.org,2002:float",
    re.compile(
        r"""^(?:[-+]?(?:[0-9][0-9_]*)\.[0-9_]*(?:[eE][-+]?[0-9]+)?
        |[-+]?(?:[0-9][0-9_]*)(?:[eE][-+]?[0-9]+)
        |\.[0-9_]+(?:[eE][-+]?[0-9]+)?
        |[-+]?\.(?:inf|Inf|INF)
        |\.(?:nan|NaN|NAN))$""",
        re.X,
    ),
    list("-+0123456789."),
)


def _construct_mapping(loader: yaml.SafeLoader, node: yaml.MappingNode, deep: bool = False) -> Any:
    seen: set[Any] = set()
    for key_node, _ in node.value:
        key = loader.construct_object(key_node, deep=deep)
        try:
            duplicate = key in seen
        except TypeError:
            continue
        if duplicate:
            raise yaml.constructor.ConstructorError(
                "while constructing a mapping",
                node.start_mark,
                f"found duplicate key {key!r}",
                key_node.start_mark,
            )
        seen.add(key)
    return loader.construct_mapping(node, deep=deep)


_UniqueKeyLoader.add_constructor(yaml.resolver.BaseResolver.DEFAULT_MAPPING_TAG, _construct_mapping)


def _plain(value: Any) -> Any:
    """Turn YAML values into JSON-compatible ones (dates become ISO strings)."""
    if isinstance(value, Mapping):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_plain(v) for v in value]
    if isinstance(value, _dt.date | _dt.datetime | _dt.time):
        return value.isoformat()
    if value is None or isinstance(value, bool | int | float | str):
        if isinstance(value, float) and not math.isfinite(value):
            return str(value)
        return value
    return str(value)
