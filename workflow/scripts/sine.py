"""Sine linearity of every sine run of a dataset and of the linear reference: table and Fig. 8."""

import pandas as pd

from spa.io import get_logger, read_params, read_runs, write_csv
from spa.openloop import frequency_note, run_tags, runs_of_kind, sine_analysis, sine_reference
from spa.openloop.reference import REFERENCE
from spa.openloop.shapes import check_input_shape
from spa.plots.openloop import fig8, thin, write_no_runs
from spa.plots.save import draw
from spa.status import naming_run, run_stage

log = get_logger("sine", snakemake.log[0])


def main() -> None:
    cfg = snakemake.params.cfg
    runs, metas = read_runs(snakemake.input.runs)
    ids = runs_of_kind(metas, "sine")
    tags = run_tags(metas, ids)
    rows, curves, settles = [], [], {}
    for i, rid in enumerate(ids, 1):
        settle = cfg["settle"]
        if settle is None:  # the hold before the sine, as recorded by the simulator
            settle = float((metas[rid].get("experiment") or {}).get("settle", 0.0))
        settles[rid] = settle
        check_input_shape(rid, "sine", runs[rid]["u"])
        with naming_run(rid, "sine"):
            aligned, summary = sine_analysis(runs[rid], settle=settle, max_lag=cfg["max_lag"])
        tag = {"run": rid, **tags.loc[rid]}
        rows.append({**tag, "settle": settle, **summary})
        curves.append(thin(aligned, 5000).assign(**tag, rms=summary["rms"]))
        log.info(
            "[%d/%d] %s: %.3g Hz, lag %.3f s, RMS %.4f",
            i, len(ids), rid, summary["frequency"], summary["lag"], summary["rms"],
        )  # fmt: skip

    if ids:
        # The same input (the first run's) through the linear first-order reference.
        params = read_params(snakemake.input.params)
        aligned, ref = sine_reference(
            runs[ids[0]], params, [metas[r]["modulator"] for r in ids],
            settle=settles[ids[0]], max_lag=cfg["max_lag"],
        )  # fmt: skip
        rows.append({**ref, "settle": settles[ids[0]]})
        log.info("linear reference: tau_m %.3f s, RMS %.4f", ref["tau_m"], ref["rms"])
        write_csv(pd.DataFrame(rows), snakemake.output.table)
        reference = thin(aligned, 5000).assign(rms=ref["rms"])
        curves = pd.concat(curves)
        ref_rows = reference.assign(modulator=REFERENCE, setting=REFERENCE)
        write_csv(pd.concat([curves, ref_rows], ignore_index=True), snakemake.output.fig8_csv)
        note = frequency_note(ref)
        draw(snakemake.output.get("fig8"), fig8, curves, reference=reference, note=note)
    else:
        log.info("no sine runs in this dataset: empty table, placeholder figure")
        message = f"{snakemake.wildcards.dataset}: no sine runs"
        tables = [snakemake.output.table, snakemake.output.fig8_csv]
        write_no_runs(message, tables, [snakemake.output.get("fig8")])


run_stage(snakemake, "sine", main, log)
