# Names the workflow uses, all from spa: the datasets of the run (spa.config), each stage's
# output and log files (spa.outputs), the digest of spa's code. No logic and no paths here.
from pathlib import Path

from spa.config import dataset_files, discover_datasets, validate_config
from spa.io import package_digest
from spa.outputs import all_targets, log_path, stage_outputs, wildcard_choice

validate_config(
    config, Path(workflow.basedir) / "workflow" / "schemas" / "config.schema.yaml"
)

RESULTS = config.get("results", "results")
# Passed to every job as `params: code=...`: editing spa/ reruns the jobs (a params change).
SPA_CODE = package_digest()
RAW_DIR = Path(config["datasets"]["raw_dir"])
SIM_DATASETS, RAW_DATASETS = discover_datasets(config)
DATASETS = SIM_DATASETS + RAW_DATASETS


def outputs(stage):
    """A stage's named outputs (spa.outputs.STAGES), folders marked for Snakemake."""
    return stage_outputs(stage, RESULTS, mark_directory=directory)


def inputs_from(stage):
    """A stage's outputs as another rule's inputs, whichever rule writes them."""
    return stage_outputs(stage, RESULTS)


def logfile(rule):
    """The log file of a rule (spa.outputs.STAGES)."""
    return log_path(rule, RESULTS)


def raw_files(wildcards):
    """Every file of a raw dataset folder, so that a change to any of them reruns its jobs."""
    return dataset_files(RAW_DIR, wildcards.dataset)
