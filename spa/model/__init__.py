"""The model: valve parameters, the exact plant, the modulators and the averaged analysis.

``params`` (ValveParams), ``plant`` (closed forms and exact simulation), ``modulators``
(modulate), ``averaging`` (Section 4 of the paper: equilibrium, time constant, chattering,
thresholds).
"""
