"""Bicoherence of the response to every chirp run of a dataset and of the linear reference."""

from spa.stages.chirp import run_chirp, write_chirp
from spa.stages.script import run_open_loop

run_open_loop(snakemake, "chirp", run_chirp, write_chirp)
