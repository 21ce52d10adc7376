"""Sine linearity of every sine run of a dataset and of the linear reference: table and Fig. 8."""

from spa.stages.script import run_open_loop
from spa.stages.sine import run_sine, write_sine

run_open_loop(snakemake, "sine", run_sine, write_sine)
