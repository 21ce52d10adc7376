"""Table 1: dead-zone and saturation thresholds of the selected modulator settings."""

from spa.io import get_logger, write_csv
from spa.model.averaging import threshold_table
from spa.model.params import ValveParams
from spa.pipeline.status import guard_environment

log = get_logger("analytic.table1", snakemake.log[0])
guard_environment(log, "analytic table 1")  # a full disk: one line saying so
params = ValveParams(**snakemake.params.nominal)
table = threshold_table(snakemake.params.selected, params)
write_csv(table, snakemake.output.table)
log.info("table 1: %d settings -> %s\n%s", len(table), snakemake.output.table, table)
