"""Close the loop for one dataset: PI designs, exact simulations, metrics, Figs. 10-11."""

from pathlib import Path

import yaml

from spa.closedloop.bench import adequacy_of, apply_bench, bench_outputs, sensor_noise
from spa.closedloop.model_error import dataset_error
from spa.closedloop.stage import closed_loop, recorded_runs
from spa.io import get_logger, read_runs
from spa.pipeline.status import run_stage
from spa.stages.closed_loop import write_closed_loop
from spa.tuning.stage import read_identified

log = get_logger("closed_loop", snakemake.log[0])


def main() -> None:
    dataset = snakemake.wildcards.dataset
    valve = read_identified(snakemake.input.params)
    rec_path = Path(snakemake.input.recommendation)
    recommendation = yaml.safe_load(rec_path.read_text()) if rec_path.is_file() else None
    cfg = snakemake.params.cfg
    result = closed_loop(valve.params, snakemake.params.selected, recommendation, cfg)
    for why in result.skipped.values():
        log.warning("%s: left out: %s", dataset, why)
    identified = yaml.safe_load(Path(snakemake.input.params).read_text())
    noise = sensor_noise(identified)
    runs, metas = read_runs(snakemake.input.runs)
    # a loop with the averaged model's feed-forward also meets the equilibrium error
    with_ff = result.controllers.get("controller") == "scheduled_ff"
    error = dataset_error(runs, metas, valve.params, identified, equilibrium=with_ff)
    bench = bench_outputs(
        result,
        valve.params,
        valve.intervals,
        cfg,
        noise,
        model_error=error,
        adequacy=adequacy_of(identified),
    )
    apply_bench(result, bench)
    recorded = recorded_runs(runs, metas, valve.params)
    write_closed_loop(result, recorded, snakemake.output, bench)
    for row in recorded.itertuples():
        log.info("%s: closed-loop run %s replayed: FIT %.1f %%", dataset, row.run, row.fit)
    log.info("%s: %s", dataset, result.sentence)


run_stage(snakemake, "closed_loop", main, log)
