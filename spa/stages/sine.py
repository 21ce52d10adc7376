"""The sine stage: every sine run of a dataset against its fitted sine and the linear
reference (paper Section 6.2, Fig. 8), then the files."""

from __future__ import annotations

import logging
from dataclasses import dataclass, field
from typing import Any

import pandas as pd

from spa._docs import fill_doc
from spa.io import write_csv
from spa.openloop import frequency_note, sine_analysis, sine_reference
from spa.openloop.reference import REFERENCE, SKIPPED_PART
from spa.pipeline.status import naming_run
from spa.plots.openloop import fig8, thin
from spa.plots.save import draw
from spa.stages._common import OpenLoopInputs, SkippedParts, skipped_reference, write_placeholders

__all__ = ["SineResult", "run_sine", "write_sine"]

_LOG = logging.getLogger("spa.stages.sine")


@dataclass(frozen=True)
class SineResult(SkippedParts):
    """What the sine stage found (empty tables without sine runs).

    Attributes
    ----------
    table : pandas.DataFrame
        One row per run (tags, ``settle``, frequency, lag, RMS, ...) and, last, the linear
        reference's row.
    curves : pandas.DataFrame
        Each run's aligned response, thinned for Fig. 8.
    reference : pandas.DataFrame
        The linear reference's aligned response, thinned.
    note : str
        Fig. 8's note on the frequency (:func:`spa.openloop.frequency_note`).
    skipped : dict
        The model-based parts left out on this valve, part -> reason: the linear reference
        (:data:`~spa.openloop.reference.SKIPPED_PART`) when no setting of the runs gives
        Eq. 9's ``tau_m`` (:func:`~spa.openloop.reference.reference_skip_reason`). Its table
        row then holds only its tags and the reason (column ``skipped``), ``reference`` is
        empty, and the runs are analysed as recorded all the same.
    """

    table: pd.DataFrame
    curves: pd.DataFrame
    reference: pd.DataFrame
    note: str
    skipped: dict[str, str] = field(default_factory=dict)

    @property
    def empty(self) -> bool:
        """True when the dataset has no sine run."""
        return self.table.empty


def run_sine(inputs: OpenLoopInputs, log: logging.Logger | None = None) -> SineResult:
    """Analyse every sine run of a dataset and the same input through the linear reference.

    Parameters
    ----------
    inputs : OpenLoopInputs
        The dataset's runs and valve; its ``cfg`` the config's ``linearity.sine`` section:
        ``settle`` (s, or None: the hold the simulator recorded before the sine) and
        ``max_lag`` (s, or None: half a period).
    log : logging.Logger, optional
        Where each run's summary is logged.

    Returns
    -------
    SineResult

    Raises
    ------
    spa.errors.RunError
        Naming the run whose input is not a sine or whose analysis failed.
    """
    log = log or _LOG
    runs, metas, params, cfg = inputs.runs, inputs.metas, inputs.params, inputs.cfg
    ids, tags = inputs.runs_of("sine")
    rows, curves, settles = [], [], {}
    for i, rid in enumerate(ids, 1):
        settle = cfg["settle"]
        if settle is None:  # the hold before the sine, as recorded by the simulator
            settle = float((metas[rid].get("experiment") or {}).get("settle", 0.0))
        settles[rid] = settle
        with naming_run(rid, "sine"):
            aligned, summary = sine_analysis(runs[rid], settle=settle, max_lag=cfg["max_lag"])
        tag = {"run": rid, **tags.loc[rid]}
        rows.append({**tag, "settle": settle, **summary})
        curves.append(thin(aligned, 5000).assign(**tag, rms=summary["rms"]))
        log.info(
            "[%d/%d] %s: %.3g Hz, lag %.3f s, RMS %.4f",
            i, len(ids), rid, summary["frequency"], summary["lag"], summary["rms"],
        )  # fmt: skip
    if not ids:
        return SineResult(pd.DataFrame(), pd.DataFrame(), pd.DataFrame(), "")
    mods, why, ref_tags = skipped_reference(metas, ids, params, log)
    if why:
        rows.append({**ref_tags, "settle": settles[ids[0]], "skipped": f"{SKIPPED_PART}: {why}"})
        note = f"sine at {float(rows[0]['frequency']):.3g} Hz; {SKIPPED_PART} skipped: {why}"
        return SineResult(
            pd.DataFrame(rows), pd.concat(curves), pd.DataFrame(), note, {SKIPPED_PART: why}
        )
    # The same input (the first run's) through the linear first-order reference.
    aligned, ref = sine_reference(
        runs[ids[0]], params, mods, settle=settles[ids[0]], max_lag=cfg["max_lag"]
    )
    rows.append({**ref, "settle": settles[ids[0]]})
    log.info("linear reference: tau_m %.3f s, RMS %.4f", ref["tau_m"], ref["rms"])
    reference = thin(aligned, 5000).assign(rms=ref["rms"])
    return SineResult(pd.DataFrame(rows), pd.concat(curves), reference, frequency_note(ref))


@fill_doc
def write_sine(
    result: SineResult, out: Any, dataset: str, log: logging.Logger | None = None
) -> None:
    """Write the sine table and Fig. 8 (its data and, where drawn, the figure): the
    outputs ``table``, ``fig8_csv`` and ``fig8`` of :func:`run_sine`'s result.

    %(write_figure_stage)s
    """
    if result.empty:
        write_placeholders(out, dataset, "sine", ["table", "fig8_csv"], ["fig8"], log or _LOG)
        return
    write_csv(result.table, out.get("table"))
    reference = None if result.reference.empty else result.reference
    ref_rows = (
        [] if reference is None else [reference.assign(modulator=REFERENCE, setting=REFERENCE)]
    )
    write_csv(pd.concat([result.curves, *ref_rows], ignore_index=True), out.get("fig8_csv"))
    draw(out.get("fig8"), fig8, result.curves, reference=reference, note=result.note)
