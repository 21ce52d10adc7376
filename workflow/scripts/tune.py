"""Tune the modulators for one dataset's identified valve; tables, figures, recommendation."""

from spa.io import get_logger
from spa.pipeline.status import run_stage
from spa.stages.tune import write_tuning
from spa.tuning import tune

log = get_logger("tune", snakemake.log[0])


def main() -> None:
    dataset = snakemake.wildcards.dataset
    result = tune(
        snakemake.input.params,
        sweeps=snakemake.params.sweeps,
        n_xi=snakemake.params.n_xi,
        options=snakemake.params.tuning,
        selected=snakemake.params.selected,
        linearity=snakemake.params.linearity,
    )
    for name, reason in result.identified.fallback.items():
        log.warning(
            "%s: %s is the nominal value (identification fallback: %s)", dataset, name, reason
        )
    for name, note in result.identified.clipped.items():
        log.warning("%s: %s interval: %s", dataset, name, note)
    for why in filter(None, result.table1["unusable"]):
        log.warning("%s: left out: %s", dataset, why)
    write_tuning(result, snakemake.output, dataset)
    log.info("%s: %s", dataset, result.sentence)


run_stage(snakemake, "tune", main, log)
