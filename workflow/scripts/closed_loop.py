"""Close the loop for one dataset: PI designs, exact simulations, metrics, Figs. 10-11."""

from pathlib import Path

import yaml

from spa.closedloop.stage import closed_loop, recorded_runs, write_controllers
from spa.io import get_logger, read_runs, write_csv
from spa.plots.closedloop import fig10, fig11
from spa.plots.save import draw
from spa.status import run_stage
from spa.tuning.stage import read_identified

log = get_logger("closed_loop", snakemake.log[0])


def main() -> None:
    out = snakemake.output
    dataset = snakemake.wildcards.dataset
    valve = read_identified(snakemake.input.params)
    rec_path = Path(snakemake.input.recommendation)
    recommendation = yaml.safe_load(rec_path.read_text()) if rec_path.is_file() else None
    result = closed_loop(
        valve.params, snakemake.params.selected, recommendation, snakemake.params.cfg
    )
    for label, why in result.skipped.items():
        log.warning("%s: %s left out: %s", dataset, label, why)
    write_csv(result.table, out.table)
    write_controllers(result, out.controllers)
    write_csv(result.traces, out.fig10_csv)
    draw(out.get("fig10"), fig10, result.traces)
    write_csv(result.steps, out.fig11_csv)
    draw(out.get("fig11"), fig11, result.steps)
    runs, metas = read_runs(snakemake.input.runs)
    recorded = recorded_runs(runs, metas, valve.params)
    write_csv(recorded, out.recorded)
    for row in recorded.itertuples():
        log.info("%s: closed-loop run %s replayed: FIT %.1f %%", dataset, row.run, row.fit)
    log.info("%s: %s", dataset, result.sentence)


run_stage(snakemake, "closed_loop", main, log)
