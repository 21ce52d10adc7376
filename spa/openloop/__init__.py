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

from spa.model.modulators import MODULATOR_ORDER
from spa.openloop.chirp import chirp_analysis, chirp_bicoherence, chirp_reference, noise_spread
from spa.openloop.levels import linear_fit_metrics, staircase_levels
from spa.openloop.noise import corrected_ripple, sensor_noise
from spa.openloop.paper import PAPER_SETTINGS, PAPER_TABLE3, PAPER_TIME_CONSTANTS, paper_case
from spa.openloop.reference import (
    REFERENCE,
    first_order_response,
    linear_reference,
    reference_run,
    reference_time_constant,
)
from spa.openloop.replicas import is_simulated, noise_free_pressure, noise_replicates
from spa.openloop.selection import (
    best_settings,
    fallback_note,
    paper_settings,
    run_tags,
    runs_of_kind,
)
from spa.openloop.sine import frequency_note, sine_analysis, sine_frequency, sine_reference
from spa.openloop.sine_fit import compensate_lag, sine_linearity
from spa.openloop.spectra import (
    bicoherence,
    mean_bicoherence,
    principal_domain_mask,
    significance_threshold,
    significant_fraction,
)
from spa.openloop.staircase import measured_thresholds, predicted_levels, staircase_analysis
from spa.openloop.steps import step_time_constants

__all__ = [
    "MODULATOR_ORDER",
    "PAPER_SETTINGS",
    "PAPER_TABLE3",
    "PAPER_TIME_CONSTANTS",
    "REFERENCE",
    "best_settings",
    "bicoherence",
    "chirp_analysis",
    "chirp_bicoherence",
    "chirp_reference",
    "compensate_lag",
    "corrected_ripple",
    "fallback_note",
    "first_order_response",
    "frequency_note",
    "is_simulated",
    "linear_fit_metrics",
    "linear_reference",
    "mean_bicoherence",
    "measured_thresholds",
    "noise_free_pressure",
    "noise_replicates",
    "noise_spread",
    "paper_case",
    "paper_settings",
    "predicted_levels",
    "principal_domain_mask",
    "reference_run",
    "reference_time_constant",
    "run_tags",
    "runs_of_kind",
    "sensor_noise",
    "significance_threshold",
    "significant_fraction",
    "sine_analysis",
    "sine_frequency",
    "sine_linearity",
    "sine_reference",
    "staircase_analysis",
    "staircase_levels",
    "step_time_constants",
]
