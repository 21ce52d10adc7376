"""Validate a bench dataset from raw/ and write its canonical run tables."""

from spa.datasets import DatasetError, ingest_dataset
from spa.io import get_logger
from spa.pipeline.provenance import write_run_index
from spa.pipeline.status import run_stage

log = get_logger("ingest_dataset", snakemake.log[0])


def main() -> None:
    folder = snakemake.params.folder
    warnings = []
    try:
        paths = ingest_dataset(folder, snakemake.output.runs, warnings, snakemake.params.supply)
    except DatasetError:
        log.error("%s failed validation; fix it (check with `spa validate %s`)", folder, folder)
        raise
    for problem in warnings:
        log.warning("%s", problem)
    write_run_index(snakemake.output.runs, paths)
    for path in paths:
        log.info("wrote %s", path)


run_stage(snakemake, "runs", main, log)
