"""Write the report's index (results/report/index.html, and results/report.html with its links
into report/) and its analytic page (results/report/analytic.html); each dataset's page is
written by its own job (page.py). The pages of datasets no longer in the run are removed."""

from pathlib import Path

import spa
from spa.io import get_logger, peak_rss_mib
from spa.pipeline.status import guard_environment
from spa.report.site import build_analytic_page, build_index, remove_stale_pages

log = get_logger("report", snakemake.log[0])
guard_environment(log, "the report")  # a full disk: one line saying so
out = snakemake.output
results = Path(out.report).parent  # the rule writes {RESULTS}/report.html
meta = {"seed": snakemake.params.seed, "spa version": spa.__version__}
datasets = snakemake.params.datasets
pages = {
    out.index: build_index(results, datasets, meta),
    out.report: build_index(results, datasets, meta, prefix="report/"),
    out.analytic: build_analytic_page(results, meta),
}
for path, text in pages.items():
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    Path(path).write_text(text, encoding="utf-8", newline="\n")
    log.info("wrote %s (%.0f KB, %d figures)", path, len(text.encode()) / 1024, text.count("<img "))
for stale in remove_stale_pages(Path(out.index).parent, datasets):  # no longer in raw/
    log.info("removed %s: its dataset is no longer in the run", stale)
log.info("peak RSS of the job: %.0f MiB", peak_rss_mib())
