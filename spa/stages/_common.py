"""What the open-loop stages (:mod:`spa.stages.staircase`, :mod:`~spa.stages.sine`,
:mod:`~spa.stages.chirp`) share: the warnings of the parts they skip, the outputs of a
dataset without runs of their kind, and the linear reference's skip."""

from __future__ import annotations

import logging
from collections.abc import Mapping, Sequence
from typing import Any

from spa.model.params import ValveParams
from spa.openloop.reference import REFERENCE, SKIPPED_PART, reference_skip_reason
from spa.pipeline.status import Skipped
from spa.plots.openloop import write_no_runs

__all__: list[str] = []


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
