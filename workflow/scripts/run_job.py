"""Several stages of one dataset in one job (spa.pipeline.jobs): ingest.smk, analyse.smk.

Runs each stage's own script in turn (``params.stages``: stage -> script name), each seeing
as ``snakemake`` a view of this job that holds its outputs, log and settings alone, and the
outputs of the stages it reads as inputs (spa.pipeline.jobs.stage_job). First, figures that
the job does not draw but an earlier run left are removed (config `figures`); the figures it
draws are saved in the formats of config `figure_formats` (default PNG alone). With
``params.store`` (the analysis job), a stage whose digest is in the results' store is restored
from it instead of run (spa.pipeline.reuse; config `reuse: false` recomputes every stage).
Where and how the job ran (executor, SLURM job id, node, elapsed time, peak memory) goes to
the dataset's execution record (spa.pipeline.execution).
"""

from spa.pipeline.execution import recorded_job
from spa.pipeline.jobs import remove_undrawn_figures
from spa.pipeline.reuse import run_job
from spa.plots.save import set_figure_formats

remove_undrawn_figures(snakemake)
set_figure_formats(snakemake.config.get("figure_formats", ["png"]))
with recorded_job(snakemake):  # results/<dataset>/provenance/execution.json
    run_job(snakemake, snakemake.scriptdir)
