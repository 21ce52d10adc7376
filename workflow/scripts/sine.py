"""Sine linearity of every sine run of a dataset: RMS deviation table and Fig. 8."""

import pandas as pd

from spa.io import get_logger, read_runs, save_figure, write_csv
from spa.openloop import run_tags, runs_of_kind, sine_analysis
from spa.plots.openloop import fig8, thin, write_no_runs
from spa.status import naming_run, run_stage

log = get_logger("sine", snakemake.log[0])


def main() -> None:
    cfg = snakemake.params.cfg
    runs, metas = read_runs(snakemake.input.runs)
    ids = runs_of_kind(metas, "sine")
    tags = run_tags(metas, ids)
    rows, curves = [], []
    for i, rid in enumerate(ids, 1):
        meta = metas[rid]
        settle = cfg["settle"]
        if settle is None:  # the hold before the sine, as recorded by the simulator
            settle = float((meta.get("experiment") or {}).get("settle", 0.0))
        with naming_run(rid, "sine"):
            aligned, summary = sine_analysis(runs[rid], settle=settle, max_lag=cfg["max_lag"])
        tag = {"run": rid, **tags.loc[rid]}
        rows.append({**tag, "settle": settle, **summary})
        curves.append(thin(aligned, 5000).assign(**tag, rms=summary["rms"]))
        log.info(
            "[%d/%d] %s: lag %.3f s, RMS %.4f", i, len(ids), rid, summary["lag"], summary["rms"]
        )

    if ids:
        write_csv(pd.DataFrame(rows), snakemake.output.table)
        save_figure(fig8(pd.concat(curves)), snakemake.output.fig8)
    else:
        log.info("no sine runs in this dataset: empty table, placeholder figure")
        message = f"{snakemake.wildcards.dataset}: no sine runs"
        write_no_runs(message, [snakemake.output.table], [snakemake.output.fig8])


run_stage(snakemake, "sine", main, log)
