# Helpers that compute targets from the config. No analysis here: that lives in spa/.
import re
from pathlib import Path

from spa.config import validate_config
from spa.io import package_digest

validate_config(
    config, Path(workflow.basedir) / "workflow" / "schemas" / "config.schema.yaml"
)

RESULTS = config.get("results", "results")
# Passed to every job as `params: code=...`: editing spa/ reruns the jobs (a params change).
SPA_CODE = package_digest()
RAW_DIR = Path(config["datasets"]["raw_dir"])


def _raw_datasets():
    """Folders of raw_dir holding a dataset.yaml, filtered by datasets.include/exclude."""
    found = sorted(p.parent.name for p in RAW_DIR.glob("*/dataset.yaml"))
    wanted = config["datasets"].get("include") or []
    exclude = set(config["datasets"].get("exclude") or [])
    missing = [d for d in wanted if d not in found]
    if missing:
        raise ValueError(
            f"config datasets.include names {missing}, but {RAW_DIR}/ has no such folder "
            f"with a dataset.yaml (found: {found})"
        )
    chosen = wanted or found
    return [d for d in chosen if d not in exclude]


RAW_DATASETS = _raw_datasets()
SIM_DATASETS = sorted(config["simulated"])
_clash = sorted(set(RAW_DATASETS) & set(SIM_DATASETS))
if _clash:
    raise ValueError(
        f"dataset name(s) {_clash} are both simulated (config simulated:) and in {RAW_DIR}/; "
        "rename one or list it under datasets.exclude"
    )
DATASETS = SIM_DATASETS + RAW_DATASETS


def _one_of(names):
    """A wildcard constraint matching exactly these names (or nothing)."""
    return "|".join(re.escape(n) for n in names) if names else "(?!x)x"


def raw_files(wildcards):
    """Every file of a raw dataset folder, so that a change to any of them reruns its jobs."""
    folder = RAW_DIR / wildcards.dataset
    return sorted(str(p) for p in folder.rglob("*") if p.is_file())


def analytic_targets():
    out = Path(RESULTS) / "analytic"
    names = ["table1.csv", "table2.csv", "fig4.png", "fig4.csv", "fig5.png", "fig5.csv"]
    return [str(out / n) for n in names]


def dataset_targets():
    per_dataset = [
        "runs",
        "identification/params.yaml",
        "identification/fig2a.png",
        "identification/fig2b.png",
        "identification/fig2c.png",
        "validation/fit.csv",
        "validation/figures",
        "staircase/table3.csv",
        "staircase/levels.csv",
        "staircase/time_constants.csv",
        "staircase/fig6.png",
        "staircase/fig7a.png",
        "staircase/fig7b.png",
        "sine/linearity.csv",
        "sine/fig8.png",
        "chirp/bicoherence.csv",
        "chirp/fig9.png",
        "tuning/table1.csv",
        "tuning/table2.csv",
        "tuning/fig4.png",
        "tuning/fig5.png",
        "tuning/recommendation.yaml",
    ]
    return [f"{RESULTS}/{d}/{name}" for d in DATASETS for name in per_dataset]
