"""Table 2: optimum of each linearity sweep, beside the paper's printed values."""

from spa.io import get_logger, write_csv
from spa.model.params import ValveParams
from spa.pipeline.status import guard_environment
from spa.tuning import optimum_table

log = get_logger("analytic.table2", snakemake.log[0])
guard_environment(log, "analytic table 2")  # a full disk: one line saying so
params = ValveParams(**snakemake.params.nominal)
table = optimum_table(snakemake.params.sweeps, params, n_xi=snakemake.params.n_xi)
write_csv(table, snakemake.output.table)
log.info("table 2 -> %s\n%s", snakemake.output.table, table)
