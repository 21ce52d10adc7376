"""Fig. 4: linearity cost J (Eq. 25) swept over each modulator's parameter."""

from spa.io import get_logger, write_csv
from spa.model.params import ValveParams
from spa.pipeline.status import guard_environment
from spa.plots.analytic import plot_cost_sweeps
from spa.plots.save import save_figure
from spa.tuning import sweep_frame

log = get_logger("analytic.fig4", snakemake.log[0])
guard_environment(log, "analytic Fig. 4")  # a full disk: one line saying so
params = ValveParams(**snakemake.params.nominal)
data = sweep_frame(snakemake.params.sweeps, params, n_xi=snakemake.params.n_xi)
write_csv(data, snakemake.output.data)
save_figure(plot_cost_sweeps(data, params=params), snakemake.output.figure)
log.info("fig 4: %d grid points (n_xi = %d)", len(data), snakemake.params.n_xi)
