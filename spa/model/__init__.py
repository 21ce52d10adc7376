"""The model: valve parameters, the exact plant, the modulators and the averaged analysis.

``params`` (ValveParams), ``plant`` (closed forms and exact simulation), ``modulators``
(modulate), ``averaging`` (Section 4 of the paper: pulse times, time fractions, equilibrium,
time constant; re-exports the two below), ``chattering`` (Eq. 10 and Appendix B's periodic
extrema), ``thresholds`` (dead-zone and saturation, Table 1).
"""
