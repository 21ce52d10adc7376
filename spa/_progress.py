"""Progress bars on long loops (runs simulated or replayed, modulator sweeps), for people only.

:func:`progress` wraps an iterable in a ``tqdm`` bar on standard error when that is a
terminal, and returns it unchanged otherwise: in a log file, a pipe, CI or a workflow job
(Snakemake runs jobs with the terminal's standard error, where bars of parallel jobs would
interleave) nothing is printed. ``SPA_PROGRESS=0`` turns the bars off, ``SPA_PROGRESS=1`` on
even without a terminal.

>>> list(progress(range(3), "runs"))  # standard error is no terminal under pytest
[0, 1, 2]
"""

from __future__ import annotations

import os
import sys
from collections.abc import Iterable, Iterator
from typing import TypeVar

__all__ = ["progress", "progress_enabled"]

T = TypeVar("T")


def progress_enabled() -> bool:
    """True when a progress bar would be shown (see the module's docstring)."""
    setting = os.environ.get("SPA_PROGRESS", "").strip().lower()
    if setting in ("0", "false", "no", "off"):
        return False
    if setting in ("1", "true", "yes", "on"):
        return True
    job = getattr(sys.modules.get("__main__"), "snakemake", None)
    if type(job).__module__.startswith("snakemake"):
        return False  # a workflow job (its script's `snakemake` object): messages go to its log
    stream = sys.stderr
    return bool(stream is not None and hasattr(stream, "isatty") and stream.isatty())


def progress(
    iterable: Iterable[T], desc: str, total: int | None = None, unit: str = "run"
) -> Iterable[T] | Iterator[T]:
    """``iterable``, with a progress bar on standard error when it is a terminal.

    Parameters
    ----------
    iterable : iterable
        What the loop goes over.
    desc : str
        What the loop does, printed before the bar (``"simulating sim"``).
    total : int, optional
        Its length, when ``len(iterable)`` does not give it.
    unit : str
        What one item is (``"run"``, ``"modulator"``).

    Returns
    -------
    iterable
        ``iterable`` itself when no bar is shown; otherwise a ``tqdm`` iterator over it that
        leaves no bar behind when done.
    """
    if not progress_enabled():
        return iterable
    from tqdm import tqdm

    return tqdm(iterable, desc=desc, total=total, unit=unit, leave=False, file=sys.stderr)
