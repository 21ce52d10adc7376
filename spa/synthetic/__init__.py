"""Simulated bench datasets: input signals, a sensor model and the paper's experiments.

A simulated run goes through exactly what a bench run goes through: an input fraction, a
digital modulator clocked at the controller step, the valve + actuator (exact, from
:func:`spa.simulate`), and a pressure sensor logged at its own rate with noise, ADC
quantisation and optionally the short damped ringing the paper saw after each valve edge.
The result is the canonical run table (``t`` s, ``p`` bar, ``valve`` 0/1, ``u`` 0–1).
"""

from __future__ import annotations

from spa._lazy import lazy_exports

#: Public name -> the module that defines it (imported on first use).
_EXPORTS: dict[str, str] = {
    **dict.fromkeys(("EXAMPLE_PARAMS", "write_example_dataset"), "spa.synthetic.example"),
    **dict.fromkeys(("chirp_input", "sine_input", "staircase_input"), "spa.synthetic.inputs"),
    **dict.fromkeys(
        (
            "RunSpec",
            "dataset_runs",
            "generate_dataset",
            "identification_runs",
            "modulated_runs",
            "run_seed",
            "simulate_run",
        ),
        "spa.synthetic.runs",
    ),
    **dict.fromkeys(("Ringing", "Sensor"), "spa.synthetic.sensor"),
}

__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)

__all__ = sorted(_EXPORTS)
