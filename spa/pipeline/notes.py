"""What a stage that worked says it left out: a part skipped (:class:`Skipped`) or runs of a
kind the dataset lacks (:class:`NoRuns`). A stage's work returns them among its warnings and
:func:`spa.pipeline.status.write_status` records them (``skipped``, ``no_runs``); the report
names them in place of the outputs concerned."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

__all__ = ["NoRuns", "Skipped"]


@dataclass(frozen=True)
class Skipped:
    """A stage's warning that names a part of its work left out on this dataset, and why.

    A stage's work returns it among its warnings (:func:`run_stage`) when a property of the
    valve or the data rules one part out (the sine stage's linear reference of a setting
    that cannot work on the valve) while the rest is done. The status records it under
    ``skipped`` (``part -> reason``) and, as text, among ``warnings``; the report names it
    on the page.

    Examples
    --------
    >>> str(Skipped("linear reference", "no setting gives a finite tau_m"))
    'linear reference skipped: no setting gives a finite tau_m'
    """

    part: str
    reason: str

    def __str__(self) -> str:
        return f"{self.part} skipped: {self.reason}"


@dataclass(frozen=True)
class NoRuns:
    """A stage's warning that the dataset has no runs of a kind it analyses: its outputs (or
    ``paths`` of them) are empty tables and figures that say so, and the report says "no
    runs" in their place, never "ok" over an empty table.

    ``paths`` are the outputs it concerns, relative to ``results/<dataset>``; empty: every
    output of the stage. The status records it under ``no_runs`` (:meth:`to_mapping`).

    Examples
    --------
    >>> str(NoRuns("staircase"))
    'no staircase runs in this dataset'
    >>> NoRuns("closed_loop", ("closed_loop/runs.csv",)).to_mapping()["paths"]
    ['closed_loop/runs.csv']
    """

    kind: str
    paths: tuple[str, ...] = ()

    def __str__(self) -> str:
        return f"no {self.kind} runs in this dataset"

    def to_mapping(self) -> dict[str, Any]:
        """``{"kind", "message", "paths"}`` for the status file."""
        return {"kind": self.kind, "message": str(self), "paths": list(self.paths)}
