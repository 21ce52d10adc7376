"""Staircase linearity of every staircase run of a dataset: Table 3, Figs. 6, 7a and 7b."""

import pandas as pd

from spa.io import get_logger, read_params, read_runs, write_csv
from spa.openloop import (
    fallback_note,
    noise_free_pressure,
    paper_settings,
    run_tags,
    runs_of_kind,
    staircase_analysis,
)
from spa.openloop.shapes import check_input_shape
from spa.plots.openloop import fig6, fig7a, fig7b, tau_outliers, thin, write_no_runs
from spa.plots.save import draw
from spa.status import naming_run, run_stage

log = get_logger("staircase", snakemake.log[0])


def main() -> None:
    out = snakemake.output
    runs, metas = read_runs(snakemake.input.runs)
    params = read_params(snakemake.input.params)
    ids = runs_of_kind(metas, "staircase")
    tags = run_tags(metas, ids)
    rows, levels, steps, traces = [], [], [], []
    for i, rid in enumerate(ids, 1):
        # simulated runs: the chattering of the true pressure, and of the sensor without noise
        check_input_shape(rid, "staircase", runs[rid]["u"])
        with naming_run(rid, "staircase"):
            clean = {
                name: noise_free_pressure(runs[rid], metas[rid], ringing=ringing)
                for name, ringing in (("noise_free", False), ("ringing", True))
            }
            lv, st, summary = staircase_analysis(
                runs[rid], metas[rid]["modulator"], params, **snakemake.params.cfg,
                clean={k: v for k, v in clean.items() if v is not None},
            )  # fmt: skip
        tag = {"run": rid, **tags.loc[rid]}
        rows.append({**summary, **tag})
        levels.append(lv.assign(**tag))
        steps.append(st.assign(**tag))
        traces.append(thin(runs[rid][["t", "p"]], 6000).assign(**tag))
        log.info(
            "[%d/%d] %s: FIT %.2f %%, MSE %.3g bar², tau %.3f ± %.3f s, ripple %.1f mbar "
            "(noise %.1f mbar subtracted: %.1f; noise-free %.1f)",
            i, len(ids), rid, summary["fit"], summary["mse"],
            summary["tau_mean"], summary["tau_sd"], 1e3 * summary["ripple_mean"],
            1e3 * summary["noise_sd"], 1e3 * summary["ripple_corrected_mean"],
            1e3 * summary.get("ripple_noise_free_mean", float("nan")),
        )  # fmt: skip

    if not ids:
        log.info("no staircase runs in this dataset: empty tables, placeholder figures")
        message = f"{snakemake.wildcards.dataset}: no staircase runs"
        tables = [out.table3, out.levels, out.time_constants, out.fig6_csv, out.fig7a_csv]
        figures = [out.get(key) for key in ("fig6", "fig7a", "fig7b")]
        write_no_runs(message, [*tables, out.fig7b_csv], figures)
    else:
        table3 = pd.DataFrame(rows)
        first = ["run", "modulator", "setting", "gain", "paper_case"]
        table3 = table3[first + [c for c in table3.columns if c not in first]]
        levels, steps = pd.concat(levels), pd.concat(steps)
        write_csv(table3, out.table3)
        write_csv(levels, out.levels)
        write_csv(steps, out.time_constants)
        traces = pd.concat(traces)
        write_csv(traces, out.fig6_csv)
        draw(out.get("fig6"), fig6, traces)
        shown, fallbacks = paper_settings(table3)
        note = fallback_note(fallbacks, "FIT")
        chosen = levels.merge(shown[["run", "fit"]], on="run")
        write_csv(chosen, out.fig7a_csv)
        draw(out.get("fig7a"), fig7a, chosen, params.k2, sweep=table3, note=note)
        steps["outlier"] = tau_outliers(steps["tau"])  # over all the dataset's steps
        chosen_steps = steps[steps["run"].isin(shown["run"])]
        write_csv(chosen_steps, out.fig7b_csv)
        counts = steps.groupby("setting")["outlier"].sum().rename("n_outliers")
        sweep = table3.join(counts, on="setting")
        draw(out.get("fig7b"), fig7b, chosen_steps, sweep=sweep, note=note)
        log.info("Figs. 7a/7b show %s", note)


run_stage(snakemake, "staircase", main, log)
