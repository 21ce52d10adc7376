"""The staircase stage: Table 3 and the data of Figs. 6, 7a and 7b for every staircase run of
a dataset (paper Section 6.1), then the files."""

from __future__ import annotations

import logging
from dataclasses import dataclass
from typing import Any

import pandas as pd

from spa.io import write_csv
from spa.openloop import (
    beyond_paper,
    fallback_note,
    noise_free_pressure,
    paper_settings,
    staircase_analysis,
)
from spa.pipeline.status import naming_run
from spa.plots.openloop import fig6, fig7a, fig7b, tau_outliers
from spa.plots.save import draw
from spa.stages._common import OpenLoopInputs, write_placeholders

__all__ = ["StaircaseResult", "run_staircase", "write_staircase"]

_LOG = logging.getLogger("spa.stages.staircase")


@dataclass(frozen=True)
class StaircaseResult:
    """What the staircase stage found in a dataset's staircase runs (all empty without any).

    Attributes
    ----------
    table3 : pandas.DataFrame
        One row per run: its tags (``run``, ``modulator``, ``setting``, ``gain``,
        ``paper_case``), FIT, MSE, MD, MAD, time constants, ripple (Table 3).
    levels, steps : pandas.DataFrame
        Per run and level (equilibrium, ripple, switching rate) and per step (time constant).
    traces : pandas.DataFrame
        Pressure traces of Fig. 6, every sample (the figure reduces its drawing).
    fig7a, fig7b : pandas.DataFrame
        The levels and steps of the settings Figs. 7a and 7b show (the paper's, or fallbacks).
    sweep : pandas.DataFrame
        Table 3 with each setting's number of time-constant outliers (Fig. 7b's sweep panel).
    note : str
        Which settings the figures show (:func:`spa.openloop.fallback_note`).
    k2 : float
        The valve's ``k2`` (bar), Fig. 7a's reference line.
    """

    table3: pd.DataFrame
    levels: pd.DataFrame
    steps: pd.DataFrame
    traces: pd.DataFrame
    fig7a: pd.DataFrame
    fig7b: pd.DataFrame
    sweep: pd.DataFrame
    note: str
    k2: float

    @property
    def empty(self) -> bool:
        """True when the dataset has no staircase run."""
        return self.table3.empty


def run_staircase(inputs: OpenLoopInputs, log: logging.Logger | None = None) -> StaircaseResult:
    """Analyse every staircase run of a dataset.

    Parameters
    ----------
    inputs : OpenLoopInputs
        The dataset's runs and valve (the model's lines and time constants); its ``cfg`` the
        config's ``linearity.staircase`` section (:func:`spa.openloop.staircase_analysis`'s
        keywords).
    log : logging.Logger, optional
        Where each run's summary is logged.

    Returns
    -------
    StaircaseResult

    Raises
    ------
    spa.errors.RunError
        Naming the run whose input is not a staircase or whose analysis failed.
    """
    log = log or _LOG
    runs, metas, params, cfg = inputs.runs, inputs.metas, inputs.params, inputs.cfg
    ids, tags = inputs.runs_of("staircase")
    rows, levels, steps, traces = [], [], [], []
    for i, rid in enumerate(ids, 1):
        # simulated runs: the chattering of the true pressure, and of the sensor without noise
        with naming_run(rid, "staircase"):
            clean = {
                name: noise_free_pressure(runs[rid], metas[rid], ringing=ringing)
                for name, ringing in (("noise_free", False), ("ringing", True))
            }
            lv, st, summary = staircase_analysis(
                runs[rid], metas[rid]["modulator"], params, **cfg,
                clean={k: v for k, v in clean.items() if v is not None},
            )  # fmt: skip
        tag = {"run": rid, **tags.loc[rid]}
        rows.append({**summary, **tag})
        levels.append(lv.assign(**tag))
        steps.append(st.assign(**tag))
        traces.append(runs[rid][["t", "p"]].assign(**tag))  # whole: Fig. 6 reduces its drawing
        log.info(
            "[%d/%d] %s: FIT %.2f %%, MSE %.3g bar², tau %.3f ± %.3f s, ripple %.1f mbar "
            "(noise %.1f mbar subtracted: %.1f; noise-free %.1f)",
            i, len(ids), rid, summary["fit"], summary["mse"],
            summary["tau_mean"], summary["tau_sd"], 1e3 * summary["ripple_mean"],
            1e3 * summary["noise_sd"], 1e3 * summary["ripple_corrected_mean"],
            1e3 * summary.get("ripple_noise_free_mean", float("nan")),
        )  # fmt: skip
    if not ids:
        empty = pd.DataFrame()
        return StaircaseResult(empty, empty, empty, empty, empty, empty, empty, "", params.k2)
    table3 = pd.DataFrame(rows)
    first = ["run", "modulator", "setting", "gain", "paper_case"]
    table3 = table3[first + [c for c in table3.columns if c not in first]]
    all_levels, all_steps = pd.concat(levels), pd.concat(steps)
    shown, fallbacks = paper_settings(table3)
    chosen = all_levels.merge(shown[["run", "fit"]], on="run")
    all_steps["outlier"] = tau_outliers(all_steps["tau"])  # over all the dataset's steps
    chosen_steps = all_steps[all_steps["run"].isin(shown["run"])]
    counts = all_steps.groupby("setting")["outlier"].sum().rename("n_outliers")
    return StaircaseResult(
        table3=table3,
        levels=all_levels,
        steps=all_steps,
        traces=pd.concat(traces),
        fig7a=chosen,
        fig7b=chosen_steps,
        sweep=table3.join(counts, on="setting"),
        note=fallback_note(fallbacks, "FIT", beyond=beyond_paper(shown)),
        k2=params.k2,
    )


def write_staircase(
    result: StaircaseResult, out: Any, dataset: str, log: logging.Logger | None = None
) -> None:
    """Write the staircase stage's tables and draw its figures.

    Parameters
    ----------
    result : StaircaseResult
        :func:`run_staircase`'s.
    out : mapping-like
        Output key to path (``snakemake.output``, or a dict): ``table3``, ``levels``,
        ``time_constants``, ``fig6_csv``, ``fig7a_csv``, ``fig7b_csv``, and the figures
        ``fig6``, ``fig7a``, ``fig7b`` where they are drawn (absent: not drawn).
    dataset : str
        The dataset's name, for the placeholder figures of a dataset without staircase runs.
    log : logging.Logger, optional
        Where to say what the figures show.
    """
    log = log or _LOG
    if result.empty:
        tables = ["table3", "levels", "time_constants", "fig6_csv", "fig7a_csv", "fig7b_csv"]
        write_placeholders(out, dataset, "staircase", tables, ["fig6", "fig7a", "fig7b"], log)
        return
    write_csv(result.table3, out.get("table3"))
    write_csv(result.levels, out.get("levels"))
    # time_constants.csv: the steps as analysed, before the outlier flag of Fig. 7b
    write_csv(result.steps.drop(columns="outlier"), out.get("time_constants"))
    write_csv(result.traces, out.get("fig6_csv"))
    draw(out.get("fig6"), fig6, result.traces)
    write_csv(result.fig7a, out.get("fig7a_csv"))
    draw(out.get("fig7a"), fig7a, result.fig7a, result.k2, sweep=result.table3, note=result.note)
    write_csv(result.fig7b, out.get("fig7b_csv"))
    draw(out.get("fig7b"), fig7b, result.fig7b, sweep=result.sweep, note=result.note)
    log.info("Figs. 7a/7b show %s", result.note)
