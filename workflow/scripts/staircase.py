"""Staircase linearity of every staircase run of a dataset: Table 3, Figs. 6, 7a and 7b."""

from spa.stages.script import run_open_loop
from spa.stages.staircase import run_staircase, write_staircase

run_open_loop(snakemake, "staircase", run_staircase, write_staircase)
