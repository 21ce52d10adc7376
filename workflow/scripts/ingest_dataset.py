"""Validate a bench dataset from raw/ and write its canonical run tables."""

import sys

from spa.datasets import DatasetError, ingest_dataset
from spa.io import get_logger
from spa.provenance import write_run_index

log = get_logger("ingest_dataset", snakemake.log[0])
folder = snakemake.params.folder
try:
    paths = ingest_dataset(folder, snakemake.output.runs)
except DatasetError as exc:
    for problem in exc.problems:
        log.error("%s", problem)
    log.error("%s failed validation; fix it (check with `spa validate %s`)", folder, folder)
    sys.exit(1)
write_run_index(snakemake.output.runs, paths)
for path in paths:
    log.info("wrote %s", path)
