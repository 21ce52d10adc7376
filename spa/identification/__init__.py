"""Identification of the valve + actuator parameters from three experiments (Section 3.2).

docs/model.md section 1 and the paper's Fig. 2:

* experiment 1, **charge** (valve open from 0 bar until the supply pressure): ``k2`` and
  ``tau2`` of ``dP/dt = (k2 - P)/tau2``: the paper's straight line in ``dP/dt`` against ``P``,
  refined by fitting its exact solution to the pressure (:func:`fit_charge`);
* experiment 2, **discharge** (valve closed from the supply pressure down to 0 bar): the power
  law ``dP/dt = -a*P**b`` and ``c1`` of ``dP/dt = -sqrt(P)/c1`` (``b = 1/2``), fitted as its
  exact solution ``sqrt(P) = sqrt(P0) - t/(2*c1)`` to the pressure (:func:`fit_discharge`);
* experiment 3, **pulse** (a pulse train with several low-state durations): ``t_on`` and
  ``t_off`` from a least-squares fit of the exact model over the whole run, plus the delay of
  every single edge for the spread (:func:`fit_delays`).

:func:`identify` chains the three and returns an :class:`IdentificationResult` that serialises
to the content of ``params.yaml``; :func:`identification_commands` and
:func:`simulate_identification` describe the three experiments' valve commands.

The modules follow the stages of that work: ``results`` (what is returned), ``rates`` (dP/dt
and segments), ``rate_fits`` (experiments 1 and 2), ``delays`` (experiment 3), ``identify``
(the three chained, then refined), ``convention`` (which delay convention the valve has),
``experiments`` (the experiment design, for the simulator and a bench)
and ``identified`` (a ``params.yaml`` read back for the stages that use the valve, with the
corners of its 95 % box).

Run tables follow the project's contract: a DataFrame with ``t`` (s), ``p`` (bar), and
optionally ``valve`` (0/1, the command over ``[t_k, t_{k+1})``). Time need not start at 0 and
the sampling may be slightly irregular: the derivative fits work on a uniform grid at the
median sample step (linear interpolation), the delay fit on the raw sample times.
"""

from __future__ import annotations

from spa._lazy import lazy_exports

#: Submodules whose ``__all__`` the package re-exports (imported on first use).
_MODULES = (
    "adequacy",
    "convention",
    "delays",
    "diagnostics",
    "edges",
    "experiments",
    "identified",
    "identify",
    "rate_fits",
    "rates",
    "refine",
    "refined",
    "results",
)
_EXPORTS, __getattr__, __dir__ = lazy_exports(__name__, _MODULES)

#: What a notebook user calls (the API reference lists these); every other name of the
#: submodules above stays importable from here but is not presented as public API.
__all__ = [
    "DerivativeFit",
    "IdentificationError",
    "IdentificationResult",
    "fit_charge",
    "fit_delays",
    "fit_discharge",
    "identification_commands",
    "identify",
    "identify_runs",
    "load_params",
    "simulate_identification",
]
