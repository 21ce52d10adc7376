"""Simulated bench datasets: input signals, a sensor model and the paper's experiments.

A simulated run goes through exactly what a bench run goes through: an input fraction, a
digital modulator clocked at the controller step, the valve + actuator (exact, from
:func:`spa.simulate`), and a pressure sensor logged at its own rate with noise, ADC
quantisation and optionally the short damped ringing the paper saw after each valve edge.
The result is the canonical run table (``t`` s, ``p`` bar, ``valve`` 0/1, ``u`` 0–1).
"""

from __future__ import annotations

from spa.synthetic.example import EXAMPLE_PARAMS, write_example_dataset
from spa.synthetic.inputs import chirp_input, sine_input, staircase_input
from spa.synthetic.runs import (
    RunSpec,
    dataset_runs,
    generate_dataset,
    identification_runs,
    modulated_runs,
    run_seed,
    simulate_run,
)
from spa.synthetic.sensor import Ringing, Sensor

__all__ = [
    "EXAMPLE_PARAMS",
    "Ringing",
    "RunSpec",
    "Sensor",
    "chirp_input",
    "dataset_runs",
    "generate_dataset",
    "identification_runs",
    "modulated_runs",
    "run_seed",
    "simulate_run",
    "sine_input",
    "staircase_input",
    "write_example_dataset",
]
