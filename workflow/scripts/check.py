"""Fail the run, naming them, when any dataset failed; else write results/status.yaml, with
each dataset stage "reused" (from the results' store) or "computed" (spa.pipeline.reuse).

First, every output of the run is recorded (size, time, sha256: spa.pipeline.provenance), so
that the next run rebuilds any output changed in between.
"""

import logging
import sys
from pathlib import Path

from spa.io import dump_yaml, get_logger
from spa.pipeline.outputs import all_targets
from spa.pipeline.provenance import record_outputs
from spa.pipeline.status import (
    dataset_failures,
    failure_summary,
    guard_environment,
    reuse_summary,
)

log = get_logger("check", snakemake.log[0], console=logging.INFO)  # the run's summary
guard_environment(log, "the check")  # a full disk: one line saying so
out = Path(snakemake.output.status)
datasets, figures = snakemake.params.datasets, snakemake.params.figures
vectors = "svg" in snakemake.config.get("figure_formats", ["png"])
targets = all_targets(out.parent, datasets, exclude=["check"], figures=figures, vectors=vectors)
record_outputs(targets, snakemake.params.ledger)
failures = dataset_failures(out.parent, snakemake.params.datasets)
if failures:
    text = failure_summary(failures)
    log.error("%d of %d datasets failed:\n%s", len(failures), len(snakemake.params.datasets), text)
    print(f"spa: {len(failures)} dataset(s) failed (see the report):\n{text}", file=sys.stderr)
    sys.exit(1)
# per dataset and stage: "reused" from the results' store or "computed" (spa.pipeline.reuse)
stages = reuse_summary(out.parent, datasets)
out.write_text(dump_yaml({"datasets": list(datasets), "failed": [], "stages": stages}))
reused = sum(how == "reused" for record in stages.values() for how in record.values())
total = sum(len(record) for record in stages.values())
log.info("all %d datasets complete (%d of %d stages reused)", len(datasets), reused, total)
