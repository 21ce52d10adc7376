"""One job for a dataset's model validation and open-loop analyses (characterise.smk).

Runs each stage's own script in turn, each seeing as ``snakemake`` a view of this job that
holds its outputs, log and settings alone (spa.jobs.stage_job).
"""

import runpy
from pathlib import Path

from spa.jobs import stage_job

for stage in snakemake.params.stages:
    runpy.run_path(
        str(Path(snakemake.scriptdir) / f"{stage}.py"),
        init_globals={"snakemake": stage_job(snakemake, stage)},
        run_name="__main__",
    )
