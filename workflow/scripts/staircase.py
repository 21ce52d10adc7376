"""Staircase linearity of every staircase run of a dataset: Table 3, Figs. 6, 7a and 7b."""

import pandas as pd
import yaml

from spa.identification import load_params
from spa.io import get_logger, read_runs, save_figure, write_csv
from spa.openloop import best_settings, run_tags, runs_of_kind, staircase_analysis
from spa.plots.openloop import fig6, fig7a, fig7b, thin, write_no_runs
from spa.status import naming_run, run_stage

log = get_logger("staircase", snakemake.log[0])


def main() -> None:
    out = snakemake.output
    runs, metas = read_runs(snakemake.input.runs)
    with open(snakemake.input.params) as fh:
        params = load_params(yaml.safe_load(fh))
    ids = runs_of_kind(metas, "staircase")
    tags = run_tags(metas, ids)
    rows, levels, steps, traces = [], [], [], []
    for i, rid in enumerate(ids, 1):
        with naming_run(rid, "staircase"):
            lv, st, summary = staircase_analysis(
                runs[rid], metas[rid]["modulator"], params, **snakemake.params.cfg
            )
        tag = {"run": rid, **tags.loc[rid]}
        rows.append({**summary, **tag})
        levels.append(lv.assign(**tag))
        steps.append(st.assign(**tag))
        traces.append(thin(runs[rid][["t", "p"]], 6000).assign(**tag))
        log.info(
            "[%d/%d] %s: FIT %.2f %%, MSE %.3g bar², tau %.3f ± %.3f s",
            i, len(ids), rid, summary["fit"], summary["mse"],
            summary["tau_mean"], summary["tau_sd"],
        )  # fmt: skip

    if not ids:
        log.info("no staircase runs in this dataset: empty tables, placeholder figures")
        message = f"{snakemake.wildcards.dataset}: no staircase runs"
        write_no_runs(
            message, [out.table3, out.levels, out.time_constants], [out.fig6, out.fig7a, out.fig7b]
        )
    else:
        table3 = pd.DataFrame(rows)
        first = ["run", "modulator", "setting", "gain", "paper_case"]
        table3 = table3[first + [c for c in table3.columns if c not in first]]
        levels, steps = pd.concat(levels), pd.concat(steps)
        write_csv(table3, out.table3)
        write_csv(levels, out.levels)
        write_csv(steps, out.time_constants)
        save_figure(fig6(pd.concat(traces)), out.fig6)
        best = best_settings(table3)
        chosen = levels.merge(best[["run", "fit"]], on="run")
        save_figure(fig7a(chosen, params.k2), out.fig7a)
        save_figure(fig7b(steps[steps["run"].isin(best["run"])]), out.fig7b)
        log.info("best settings (Fig. 7): %s", ", ".join(best["setting"]))


run_stage(snakemake, "staircase", main, log)
