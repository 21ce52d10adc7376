"""Problems found in a dataset, the error that carries them, and the suggestions in their
messages."""

from __future__ import annotations

import difflib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

# --------------------------------------------------------------------------- problems


@dataclass(frozen=True, slots=True)
class Problem:
    """One thing wrong with a dataset, located as precisely as possible.

    Parameters
    ----------
    file : str or None
        File the problem is in, relative to the dataset folder (``"dataset.yaml"`` for the
        description), or None for the folder itself.
    run : str or None
        Run id, when the problem belongs to one run.
    column : str or None
        Column (or MATLAB variable) name as written in the file.
    row : int or None
        Data row, counted from 1 at the first row after the header: the first row where the
        problem shows (the message counts the others).
    message : str
        What is wrong and what was expected.
    key : str or None
        Location inside ``dataset.yaml``, such as ``runs[2].kind``.
    line : int or None
        Line of a CSV file (the header is line 1), when known.
    level : {"error", "warning"}
        Warnings are reported but do not make a dataset invalid.
    """

    file: str | None
    run: str | None
    column: str | None
    row: int | None
    message: str
    key: str | None = None
    line: int | None = None
    level: str = "error"

    def __str__(self) -> str:
        where = self.file or "dataset folder"
        if self.key:
            where += f": {self.key}"
        details = []
        if self.run is not None:
            details.append(f"run {self.run!r}")
        if self.column is not None:
            details.append(f"column {self.column!r}")
        if self.row is not None:
            details.append(f"row {self.row}" + (f" (line {self.line})" if self.line else ""))
        elif self.line is not None:
            details.append(f"line {self.line}")
        if details:
            where += f" [{', '.join(details)}]"
        return f"{self.level}: {where}: {self.message}"

    @property
    def is_error(self) -> bool:
        """True for an error, False for a warning."""
        return self.level == "error"


class DatasetError(ValueError):
    """Raised when a dataset breaks the contract; ``problems`` lists every problem found."""

    def __init__(self, folder: str | Path, problems: list[Problem]) -> None:
        self.folder = Path(folder)
        self.problems = list(problems)
        n = sum(p.is_error for p in self.problems)
        lines = "\n  ".join(str(p) for p in self.problems)
        super().__init__(f"{folder}: {n} error(s) in dataset (see raw/README.md):\n  {lines}")


def _suggest(word: Any, choices: Any) -> str:
    """Return ``" (did you mean 'x'?)"`` for the closest of ``choices``, or ``""``."""
    options = [str(c) for c in choices]
    text = str(word)
    for c in options:
        if c.lower() == text.lower():
            return f" (did you mean {c!r}?)"
    close = difflib.get_close_matches(text, options, n=1, cutoff=0.6)
    return f" (did you mean {close[0]!r}?)" if close else ""


def _unknown_key(key: Any, allowed: Any) -> str:
    return f"unknown key {key!r}{_suggest(key, allowed)}; allowed keys: {_one_of(allowed)}"


def _is_one_of(value: Any, choices: Any) -> bool:
    """``value in choices`` for string choices, False for any other (even unhashable) value."""
    return isinstance(value, str) and value in choices


def _one_of(choices: Any) -> str:
    return ", ".join(str(c) for c in choices)
