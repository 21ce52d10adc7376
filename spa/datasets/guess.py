"""One guess of ``spa init`` and its reason (:mod:`spa.datasets.draft`)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

__all__ = ["Guess"]


@dataclass(frozen=True, slots=True)
class Guess:
    """One guess and why.

    Attributes
    ----------
    value : Any
        The guess (a column name, unit, kind or modulator mapping), or None if undecided.
    reason : str
        Why this value, or why none could be given (one line, for a YAML comment).
    """

    value: Any
    reason: str

    @property
    def decided(self) -> bool:
        """True when a value was guessed."""
        return self.value is not None
