"""Bicoherence of the response to every chirp run of a dataset and of the linear reference."""

from spa.datasets import read_runs
from spa.io import get_logger, read_params
from spa.pipeline.status import run_stage
from spa.stages.chirp import run_chirp, write_chirp

log = get_logger("chirp", snakemake.log[0])


def main() -> list:
    runs, metas = read_runs(snakemake.input.runs)
    params = read_params(snakemake.input.params)
    result = run_chirp(runs, metas, params, snakemake.params.cfg, log)
    write_chirp(result, snakemake.output, snakemake.wildcards.dataset, log)
    return result.warnings


run_stage(snakemake, "chirp", main, log)
