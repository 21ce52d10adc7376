"""Bicoherence of the response to every chirp run of a dataset and of the linear reference."""

import pandas as pd

from spa.io import get_logger, read_params, read_runs, write_csv
from spa.openloop import (
    chirp_analysis,
    chirp_reference,
    fallback_note,
    is_simulated,
    no_ringing_spread,
    noise_spread,
    paper_settings,
    run_tags,
    runs_of_kind,
)
from spa.openloop.shapes import check_input_shape
from spa.plots.openloop import fig9, fig9_data, write_no_runs
from spa.plots.save import draw
from spa.status import naming_run, run_stage

log = get_logger("chirp", snakemake.log[0])


def main() -> None:
    cfg = dict(snakemake.params.cfg)
    seeds = cfg.pop("seeds")
    runs, metas = read_runs(snakemake.input.runs)
    ids = runs_of_kind(metas, "chirp")
    tags = run_tags(metas, ids)
    rows, maps = [], {}
    for i, rid in enumerate(ids, 1):
        check_input_shape(rid, "chirp", runs[rid]["u"])
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

    if ids:
        # The same input (the first run's) through the linear first-order reference.
        params = read_params(snakemake.input.params)
        mods = [metas[r]["modulator"] for r in ids]
        first = ids[0]  # through its sensor (ringing after its edges, its noise) if simulated
        f, bic, ref = chirp_reference(runs[first], params, mods, metas[first], seeds, **cfg)
        log.info("linear reference: tau_m %.3f s, significant fraction %.4f",
                 ref["tau_m"], ref["significant_fraction"])  # fmt: skip
        table = pd.DataFrame([*rows, ref])
        write_csv(table, snakemake.output.table)
        bounded = cfg["normalisation"] == "bounded"
        score = "significant_fraction" if bounded else "mean_bicoherence"
        shown, fallbacks = paper_settings(table.iloc[:-1], score=score, higher=False)
        named = [(r["setting"], *maps[r["run"]]) for _, r in shown.iterrows()]
        named.append((ref["setting"], f, bic, ref["threshold"], ref["fmin"]))
        write_csv(fig9_data(named), snakemake.output.fig9_csv)
        titles = [*(_title(r) for _, r in shown.iterrows()), _title(ref)]
        panels = [(title, *rest) for title, (_, *rest) in zip(titles, named, strict=True)]
        note = (
            f"{cfg['normalisation']} bicoherence, {ref['n_segments']} segments, bins above "
            f"{ref['threshold']:.3f} (α = {cfg['alpha']}) coloured; "
            + fallback_note(fallbacks, score)
        )
        settings = list(shown["setting"])
        draw(snakemake.output.get("fig9"), fig9, panels, sweep=table, shown=settings, note=note)
    else:
        log.info("no chirp runs in this dataset: empty table, placeholder figure")
        message = f"{snakemake.wildcards.dataset}: no chirp runs"
        tables = [snakemake.output.table, snakemake.output.fig9_csv]
        write_no_runs(message, tables, [snakemake.output.get("fig9")])


def _title(row) -> str:
    """A map's title: its setting and the fraction of its domain that is significant."""
    return f"{row['setting']}: {row['significant_fraction']:.1%} significant"


run_stage(snakemake, "chirp", main, log)
