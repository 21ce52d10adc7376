"""Write results/report.html: every table and figure of the run in one offline HTML page."""

from pathlib import Path

import spa
from spa.io import get_logger
from spa.report import build_report
from spa.status import guard_environment

log = get_logger("report", snakemake.log[0])
guard_environment(log, "the report")  # a full disk: one line saying so
out = Path(snakemake.output.report)
results = out.parent  # the rule writes {RESULTS}/report.html
meta = {"seed": snakemake.params.seed, "spa version": spa.__version__}
text = build_report(results, snakemake.params.datasets, meta, figures=snakemake.params.figures)
with open(out, "w", encoding="utf-8", newline="\n") as fh:
    fh.write(text)
log.info(
    "wrote %s (%.0f KB, %d figures, %d tables)",
    out,
    len(text.encode()) / 1024,
    text.count("<img "),
    text.count("<table>"),
)
