"""What the open-loop stages (:mod:`spa.stages.staircase`, :mod:`~spa.stages.sine`,
:mod:`~spa.stages.chirp`) share: their inputs and the runs of their kind, the warnings of the
parts they skip, the outputs of a dataset without runs of their kind, and the linear
reference's skip."""

from __future__ import annotations

import logging
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import pandas as pd

from spa.model.params import ValveParams
from spa.openloop.reference import REFERENCE, SKIPPED_PART, reference_skip_reason
from spa.openloop.selection import run_tags, runs_of_kind
from spa.openloop.shapes import check_input_shape
from spa.pipeline.status import Skipped
from spa.plots.openloop import write_no_runs

__all__ = ["OpenLoopInputs"]


@dataclass(frozen=True)
class OpenLoopInputs:
    """What an open-loop stage reads: a dataset's runs, its identified valve, its settings.

    Attributes
    ----------
    runs, metas : mapping
        Run id to canonical run table and to its metadata (:func:`spa.datasets.read_runs`).
    params : ValveParams
        The dataset's identified valve (the model's lines, the linear reference's time
        constant).
    cfg : mapping
        The stage's section of the config (``linearity.<stage>``).
    """

    runs: Mapping[str, pd.DataFrame]
    metas: Mapping[str, Mapping[str, Any]]
    params: ValveParams
    cfg: Mapping[str, Any]

    def runs_of(self, kind: str) -> tuple[list[str], pd.DataFrame]:
        """The ids of the runs of ``kind`` in the order of their settings
        (:func:`spa.openloop.runs_of_kind`) and their tags (:func:`spa.openloop.run_tags`).

        Raises
        ------
        spa.errors.RunError
            Naming the first run whose input is not of ``kind``'s shape
            (:func:`spa.openloop.shapes.check_input_shape`), before any run is analysed.
        """
        ids = runs_of_kind(self.metas, kind)
        for rid in ids:
            check_input_shape(rid, kind, self.runs[rid]["u"])
        return ids, run_tags(self.metas, ids)


class SkippedParts:
    """Mixin of a stage result with a ``skipped`` mapping, part -> reason."""

    skipped: dict[str, str]

    @property
    def warnings(self) -> list[Skipped]:
        """What the stage's status records: one :class:`~spa.pipeline.status.Skipped` a part."""
        return [Skipped(part, why) for part, why in self.skipped.items()]


def write_placeholders(
    out: Any,
    dataset: str,
    kind: str,
    tables: Sequence[str],
    figures: Sequence[str],
    log: logging.Logger,
) -> None:
    """Write the outputs ``tables`` and ``figures`` (keys of ``out``) of a dataset without
    ``kind`` runs: empty tables and figures that say so, and log it."""
    s = "s" if len(figures) > 1 else ""
    log.info("no %s runs in this dataset: empty table%s, placeholder figure%s", kind, s, s)
    write_no_runs(
        f"{dataset}: no {kind} runs",
        [out.get(key) for key in tables],
        [out.get(key) for key in figures],
    )


def skipped_reference(
    metas: Mapping[str, Mapping[str, Any]],
    ids: Sequence[str],
    params: ValveParams,
    log: logging.Logger,
) -> tuple[list[Any], str, dict[str, str]]:
    """The runs' modulators, why the linear reference is left out on this valve ("" when it
    is not; then logged) and its table row's tags."""
    mods = [metas[r]["modulator"] for r in ids]
    why = reference_skip_reason(mods, params)
    if why:  # the runs as recorded; the model-based reference left out by name
        log.warning("%s skipped: %s", SKIPPED_PART, why)
    return mods, why, {"run": REFERENCE, "modulator": REFERENCE, "setting": REFERENCE}
