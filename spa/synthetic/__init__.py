"""Simulated bench datasets: input signals, a sensor model and the paper's experiments.

A simulated run goes through exactly what a bench run goes through: an input fraction, a
digital modulator clocked at the controller step, the valve + actuator (exact, from
:func:`spa.simulate`), and a pressure sensor logged at its own rate with noise, ADC
quantisation and optionally the short damped ringing the paper saw after each valve edge.
The result is the canonical run table (``t`` s, ``p`` bar, ``valve`` 0/1, ``u`` 0–1).

:mod:`~spa.synthetic.physical` is a test plant that is *not* the model (orifice flow, spool
dead times, a compliant chamber, regulator droop, a lagging sensor; its twin in C): a
dataset that declares ``plant: {kind: physical}`` has every run made by it. The model itself
has a twin in C too (``model_plant.c``, :func:`spa.simulate` stepped tick by tick), on which
the plan's player closes its loops (:func:`spa.plan.host.play_on_model`).
"""

from __future__ import annotations

from spa._lazy import lazy_exports

#: Submodules whose ``__all__`` the package re-exports (imported on first use).
_MODULES = ("example", "inputs", "physical", "runs", "sensor")
_EXPORTS, __getattr__, __dir__ = lazy_exports(__name__, _MODULES)

#: What a notebook user calls (the API reference lists these); every other name of the
#: submodules above stays importable from here but is not presented as public API.
__all__ = [
    "EXAMPLE_PARAMS",
    "Ringing",
    "Sensor",
    "chirp_input",
    "identification_experiment_for",
    "sensor_record",
    "simulate_run",
    "sine_input",
    "staircase_input",
    "write_example_dataset",
]
