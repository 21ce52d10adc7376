"""Figures, one module per stage: ``analytic`` (Figs. 4-5), ``identification`` (Fig. 2 and the
validation overlays), ``openloop`` (Figs. 6-9). Import the module you need: matplotlib is
loaded only by the jobs that draw."""
