# Names the workflow uses, all from spa: the datasets of the run (spa.pipeline.config), each stage's
# output and log files (spa.pipeline.outputs), the digest of spa's code. No logic and no paths here.
import gc
from pathlib import Path

from snakemake.exceptions import WorkflowError
from snakemake.logging import logger

from spa._guard import ShadowedPackageError, check_package

# A clone folder named `spa` in the current folder shadows the package: say so, first.
try:
    check_package()
except ShadowedPackageError as _exc:
    raise WorkflowError(str(_exc)) from None

from spa.pipeline.config import discover_datasets, figure_datasets, validate_config
from spa.datasets.spec import undecodable_datasets
from spa.io import package_digest
from spa.pipeline.jobs import joined_outputs
from spa.pipeline.provenance import (
    dataset_digest,
    missing_outputs,
    output_ledger,
    remove_altered_outputs,
    remove_damaged_run_folders,
)
from spa.pipeline.outputs import (
    all_targets,
    job_stages,
    log_path,
    stage_outputs,
    stage_settings,
    wildcard_choice,
)
from spa.pipeline.reuse import JOB_GC_THRESHOLD
from spa.pipeline.safety import check_results_dir
from spa.pipeline.workflow_report import report_flags

# Snakemake builds a few thousand objects a dataset (jobs, files) over a heap of its imports:
# at the collector's default thresholds a dry run over 102 datasets spends 0.6 of its 4 CPU-s
# collecting garbage, at a job's thresholds 0.33 (benchmarks/README.md, "What every process
# pays").
gc.set_threshold(*JOB_GC_THRESHOLD)

validate_config(
    config, Path(workflow.basedir) / "workflow" / "schemas" / "config.schema.yaml"
)

RESULTS = config.get("results", "results")
# Captions of the tables and figures in `snakemake --report` (spa.pipeline.workflow_report).
CAPTIONS = Path(workflow.basedir) / "workflow" / "report"
# Refuse, before anything runs, a results folder that overlaps raw data (spa.pipeline.safety).
check_results_dir(RESULTS, config["datasets"]["raw_dir"])
# Passed to every job as `params: code=...`: editing spa/ reruns the jobs (a params change).
SPA_CODE = package_digest()
RAW_DIR = Path(config["datasets"]["raw_dir"])
SIM_DATASETS, RAW_DATASETS = discover_datasets(config)
for _name in undecodable_datasets(RAW_DIR):
    logger.warning(
        f"{RAW_DIR}/{_name}: skipped: a dataset's folder name must be UTF-8 text"
    )
DATASETS = SIM_DATASETS + RAW_DATASETS
# The datasets whose figures are drawn (config `figures`: all, none or a list).
FIGURE_DATASETS = figure_datasets(config, DATASETS)
# Whether a dataset's figures get SVG copies beside their PNGs (config `figure_formats`).
FIGURE_VECTORS = "svg" in config.get("figure_formats", ["png"])


def outputs(stage, figures=True):
    """A stage's named outputs (spa.pipeline.outputs.STAGES), folders marked for Snakemake, tables
    and figures marked for `snakemake --report` with their captions (spa.pipeline.workflow_report);
    without its figures when `figures` is False.
    """
    paths = stage_outputs(
        stage,
        RESULTS,
        mark_directory=directory,
        figures=figures,
        vectors=FIGURE_VECTORS,
    )
    for key, flags in report_flags(stage, CAPTIONS).items():
        if key in paths:
            paths[key] = report(paths[key], **flags)
    return paths


def inputs_from(stage):
    """A stage's outputs as another rule's inputs, whichever rule writes them."""
    return stage_outputs(stage, RESULTS)


def without(paths, drop):
    """``paths`` less those in ``drop``, in order."""
    drop = {str(p) for p in drop}
    return [p for p in paths if p not in drop]


def logfile(rule):
    """The log file of a rule (spa.pipeline.outputs.STAGES)."""
    return log_path(rule, RESULTS)


# Digests of raw files, remembered by stat between runs (spa.pipeline.provenance).
DIGEST_CACHE = str(Path(".snakemake") / "spa" / "raw-digests.json")


def raw_digest(wildcards):
    """The content digest of a bench dataset folder (a parameter: reruns on content only)."""
    return dataset_digest(RAW_DIR / wildcards.dataset, cache=DIGEST_CACHE)


# What the last complete run wrote: size, time and sha256 of every output (spa.pipeline.provenance),
# one file per results folder.
OUTPUT_LEDGER = output_ledger(RESULTS)
# An output changed since it was written is removed (a run table with its folder), and a
# folder of run tables that lost or gained a member too, so that they are rebuilt.
_RUN_FOLDERS = [stage_outputs("runs", RESULTS, d)["runs"] for d in DATASETS]
for _path, _why in {
    **remove_damaged_run_folders(RESULTS, _RUN_FOLDERS),
    **remove_altered_outputs(RESULTS, OUTPUT_LEDGER, _RUN_FOLDERS),
}.items():
    logger.warning(f"{_path}: {_why}; it is rebuilt")
# Every output of the run, and those of them that are missing: reproduce-all asks for the
# missing ones by name, since Snakemake does not rebuild a missing file whose downstream
# outputs are up to date (its issue 1978). Their jobs rerun, then everything downstream.
ALL_OUTPUTS = all_targets(
    RESULTS,
    DATASETS,
    exclude=["check"],
    figures=FIGURE_DATASETS,
    vectors=FIGURE_VECTORS,
)
# Not needed when the report and the check are missing too: they run and ask for every file.
MISSING_OUTPUTS = missing_outputs(
    ALL_OUTPUTS,
    downstream=[
        *stage_outputs("report", RESULTS).values(),
        *stage_outputs("check", RESULTS).values(),
    ],
)
