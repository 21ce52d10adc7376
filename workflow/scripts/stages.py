"""Several stages of one dataset in one job (spa.pipeline.jobs): ingest.smk, analyse.smk.

Runs each stage's own script in turn (``params.stages``: stage -> script name), each seeing
as ``snakemake`` a view of this job that holds its outputs, log and settings alone, and the
outputs of the stages before it as inputs (spa.pipeline.jobs.stage_job). First, figures that the job
does not draw but an earlier run left are removed (config `figures`); the figures it draws
are saved in the formats of config `figure_formats` (default PNG alone).
"""

import runpy
from pathlib import Path

from spa.pipeline.jobs import remove_undrawn_figures, stage_job
from spa.plots.save import set_figure_formats

remove_undrawn_figures(snakemake)
set_figure_formats(snakemake.config.get("figure_formats", ["png"]))
for stage, script in snakemake.params.stages.items():
    runpy.run_path(
        str(Path(snakemake.scriptdir) / f"{script}.py"),
        init_globals={"snakemake": stage_job(snakemake, stage)},
        run_name="__main__",
    )
