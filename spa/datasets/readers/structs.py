"""Names inside a MATLAB file: variables, struct field paths and dSpace recording signals.

Both MATLAB readers (v5 through ``scipy.io``, v7.3 through ``h5py``) describe what a file holds
as *leaves*: one per variable or struct field, with its MATLAB class, its shape and a way to
read rows of it. :class:`_StructSource` then resolves the names used in ``dataset.yaml``:

* a variable (``p_act``) or a struct field path (``rec.sensors.p_act``);
* a signal of a **dSpace ControlDesk recording** (a struct variable with fields ``X`` and
  ``Y``, each a struct array with fields ``Name`` and ``Data``) by its full ``Name``
  (``Platform/Model Root/Sensors/p_act``) or by the last component of that path when no other
  signal ends the same way (``p_act``);
* ``t``, when no variable or signal is called so and the file holds exactly one dSpace ``X``
  entry (the recording's time axis): that entry.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import numpy.typing as npt

from spa.datasets.contract import _BATCH_ROWS
from spa.datasets.problems import _suggest
from spa.datasets.readers.base import Source, _Chunk, _ReadError

#: MATLAB classes read as numbers.
NUMERIC_CLASSES = frozenset(
    ["double", "single", "logical"] + [f"{s}int{b}" for s in ("", "u") for b in (8, 16, 32, 64)]
)

_LISTED = 12  # names listed in a message


@dataclass
class _Leaf:
    """One variable or struct field: MATLAB class, MATLAB shape, reader of rows."""

    kind: str
    shape: tuple[int, ...]
    read: Callable[[int, int], npt.NDArray[np.float64]] | None = None
    fields: tuple[str, ...] = ()

    @property
    def is_vector(self) -> bool:
        return len(self.shape) <= 2 and (min(self.shape, default=1) <= 1)

    @property
    def size(self) -> int:
        return int(np.prod(self.shape)) if self.shape else 1


@dataclass
class _Recording:
    """A dSpace ControlDesk recording: its variable, X (time) and Y (signal) entries."""

    variable: str
    x: list[tuple[str, _Leaf]] = field(default_factory=list)
    y: list[tuple[str, _Leaf]] = field(default_factory=list)


def _quoted(names: list[str]) -> str:
    more = f", ... ({len(names)} in all)" if len(names) > _LISTED else ""
    return ", ".join(repr(n) for n in names[:_LISTED]) + more


class _StructSource(Source):
    """Resolve names (variables, field paths, dSpace signals) to leaves; check and read them."""

    def __init__(self, path: Path, leaves: dict[str, _Leaf], recordings: list[_Recording]):
        self.path = path
        self.leaves = leaves
        self.recordings = recordings
        self.signals: dict[str, _Leaf] = {}
        for rec in recordings:
            for name, leaf in rec.x + rec.y:
                self.signals.setdefault(name, leaf)
        self.what = "signal" if recordings else "MATLAB variable"
        self.columns = list(self.signals) + [k for k in leaves if k not in self.signals]

    def _short(self, name: str) -> list[str]:
        return [s for s in self.signals if s.rsplit("/", 1)[-1] == name]

    def resolve(self, name: str) -> str | None:
        """The file's name for ``name``, None when absent; raises when ambiguous."""
        if name in self.signals or name in self.leaves:
            return name
        short = self._short(name)
        if len(short) > 1:
            raise _ReadError(
                f"signal name {name!r} is ambiguous: it ends {_quoted(short)}; give the full "
                f"signal name under columns: in dataset.yaml",
                column=name,
            )
        if short:
            return short[0]
        xs = [n for rec in self.recordings for n, _ in rec.x]
        if name == "t" and len(xs) == 1:
            return xs[0]
        return None

    def describe(self, name: str) -> str:
        """What the file holds and the closest name to ``name``, for a 'missing' message."""
        top = [k for k in self.leaves if "." not in k]
        text = f"; the file holds the variables {_quoted(top)}"
        fields = [k for k in self.leaves if "." in k and self.leaves[k].kind in NUMERIC_CLASSES]
        if fields:
            text += f", the struct fields {_quoted(fields)}"
        if self.signals:
            text += f", the dSpace signals {_quoted(list(self.signals))}"
        shorts = [s.rsplit("/", 1)[-1] for s in self.signals]
        return text + _suggest(name, [*self.leaves, *self.signals, *shorts])

    def _leaf(self, name: str) -> _Leaf:
        key = self.resolve(name)
        assert key is not None
        return self.signals.get(key) or self.leaves[key]

    def check_types(self, names: list[str]) -> list[_ReadError]:
        errors = []
        lengths: dict[str, int] = {}
        for name in names:
            leaf = self._leaf(name)
            label = "signal" if self.resolve(name) in self.signals else "MATLAB variable"
            what = f"{label} {name!r}"
            if leaf.kind == "struct":
                paths = [f"{self.resolve(name)}.{f}" for f in leaf.fields]
                errors.append(
                    _ReadError(
                        f"{what} is a struct (fields {_quoted(list(leaf.fields))}); name one of "
                        f"its fields, e.g. {_quoted(paths[:1])}, under columns: in dataset.yaml",
                        column=name,
                    )
                )
            elif leaf.kind not in NUMERIC_CLASSES or leaf.read is None:
                errors.append(
                    _ReadError(
                        f"{what} holds {leaf.kind}, not numbers; expected a numeric vector "
                        "(double, single, integer or logical)",
                        column=name,
                    )
                )
            elif not leaf.is_vector:
                shape = "×".join(str(s) for s in leaf.shape)
                errors.append(
                    _ReadError(
                        f"{what} has shape {shape}; expected a vector (n×1 or 1×n)", column=name
                    )
                )
            else:
                lengths[name] = leaf.size
        if len(set(lengths.values())) > 1:
            sizes = ", ".join(f"{k}: {v}" for k, v in lengths.items())
            errors.append(
                _ReadError(f"{self.what}s have different lengths ({sizes}); expected one length")
            )
        return errors

    def chunks(self, names: list[str], as_text: bool = False) -> Iterator[_Chunk]:
        leaves = {n: self._leaf(n) for n in names}
        n = min((leaf.size for leaf in leaves.values()), default=0)
        for start in range(0, n, _BATCH_ROWS):
            stop = min(start + _BATCH_ROWS, n)
            values = {k: leaf.read(start, stop) for k, leaf in leaves.items() if leaf.read}
            yield start, values, {}
