"""Several stages of one dataset in one job (spa.pipeline.jobs): ingest.smk, analyse.smk.

Runs each stage's own script in turn (``params.stages``: stage -> script name), each seeing
as ``snakemake`` a view of this job that holds its outputs, log and settings alone, and the
outputs of the stages it reads as inputs (spa.pipeline.jobs.stage_job). First, figures that
the job does not draw but an earlier run left are removed (config `figures`). With
``params.store`` (the analysis job), a stage whose digest is in the results' store is restored
from it instead of run (spa.pipeline.reuse; config `reuse: false` recomputes every stage).
"""

import runpy
from pathlib import Path

from spa.pipeline.jobs import read_files, remove_undrawn_figures, stage_job
from spa.pipeline.outputs import dataset_folder, get_stage
from spa.pipeline.reuse import file_digest, run_or_reuse

remove_undrawn_figures(snakemake)
stages = snakemake.params.stages
store = bool(snakemake.params.get("store"))
enabled = bool((getattr(snakemake, "config", None) or {}).get("reuse", True))
memo = {}


def digest(path, status=False):
    """file_digest, once per file and job (an earlier stage's outputs do not change)."""
    key = (str(path), status)
    if key not in memo:
        memo[key] = file_digest(path, status)
    return memo[key]


for stage, script in stages.items():
    view = stage_job(snakemake, stage)
    path = Path(snakemake.scriptdir) / f"{script}.py"

    def run(path=path, view=view):
        runpy.run_path(str(path), init_globals={"snakemake": view}, run_name="__main__")

    if not store:
        run()
        continue
    folder = dataset_folder(stage, dict(view.output.items()))
    raw = Path(str(snakemake.params.get("raw_dir", ""))) / str(snakemake.wildcards.dataset)
    run_or_reuse(
        view,
        stage,
        path,
        run,
        results=folder.parent,
        reads=read_files(snakemake, stage),
        raw={name: raw / name for name in get_stage(stage).raw_files},
        enabled=enabled,
        digest=digest,
    )
