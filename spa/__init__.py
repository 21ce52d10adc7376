"""spa: exact simulation and open-loop characterisation of a pulse-driven soft pneumatic actuator.

Implements Serrano-Balbontín et al., "Open-Loop Characterisation of Soft Actuator Pressure
Regulated by Pulse-Driven Solenoid Valve", Robotics 2025, 14(12), 177.

The subpackages follow the pipeline's stages: ``model`` (ValveParams, the exact plant, the
modulators, the averaged analysis of Section 4), ``datasets`` (the dataset contract, readers,
checks, ingest), ``synthetic`` (simulated datasets), ``identification`` (Section 3.2),
``validation`` (the identified model replayed on every run), ``tuning`` (Section 5),
``openloop`` (Section 6: Table 3, Figs. 6-9), ``plots`` and ``report``.

The top level re-exports the public API: what a notebook user calls, grouped by task in the
API reference (docs/api/index.rst). Names are imported on first use (PEP 562), so that
``import spa`` and ``import spa.io`` stay cheap in a workflow job that needs one stage only.
"""

from __future__ import annotations

from spa._lazy import lazy_exports
from spa.closedloop import _EXPORTS as _CLOSED_LOOP

__version__ = "0.1.0"

#: Public name -> the module that defines it: what a notebook user calls, by task. The API
#: reference's front page (docs/api/index.rst) lists exactly these, in the same sections, and
#: tests/test_docs_site.py keeps the two in step.
_EXPORTS: dict[str, str] = {
    # The valve and the plant: parameters, the exact simulation.
    "ValveParams": "spa.model.params",
    **dict.fromkeys(("charge", "discharge", "simulate"), "spa.model.plant"),
    "load_params": "spa.identification.results",
    # The modulators.
    **dict.fromkeys(
        ("MODULATORS", "Modulator", "check_settings", "modulate"), "spa.model.modulators"
    ),
    # The averaged analysis (Section 4), from the module that defines each name.
    **dict.fromkeys(
        ("equilibrium", "equilibrium_pressure", "pulse_times", "time_constant", "time_fractions"),
        "spa.model.averaging",
    ),
    **dict.fromkeys(
        ("chattering_estimate", "pseudo_steady_mean", "pseudo_steady_state"),
        "spa.model.chattering",
    ),
    "thresholds": "spa.model.thresholds",
    # Datasets: the raw/ contract, the canonical run tables.
    **dict.fromkeys(("DatasetError", "ingest_dataset", "validate_dataset"), "spa.datasets"),
    "read_run_table": "spa.datasets",
    "read_runs": "spa.datasets",
    # Identification (Section 3.2) and the model's validation on every run.
    **dict.fromkeys(
        ("IdentificationError", "IdentificationResult", "identify", "identify_runs"),
        "spa.identification",
    ),
    **dict.fromkeys(("ValidationResult", "validate_run", "validate_runs"), "spa.validation"),
    # Tuning (Section 5).
    **dict.fromkeys(
        ("iipfm_optimal_t_l", "linearity_cost", "modulator_settings", "optimum", "sweep"),
        "spa.tuning",
    ),
    **dict.fromkeys(("TuningResult", "tune"), "spa.tuning"),
    # Open-loop characterisation (Section 6).
    **dict.fromkeys(("linear_fit_metrics", "staircase_levels"), "spa.openloop.levels"),
    "step_time_constants": "spa.openloop.steps",
    **dict.fromkeys(("compensate_lag", "sine_linearity"), "spa.openloop.sine_fit"),
    **dict.fromkeys(
        ("chirp_analysis", "predicted_levels", "sine_analysis", "staircase_analysis"),
        "spa.openloop",
    ),
    **dict.fromkeys(
        ("bicoherence", "mean_bicoherence", "principal_domain_mask"), "spa.openloop.spectra"
    ),
    # Closed loop: design, exact simulation, the controller on a bench (where
    # spa.closedloop says each lives).
    **{
        name: _CLOSED_LOOP[name]
        for name in (
            "PIController",
            "design_pi",
            "simulate_closed_loop",
            "ControllerStepper",
            "controller_header",
            "export_designed",
        )
    },
}

__all__ = sorted(_EXPORTS)


_, __getattr__, __dir__ = lazy_exports(__name__, (), _EXPORTS)
