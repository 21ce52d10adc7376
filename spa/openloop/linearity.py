"""Staircase and sine linearity analyses of the open-loop experiments (docs/model.md section 5).

Pure functions on arrays; the arguments are the columns of the canonical run table
(``t`` in s, ``p`` in bar, ``valve`` 0/1, ``u`` the input fraction), so a run is analysed as

>>> import numpy as np
>>> import pandas as pd
>>> t = np.arange(0, 20, 0.01)
>>> u = np.floor(t / 5) / 4  # four levels, 0 .. 0.75
>>> run = pd.DataFrame({"t": t, "p": 0.8 * u, "u": u})
>>> levels = staircase_levels(run["t"], run["p"], run["u"])
>>> round(linear_fit_metrics(levels["xi"], levels["p_eq"])["fit"], 9)
100.0

* Staircase (Table 3, Fig. 7): `staircase_levels` finds the constant-input levels and the
  settled statistics of each; `linear_fit_metrics` fits ``P = m*xi + n`` to the equilibrium
  pressures; `step_time_constants` measures the time to 63.2 % of each step's change.
* Sine (Fig. 8): `compensate_lag` removes the phase lag by cross-correlation, then
  `sine_linearity` compares the pressure normalised to its maximum with the line from
  (0, 0) to (1, 1).

None of them loops over samples in Python: per-level statistics use ``ufunc.reduceat`` and
cumulative sums over the contiguous runs of samples that make up each level.
"""

from __future__ import annotations

from spa.openloop._arrays import TAU_FRACTION
from spa.openloop.levels import linear_fit_metrics, staircase_levels
from spa.openloop.sine_fit import compensate_lag, sine_linearity
from spa.openloop.steps import step_time_constants

__all__ = [
    "TAU_FRACTION",
    "compensate_lag",
    "linear_fit_metrics",
    "sine_linearity",
    "staircase_levels",
    "step_time_constants",
]
