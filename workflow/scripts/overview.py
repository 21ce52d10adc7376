"""The overview across datasets (results/overview.csv) and Fig. O1 (results/overview.png)."""

from pathlib import Path

from spa._memo import use_folder
from spa.io import get_logger, peak_rss_mib, write_csv
from spa.pipeline.reuse import code_digest
from spa.pipeline.status import guard_environment
from spa.pipeline.store import MEMO, STORE
from spa.plots.save import draw
from spa.report.overview import overview_table, read_rows
from spa.report.overview_figure import plot_overview
from spa.report.params import PARAM_NAMES

log = get_logger("overview", snakemake.log[0])
guard_environment(log, "the overview")  # a full disk: one line saying so
# Fig. O1 of the same table is copied from the results' store, not drawn (spa._memo)
if (getattr(snakemake, "config", None) or {}).get("reuse", True):
    use_folder(Path(snakemake.output.table).parent / STORE / MEMO, code_digest())
table = overview_table(read_rows(snakemake.input.rows))
write_csv(table, snakemake.output.table)
draw(snakemake.output.figure, plot_overview, table)
for p in PARAM_NAMES:
    changed = table.loc[table[f"changed_{p}"], "dataset"].tolist()
    if changed:
        log.warning("%s changed (interval excludes the previous session's) at %s", p, changed)
log.info("overview of %d datasets", len(table))
log.info("peak RSS of the job: %.0f MiB", peak_rss_mib())
