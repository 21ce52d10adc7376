"""Tuning the modulators for linearity by optimisation (docs/model.md section 4, paper Section 5).

One concept per module, all re-exported here:

* :mod:`spa.tuning.cost` – the cost ``J`` of Eq. 25, the sweeps, their optimum and the
  analytic IIPFM optimum ``t_l*`` of Eq. 29;
* :mod:`spa.tuning.exact` – ``J_exact``, the same cost from the exact periodic steady state
  (:mod:`spa.model.periodic`) instead of the averaged Eq. 5;
* :mod:`spa.tuning.intervals` – the identification's 95 % intervals propagated by the corners
  of their box (:func:`spa.identification.identified.corners`);
* :mod:`spa.tuning.tables` – the tidy tables of Fig. 4, Table 2 and Fig. 5;
* :mod:`spa.tuning.constraints` – the options, the user's constraints and how far a setting
  is from meeting them;
* :mod:`spa.tuning.candidates` – every setting of the sweeps with its costs and what a user
  must live with;
* :mod:`spa.tuning.recommend` – the recommended setting and what it will do;
* :mod:`spa.tuning.sentence` – the recommendation in one sentence;
* :mod:`spa.tuning.valve` – :func:`tune`, the whole stage for one valve.
"""

from spa._lazy import lazy_exports

#: Submodules whose ``__all__`` the package re-exports (imported on first use).
_MODULES = (
    "cost",
    "exact",
    "intervals",
    "constraints",
    "candidates",
    "recommend",
    "sentence",
    "valve",
    "tables",
)
_EXPORTS, __getattr__, __dir__ = lazy_exports(__name__, _MODULES)

#: What a notebook user calls (the API reference lists these); every other name of the
#: submodules above stays importable from here but is not presented as public API.
__all__ = [
    "CONSTRAINTS",
    "TuningError",
    "TuningOptions",
    "TuningResult",
    "iipfm_optimal_t_l",
    "linearity_cost",
    "modulator_settings",
    "optimum",
    "propagate",
    "sweep",
    "tune",
]
