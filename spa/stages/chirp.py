"""The chirp stage: the bicoherence of the response to every chirp run of a dataset and of
the linear reference (paper Section 6.3, Fig. 9), then the files."""

from __future__ import annotations

import logging
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pandas as pd

from spa._docs import fill_doc
from spa.io import write_csv
from spa.openloop import (
    beyond_paper,
    chirp_analysis,
    chirp_reference,
    fallback_note,
    is_simulated,
    no_ringing_spread,
    noise_spread,
    paper_settings,
)
from spa.openloop.reference import SKIPPED_PART
from spa.pipeline.status import naming_run
from spa.plots.openloop import fig9, fig9_data
from spa.plots.save import draw
from spa.stages._common import OpenLoopInputs, SkippedParts, skipped_reference, write_placeholders

__all__ = ["ChirpResult", "run_chirp", "write_chirp"]

_LOG = logging.getLogger("spa.stages.chirp")

#: One bicoherence map: (setting, frequencies, bicoherence, threshold, lowest frequency).
Map = tuple[str, np.ndarray, np.ndarray, float, float]


@dataclass(frozen=True)
class ChirpResult(SkippedParts):
    """What the chirp stage found (empty without chirp runs).

    Attributes
    ----------
    table : pandas.DataFrame
        One row per run (tags, significant fraction with its spread over noise seeds, with
        and without the sensor's ringing, mean bicoherence, ...) and, last, the linear
        reference's row.
    maps : list of Map
        The maps Fig. 9 shows: the paper's settings (or fallbacks), then the reference.
    shown : list of str
        Their settings, the reference left out.
    titles : list of str
        Each map's panel title.
    note : str
        Fig. 9's note (normalisation, segments, threshold, settings shown).
    skipped : dict
        The model-based parts left out on this valve, part -> reason: the linear reference
        when no setting of the runs gives Eq. 9's ``tau_m``
        (:func:`~spa.openloop.reference.reference_skip_reason`). Its table row then holds
        only its tags and the reason (column ``skipped``) and no map of it is shown; the
        runs' bicoherence needs no model and is computed all the same.
    """

    table: pd.DataFrame
    maps: list[Map] = field(default_factory=list)
    shown: list[str] = field(default_factory=list)
    titles: list[str] = field(default_factory=list)
    note: str = ""
    skipped: dict[str, str] = field(default_factory=dict)

    @property
    def empty(self) -> bool:
        """True when the dataset has no chirp run."""
        return self.table.empty


def _title(row: Mapping[str, Any]) -> str:
    """A map's title: its setting and the fraction of its domain that is significant."""
    return f"{row['setting']}: {row['significant_fraction']:.1%} significant"


def run_chirp(inputs: OpenLoopInputs, log: logging.Logger | None = None) -> ChirpResult:
    """Bicoherence of every chirp run of a dataset and of the linear reference.

    Parameters
    ----------
    inputs : OpenLoopInputs
        The dataset's runs and valve; its ``cfg`` the config's ``linearity.chirp`` section:
        ``seeds`` (sensor-noise realisations of a simulated run) and
        :func:`spa.openloop.chirp_analysis`'s keywords.
    log : logging.Logger, optional
        Where each run's summary is logged.

    Returns
    -------
    ChirpResult

    Raises
    ------
    spa.errors.RunError
        Naming the run whose input is not a chirp or whose analysis failed.
    """
    log = log or _LOG
    runs, metas, params = inputs.runs, inputs.metas, inputs.params
    cfg = dict(inputs.cfg)
    seeds = cfg.pop("seeds")
    ids, tags = inputs.runs_of("chirp")
    rows, maps = [], {}
    for i, rid in enumerate(ids, 1):
        with naming_run(rid, "chirp"):
            f, bic, summary = chirp_analysis(runs[rid], **cfg)
            if is_simulated(metas[rid]) and seeds > 1:  # the spread over sensor-noise seeds
                summary.update(noise_spread(metas[rid], summary, seeds, **cfg))
                summary.update(no_ringing_spread(metas[rid], seeds, **cfg))
        rows.append({"run": rid, **tags.loc[rid], **summary})
        maps[rid] = (f, bic, summary["threshold"], summary["fmin"])
        log.info(
            "[%d/%d] %s: significant fraction %.4f (seeds %.4f-%.4f), mean bicoherence %.4f",
            i, len(ids), rid, summary["significant_fraction"],
            summary.get("significant_fraction_min", float("nan")),
            summary.get("significant_fraction_max", float("nan")), summary["mean_bicoherence"],
        )  # fmt: skip
    if not ids:
        return ChirpResult(pd.DataFrame())
    first = ids[0]  # through its sensor (ringing after its edges, its noise) if simulated
    mods, why, ref_tags = skipped_reference(metas, ids, params, log)
    if why:
        ref = {**ref_tags, "skipped": f"{SKIPPED_PART}: {why}"}
        basis = rows[0]  # the runs' own segments and threshold
    else:
        # The same input (the first run's) through the linear first-order reference.
        f, bic, ref = chirp_reference(runs[first], params, mods, metas[first], seeds, **cfg)
        log.info("linear reference: tau_m %.3f s, significant fraction %.4f",
                 ref["tau_m"], ref["significant_fraction"])  # fmt: skip
        basis = ref
    table = pd.DataFrame([*rows, ref])
    bounded = cfg["normalisation"] == "bounded"
    score = "significant_fraction" if bounded else "mean_bicoherence"
    shown, fallbacks = paper_settings(table.iloc[:-1], score=score, higher=False)
    named: list[Map] = [(r["setting"], *maps[r["run"]]) for _, r in shown.iterrows()]
    titles = [_title(r) for _, r in shown.iterrows()]
    if not why:
        named.append((ref["setting"], f, bic, ref["threshold"], ref["fmin"]))
        titles.append(_title(ref))
    note = (
        f"{cfg['normalisation']} bicoherence, {basis['n_segments']} segments, bins above "
        f"{basis['threshold']:.3f} (α = {cfg['alpha']}) coloured; "
        + fallback_note(fallbacks, score, higher=False, beyond=beyond_paper(shown))
        + (f"; {SKIPPED_PART} skipped: {why}" if why else "")
    )
    skipped = {SKIPPED_PART: why} if why else {}
    return ChirpResult(table, named, list(shown["setting"]), titles, note, skipped)


@fill_doc
def write_chirp(
    result: ChirpResult, out: Any, dataset: str, log: logging.Logger | None = None
) -> None:
    """Write the chirp table and Fig. 9 (its data and, where drawn, the figure): the
    outputs ``table``, ``fig9_csv`` and ``fig9`` of :func:`run_chirp`'s result.

    %(write_figure_stage)s
    """
    if result.empty:
        write_placeholders(out, dataset, "chirp", ["table", "fig9_csv"], ["fig9"], log or _LOG)
        return
    write_csv(result.table, out.get("table"))
    write_csv(fig9_data(result.maps), out.get("fig9_csv"))
    panels = [(title, *rest) for title, (_, *rest) in zip(result.titles, result.maps, strict=True)]
    draw(out.get("fig9"), fig9, panels, sweep=result.table, shown=result.shown, note=result.note)
