"""Figures, one module per stage: ``analytic`` (Figs. 4-5), ``tuning`` (a valve's Figs. 4-5),
``identification`` (Fig. 2 and the validation overlays), ``openloop`` (Figs. 6-9),
``closedloop`` (Figs. 10-11) (Fig. O1, the overview of many sessions, is the report's:
:mod:`spa.report.overview_figure`); ``style`` (palette, order, legends),
``save`` (the one writer), ``check`` (a drawn figure read as a person reads it),
``caption_check`` (its caption read against what it draws) and ``drawn`` (what an axes draws,
for both). Import the module you need: matplotlib is loaded only by the jobs that draw."""
