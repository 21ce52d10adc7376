"""Bicoherence of the response to every chirp run of a dataset: table and Fig. 9."""

import pandas as pd

from spa.io import get_logger, read_runs, save_figure, write_csv
from spa.openloop import best_settings, chirp_analysis, run_tags, runs_of_kind
from spa.plots.openloop import fig9, write_no_runs
from spa.status import naming_run, run_stage

log = get_logger("chirp", snakemake.log[0])


def main() -> None:
    runs, metas = read_runs(snakemake.input.runs)
    ids = runs_of_kind(metas, "chirp")
    tags = run_tags(metas, ids)
    rows, maps = [], {}
    for i, rid in enumerate(ids, 1):
        with naming_run(rid, "chirp"):
            f, bic, summary = chirp_analysis(runs[rid], **snakemake.params.cfg)
        rows.append({"run": rid, **tags.loc[rid], **summary})
        maps[rid] = (f, bic)
        log.info("[%d/%d] %s: mean bicoherence %.4f", i, len(ids), rid, summary["mean_bicoherence"])

    if ids:
        table = pd.DataFrame(rows)
        write_csv(table, snakemake.output.table)
        best = best_settings(table, score="mean_bicoherence", higher=False)
        panels = [
            (f"{r.setting}: mean {r.mean_bicoherence:.3f}", *maps[r.run]) for r in best.itertuples()
        ]
        save_figure(fig9(panels), snakemake.output.fig9)
    else:
        log.info("no chirp runs in this dataset: empty table, placeholder figure")
        message = f"{snakemake.wildcards.dataset}: no chirp runs"
        write_no_runs(message, [snakemake.output.table], [snakemake.output.fig9])


run_stage(snakemake, "chirp", main, log)
