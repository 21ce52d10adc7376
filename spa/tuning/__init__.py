"""Tuning the modulators for linearity by optimisation (docs/model.md section 4, paper Section 5).

One concept per module, all re-exported here:

* :mod:`spa.tuning.cost` – the cost ``J`` of Eq. 25, the sweeps, their optimum and the
  analytic IIPFM optimum ``t_l*`` of Eq. 29;
* :mod:`spa.tuning.exact` – ``J_exact``, the same cost from the exact periodic steady state
  (:mod:`spa.model.periodic`) instead of the averaged Eq. 5;
* :mod:`spa.tuning.intervals` – the identification's 95 % intervals propagated by the corners
  of their box;
* :mod:`spa.tuning.tables` – the tidy tables of Fig. 4, Table 2 and Fig. 5;
* :mod:`spa.tuning.recommend` – candidates, constraints and the recommended setting;
* :mod:`spa.tuning.stage` – :func:`tune`, the whole stage for one valve.
"""

from spa.tuning.cost import (
    DEFAULT_SWEEPS,
    PAPER_SETTING,
    PAPER_TABLE2,
    SWEPT_PARAMETER,
    check_sweeps,
    constraint,
    deviation_cost,
    feasible,
    iipfm_optimal_t_l,
    linearity_cost,
    modulator_settings,
    optimum,
    paper_setting,
    setting,
    sweep,
    sweep_grid,
)
from spa.tuning.exact import exact_cost, exact_curve
from spa.tuning.intervals import INTERVAL_METHOD, corners, propagate, read_intervals
from spa.tuning.recommend import (
    CONSTRAINTS,
    TuningOptions,
    candidate_frame,
    predict,
    recommend,
    recommendation_sentence,
    setting_metrics,
)
from spa.tuning.stage import (
    Identified,
    TuningError,
    TuningResult,
    format_result,
    read_identified,
    tune,
    tune_with_config,
)
from spa.tuning.tables import equilibrium_frame, optimum_table, sweep_frame, tuning_table

__all__ = [
    "CONSTRAINTS",
    "DEFAULT_SWEEPS",
    "INTERVAL_METHOD",
    "PAPER_SETTING",
    "PAPER_TABLE2",
    "SWEPT_PARAMETER",
    "Identified",
    "TuningError",
    "TuningOptions",
    "TuningResult",
    "candidate_frame",
    "check_sweeps",
    "constraint",
    "corners",
    "deviation_cost",
    "equilibrium_frame",
    "exact_cost",
    "exact_curve",
    "feasible",
    "format_result",
    "iipfm_optimal_t_l",
    "linearity_cost",
    "modulator_settings",
    "optimum",
    "optimum_table",
    "paper_setting",
    "predict",
    "propagate",
    "read_identified",
    "read_intervals",
    "recommend",
    "recommendation_sentence",
    "setting",
    "setting_metrics",
    "sweep",
    "sweep_frame",
    "sweep_grid",
    "tune",
    "tune_with_config",
    "tuning_table",
]
