"""spa: exact simulation and open-loop characterisation of a pulse-driven soft pneumatic actuator.

Implements Serrano-Balbontín et al., "Open-Loop Characterisation of Soft Actuator Pressure
Regulated by Pulse-Driven Solenoid Valve", Robotics 2025, 14(12), 177.

The top level re-exports the public API; the modules hold one concept each:
``params`` (ValveParams), ``modulators`` (modulate), ``plant`` (simulate), ``averaging``
(Section 4 of the paper), ``tuning`` (Section 5), ``synthetic`` (simulated datasets),
``identification`` and ``validation`` (Section 3.2), ``linearity``, ``spectra`` and
``openloop`` (Section 6: Table 3, Figs. 6-9), ``report`` (the HTML report).
"""

from spa.identification import (
    IdentificationError,
    IdentificationResult,
    identify,
    identify_runs,
    load_params,
)
from spa.model.averaging import (
    chattering_estimate,
    equilibrium,
    equilibrium_pressure,
    pseudo_steady_mean,
    pseudo_steady_state,
    pulse_times,
    thresholds,
    time_constant,
    time_fractions,
)
from spa.model.modulators import MODULATORS, check_settings, modulate
from spa.model.params import ValveParams
from spa.model.plant import charge, discharge, simulate
from spa.openloop import chirp_analysis, predicted_levels, sine_analysis, staircase_analysis
from spa.openloop.linearity import (
    compensate_lag,
    linear_fit_metrics,
    sine_linearity,
    staircase_levels,
    step_time_constants,
)
from spa.openloop.spectra import bicoherence, mean_bicoherence, principal_domain_mask
from spa.tuning import iipfm_optimal_t_l, linearity_cost, modulator_settings, optimum, sweep
from spa.validation import ValidationResult, validate_run, validate_runs

__all__ = [
    "MODULATORS",
    "IdentificationError",
    "IdentificationResult",
    "ValidationResult",
    "ValveParams",
    "bicoherence",
    "charge",
    "chattering_estimate",
    "check_settings",
    "chirp_analysis",
    "compensate_lag",
    "discharge",
    "equilibrium",
    "equilibrium_pressure",
    "identify",
    "identify_runs",
    "iipfm_optimal_t_l",
    "linear_fit_metrics",
    "linearity_cost",
    "load_params",
    "mean_bicoherence",
    "modulate",
    "modulator_settings",
    "optimum",
    "predicted_levels",
    "principal_domain_mask",
    "pseudo_steady_mean",
    "pseudo_steady_state",
    "pulse_times",
    "simulate",
    "sine_analysis",
    "sine_linearity",
    "staircase_analysis",
    "staircase_levels",
    "step_time_constants",
    "sweep",
    "thresholds",
    "time_constant",
    "time_fractions",
    "validate_run",
    "validate_runs",
]
__version__ = "0.1.0"
