"""Sine linearity of every sine run of a dataset and of the linear reference: table and Fig. 8."""

from spa.datasets import read_runs
from spa.io import get_logger, read_params
from spa.pipeline.status import run_stage
from spa.stages.sine import run_sine, write_sine

log = get_logger("sine", snakemake.log[0])


def main() -> list:
    runs, metas = read_runs(snakemake.input.runs)
    params = read_params(snakemake.input.params)
    result = run_sine(runs, metas, params, snakemake.params.cfg, log)
    write_sine(result, snakemake.output, snakemake.wildcards.dataset, log)
    return result.warnings


run_stage(snakemake, "sine", main, log)
