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

`sine_reference` and `chirp_reference` put the same input through a linear first-order
plant (:mod:`~spa.openloop.reference`) and analyse it identically: the row with
``modulator = "linear"`` of each table (noise-free, except that a simulated chirp's reference
is logged by the run's own sensor). For simulated runs, :mod:`~spa.openloop.replicas` gives
the noise-free pressure, fresh-noise replicates and any record through the run's sensor.
The array functions behind the analyses are in :mod:`~spa.openloop.levels`,
:mod:`~spa.openloop.steps`, :mod:`~spa.openloop.sine_fit` and :mod:`~spa.openloop.spectra`;
the paper's printed values and settings in :mod:`~spa.openloop.paper`; the choice of runs
and of the settings a figure shows in :mod:`~spa.openloop.selection`.
"""

from __future__ import annotations

from spa._lazy import lazy_exports

#: Submodules whose ``__all__`` the package re-exports (imported on first use).
_MODULES = (
    "chirp",
    "levels",
    "noise",
    "paper",
    "reference",
    "replicas",
    "selection",
    "sine",
    "sine_fit",
    "spectra",
    "staircase",
    "steps",
)
_EXTRA = {"MODULATOR_ORDER": "spa.model.modulators"}
_EXPORTS, __getattr__, __dir__ = lazy_exports(__name__, _MODULES, _EXTRA)

#: What a notebook user calls (the API reference lists these); every other name of the
#: submodules above stays importable from here but is not presented as public API.
__all__ = [
    "PAPER_TABLE2",
    "PAPER_TABLE3",
    "bicoherence",
    "chirp_analysis",
    "chirp_reference",
    "compensate_lag",
    "linear_fit_metrics",
    "mean_bicoherence",
    "predicted_levels",
    "principal_domain_mask",
    "significance_threshold",
    "significant_fraction",
    "sine_analysis",
    "sine_linearity",
    "sine_reference",
    "staircase_analysis",
    "staircase_levels",
    "step_time_constants",
]
