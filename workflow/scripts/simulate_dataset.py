"""Simulate one configured dataset into canonical run tables."""

from spa.io import get_logger
from spa.pipeline.execution import recorded_job
from spa.pipeline.provenance import write_run_index
from spa.pipeline.status import run_stage
from spa.synthetic import generate_dataset

log = get_logger("simulate_dataset", snakemake.log[0])


def main() -> None:
    name = snakemake.wildcards.dataset
    paths = generate_dataset(
        name,
        snakemake.params.cfg,
        snakemake.params.experiments,
        snakemake.params.seed,
        snakemake.output.runs,
        progress=log.info,
    )
    write_run_index(snakemake.output.runs, paths)
    log.info("%s: %d runs written to %s", name, len(paths), snakemake.output.runs)


with recorded_job(snakemake):  # results/<dataset>/provenance/execution.json
    run_stage(snakemake, "runs", main, log)
