"""Staircase linearity of every staircase run of a dataset: Table 3, Figs. 6, 7a and 7b."""

from spa.datasets import read_runs
from spa.io import get_logger, read_params
from spa.pipeline.status import run_stage
from spa.stages.staircase import run_staircase, write_staircase

log = get_logger("staircase", snakemake.log[0])


def main() -> None:
    runs, metas = read_runs(snakemake.input.runs)
    params = read_params(snakemake.input.params)
    result = run_staircase(runs, metas, params, snakemake.params.cfg, log)
    write_staircase(result, snakemake.output, snakemake.wildcards.dataset, log)


run_stage(snakemake, "staircase", main, log)
