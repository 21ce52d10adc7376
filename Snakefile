# spa: reproduce Serrano-Balbontín et al., Robotics 2025, 14(12), 177, and characterise new benches.
import os

from snakemake.utils import min_version

min_version("9.0")


configfile: "config/config.yaml"


# Every rule declares `threads: 1`, so a job's linear algebra stays on its one core: BLAS's
# own threads only fight the jobs Snakemake already runs side by side (the laws' fit costs
# 2.7 times the CPU with them on 2 cores, benchmarks/README.md). A value already set wins.
for _blas in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_blas, "1")


# The front page of `snakemake --report report.zip`; each table and figure has its own
# caption and category (workflow/report/, spa.pipeline.workflow_report).
report: "workflow/report/workflow.rst"


# `snakemake --lint` has one finding, "Specify a conda environment or container for each
# rule", for every rule; it is deliberately not followed. Every rule runs the same pinned
# Python environment (requirements.lock, installed by `make setup`; on a cluster, the same
# .venv on the shared file system), so a per-rule conda env would duplicate the lock file and
# could drift from it. tests/test_workflow.py checks that no other lint finding appears.
include: "workflow/rules/common.smk"
include: "workflow/rules/analytic.smk"
include: "workflow/rules/datasets.smk"
include: "workflow/rules/analyse.smk"
include: "workflow/rules/report.smk"


rule reproduce_all:
    name:
        "reproduce-all"
    default_target: True
    input:
        **inputs_from("check"),
        missing=MISSING_OUTPUTS,
