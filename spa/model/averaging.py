"""Averaged analysis of a pulse-driven valve feeding a soft actuator (MODEL.md section 3).

Section 4.2 of the paper replaces the switched plant by its average over one pulse period:
the actuator discharges for the fraction ``alpha1`` of the period and charges for the fraction
``alpha2``, the valve's opening and closing delays being dead time. Everything here is a
closed form in the input fraction ``xi`` and the modulator's settings:

* :func:`pulse_times` – steady high/low durations of each modulator (Appendix A);
* :func:`time_fractions` – the effective fractions ``alpha1``, ``alpha2`` (Eqs. 6–7);
* :func:`equilibrium_pressure`, :func:`equilibrium` – the averaged equilibrium (Eq. 5);
* :func:`time_constant` – the equivalent time constant (Eq. 9);
* :func:`chattering_estimate` – the chattering estimate (Eq. 10);
* :func:`pseudo_steady_state`, :func:`pseudo_steady_mean` – the exact periodic extrema for a
  fixed pulse train (Appendix B), no averaging assumed;
* :func:`thresholds`, :func:`threshold_table` – dead-zone and saturation (Table 1).

All functions are vectorised: ``xi`` and the modulator settings may be scalars or arrays and
broadcast against each other (NumPy rules); a scalar in gives a NumPy scalar out.
"""

from __future__ import annotations

from spa.model.chattering import chattering_estimate, pseudo_steady_mean, pseudo_steady_state
from spa.model.equilibrium import equilibrium, equilibrium_pressure, time_constant
from spa.model.pulses import Floats as Floats
from spa.model.pulses import pulse_times, time_fractions
from spa.model.thresholds import THRESHOLD_FORMULAS, threshold_table, thresholds

__all__ = [
    "THRESHOLD_FORMULAS",
    "chattering_estimate",
    "equilibrium",
    "equilibrium_pressure",
    "pseudo_steady_mean",
    "pseudo_steady_state",
    "pulse_times",
    "threshold_table",
    "thresholds",
    "time_constant",
    "time_fractions",
]
