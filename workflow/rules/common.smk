# Names the workflow uses, all from spa: the datasets of the run (spa.config), each stage's
# output and log files (spa.outputs), the digest of spa's code. No logic and no paths here.
from pathlib import Path

from snakemake.exceptions import WorkflowError
from snakemake.logging import logger

from spa._guard import ShadowedPackageError, check_package

# A clone folder named `spa` in the current folder shadows the package: say so, first.
try:
    check_package()
except ShadowedPackageError as _exc:
    raise WorkflowError(str(_exc)) from None

from spa.config import discover_datasets, figure_datasets, validate_config
from spa.io import package_digest
from spa.jobs import joined_outputs
from spa.provenance import dataset_digest, remove_damaged_run_folders
from spa.outputs import all_targets, log_path, stage_outputs, wildcard_choice
from spa.safety import check_results_dir
from spa.workflow_report import report_flags

validate_config(
    config, Path(workflow.basedir) / "workflow" / "schemas" / "config.schema.yaml"
)

RESULTS = config.get("results", "results")
# Captions of the tables and figures in `snakemake --report` (spa.workflow_report).
CAPTIONS = Path(workflow.basedir) / "workflow" / "report"
# Refuse, before anything runs, a results folder that overlaps raw data (spa.safety).
check_results_dir(RESULTS, config["datasets"]["raw_dir"])
# Passed to every job as `params: code=...`: editing spa/ reruns the jobs (a params change).
SPA_CODE = package_digest()
RAW_DIR = Path(config["datasets"]["raw_dir"])
SIM_DATASETS, RAW_DATASETS = discover_datasets(config)
DATASETS = SIM_DATASETS + RAW_DATASETS
# The datasets whose figures are drawn (config `figures`: all, none or a list).
FIGURE_DATASETS = figure_datasets(config, DATASETS)


def outputs(stage, figures=True):
    """A stage's named outputs (spa.outputs.STAGES), folders marked for Snakemake, tables
    and figures marked for `snakemake --report` with their captions (spa.workflow_report);
    without its figures when `figures` is False.
    """
    paths = stage_outputs(stage, RESULTS, mark_directory=directory, figures=figures)
    for key, flags in report_flags(stage, CAPTIONS).items():
        if key in paths:
            paths[key] = report(paths[key], **flags)
    return paths


def inputs_from(stage):
    """A stage's outputs as another rule's inputs, whichever rule writes them."""
    return stage_outputs(stage, RESULTS)


def logfile(rule):
    """The log file of a rule (spa.outputs.STAGES)."""
    return log_path(rule, RESULTS)


# Digests of raw files, remembered by stat between runs (spa.provenance).
DIGEST_CACHE = str(Path(".snakemake") / "spa" / "raw-digests.json")


def raw_digest(wildcards):
    """The content digest of a bench dataset folder (a parameter: reruns on content only)."""
    return dataset_digest(RAW_DIR / wildcards.dataset, cache=DIGEST_CACHE)


# A folder of run tables that lost or changed a member is removed, so that it is rebuilt.
for _folder, _why in remove_damaged_run_folders(
    RESULTS, [stage_outputs("runs", RESULTS, d)["runs"] for d in DATASETS]
).items():
    logger.warning(f"{_folder}: {_why}; the folder is rebuilt")
