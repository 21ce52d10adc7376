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

from spa._lazy import lazy_exports

#: Public name -> the module that defines it (imported on first use).
_EXPORTS: dict[str, str] = {
    **dict.fromkeys(
        (
            "DEFAULT_SWEEPS",
            "PAPER_SETTING",
            "PAPER_TABLE2",
            "SWEPT_PARAMETER",
            "check_sweeps",
            "constraint",
            "deviation_cost",
            "feasible",
            "iipfm_optimal_t_l",
            "linearity_cost",
            "modulator_settings",
            "optimum",
            "paper_setting",
            "setting",
            "sweep",
            "sweep_grid",
        ),
        "spa.tuning.cost",
    ),
    **dict.fromkeys(("exact_cost", "exact_curve"), "spa.tuning.exact"),
    **dict.fromkeys(
        ("INTERVAL_METHOD", "corners", "propagate", "read_intervals"), "spa.tuning.intervals"
    ),
    **dict.fromkeys(
        (
            "CONSTRAINTS",
            "TuningOptions",
            "candidate_frame",
            "predict",
            "recommend",
            "recommendation_sentence",
            "setting_metrics",
        ),
        "spa.tuning.recommend",
    ),
    **dict.fromkeys(
        (
            "Identified",
            "TuningError",
            "TuningResult",
            "format_result",
            "read_identified",
            "tune",
            "tune_with_config",
        ),
        "spa.tuning.stage",
    ),
    **dict.fromkeys(
        ("equilibrium_frame", "optimum_table", "sweep_frame", "tuning_table"), "spa.tuning.tables"
    ),
}

__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)

__all__ = sorted(_EXPORTS)
