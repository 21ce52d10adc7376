"""Close the loop for one dataset: PI designs, exact simulations, metrics, Figs. 10-11."""

from spa.io import get_logger
from spa.pipeline.status import NoRuns, run_stage
from spa.stages.closed_loop import close_dataset_loop, write_closed_loop

log = get_logger("closed_loop", snakemake.log[0])


def main() -> list[NoRuns] | None:
    dataset = snakemake.wildcards.dataset
    result, recorded, bench = close_dataset_loop(
        snakemake.input.params,
        snakemake.input.recommendation,
        snakemake.input.runs,
        snakemake.params.selected,
        snakemake.params.cfg,
    )
    for why in result.skipped.values():
        log.warning("%s: left out: %s", dataset, why)
    write_closed_loop(result, recorded, snakemake.output, bench)
    for row in recorded.itertuples():
        log.info("%s: closed-loop run %s replayed: FIT %.1f %%", dataset, row.run, row.fit)
    log.info("%s: %s", dataset, result.sentence)
    # the recorded runs' comparison has no closed_loop run to compare: said, not "ok"
    return [NoRuns("closed_loop", ("closed_loop/runs.csv",))] if recorded.empty else None


run_stage(snakemake, "closed_loop", main, log)
