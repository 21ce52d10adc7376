"""Open-loop characterisation of one run: staircase, sine and chirp (paper Section 6).

Each analysis takes one canonical run table (``t`` s, ``p`` bar, ``valve`` 0/1, ``u`` input
fraction) and returns tables ready to be written:

* `staircase_analysis` (:mod:`~spa.openloop.staircase`): per level the measured equilibrium,
  chattering (with the sensor's noise subtracted, :mod:`~spa.openloop.noise`) and switching
  rate beside the averaged model's predictions; per step the time constant (Fig. 7b); one
  row of Table 3.
* `sine_analysis` (:mod:`~spa.openloop.sine`): the lag-compensated input against the
  normalised pressure (Fig. 8) and its deviation from the line from (0, 0) to (1, 1).
* `chirp_analysis` (:mod:`~spa.openloop.chirp`): the bounded bicoherence of the pressure
  (Fig. 9), its significance threshold and the fraction of the map above it.

`sine_reference` and `chirp_reference` put the same input through a noise-free linear
first-order plant (:mod:`~spa.openloop.reference`) and analyse it identically: the row with
``modulator = "linear"`` of each table. For simulated runs, :mod:`~spa.openloop.replicas`
gives the noise-free pressure and fresh-noise replicates. The array functions behind the
analyses are in :mod:`~spa.openloop.levels`, :mod:`~spa.openloop.steps`,
:mod:`~spa.openloop.sine_fit` and :mod:`~spa.openloop.spectra`; the paper's printed values
and settings in :mod:`~spa.openloop.paper`; the choice of runs and of the settings a figure
shows in :mod:`~spa.openloop.selection`.
"""

from __future__ import annotations

from spa._lazy import lazy_exports

#: Public name -> the module that defines it (imported on first use).
_EXPORTS: dict[str, str] = {
    "MODULATOR_ORDER": "spa.model.modulators",
    **dict.fromkeys(
        ("chirp_analysis", "chirp_bicoherence", "chirp_reference", "noise_spread"),
        "spa.openloop.chirp",
    ),
    **dict.fromkeys(("linear_fit_metrics", "staircase_levels"), "spa.openloop.levels"),
    **dict.fromkeys(("corrected_ripple", "sensor_noise"), "spa.openloop.noise"),
    **dict.fromkeys(
        ("PAPER_SETTINGS", "PAPER_TABLE3", "PAPER_TIME_CONSTANTS", "paper_case"),
        "spa.openloop.paper",
    ),
    **dict.fromkeys(
        (
            "REFERENCE",
            "first_order_response",
            "linear_reference",
            "reference_run",
            "reference_time_constant",
        ),
        "spa.openloop.reference",
    ),
    **dict.fromkeys(
        ("is_simulated", "noise_free_pressure", "noise_replicates"), "spa.openloop.replicas"
    ),
    **dict.fromkeys(
        ("best_settings", "fallback_note", "paper_settings", "run_tags", "runs_of_kind"),
        "spa.openloop.selection",
    ),
    **dict.fromkeys(
        ("frequency_note", "sine_analysis", "sine_frequency", "sine_reference"), "spa.openloop.sine"
    ),
    **dict.fromkeys(("compensate_lag", "sine_linearity"), "spa.openloop.sine_fit"),
    **dict.fromkeys(
        (
            "bicoherence",
            "mean_bicoherence",
            "principal_domain_mask",
            "significance_threshold",
            "significant_fraction",
        ),
        "spa.openloop.spectra",
    ),
    **dict.fromkeys(
        ("measured_thresholds", "predicted_levels", "staircase_analysis"), "spa.openloop.staircase"
    ),
    "step_time_constants": "spa.openloop.steps",
}

__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)

__all__ = sorted(_EXPORTS)
