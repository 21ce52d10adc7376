"""Fig. 5: equilibrium pressure (Eq. 5) and time constant (Eq. 9) at the Table 2 optima."""

import pandas as pd

from spa.io import get_logger, write_csv
from spa.model.params import ValveParams
from spa.pipeline.status import guard_environment
from spa.plots.analytic import plot_equilibrium
from spa.plots.save import save_figure
from spa.tuning import equilibrium_frame

log = get_logger("analytic.fig5", snakemake.log[0])
guard_environment(log, "analytic Fig. 5")  # a full disk: one line saying so
params = ValveParams(**snakemake.params.nominal)
table2 = pd.read_csv(snakemake.input.table2)
# Table 2 gives PWM in Hz and the time parameters in ms.
scale = table2["unit"].map({"Hz": 1.0, "ms": 1e-3})
optima = dict(zip(table2["modulator"], table2["optimum"] * scale, strict=True))
data = equilibrium_frame(optima, params, n_xi=snakemake.params.n_xi)
write_csv(data, snakemake.output.data)
save_figure(plot_equilibrium(data), snakemake.output.figure)
log.info("fig 5 at %s", optima)
