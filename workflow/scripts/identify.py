"""Identify c1, k2, tau2, t_on, t_off of one dataset; write params.yaml and Fig. 2."""

from spa.datasets import read_runs
from spa.datasets.checks import k2_warning
from spa.identification import identify_with_config
from spa.io import get_logger
from spa.pipeline.status import run_stage
from spa.stages.identify import write_identification

log = get_logger("identify", snakemake.log[0])


def main() -> list[str]:
    dataset = snakemake.wildcards.dataset
    runs, metas = read_runs(snakemake.input.runs)
    kinds = {rid: m["kind"] for rid, m in metas.items()}
    config = {"identification": snakemake.params.cfg, "nominal": snakemake.params.nominal}
    settings = {**config, "seed": snakemake.params.seed}
    result = identify_with_config(
        runs, kinds, settings, metas=metas
    )
    for name, reason in result.fallback.items():
        log.warning("%s: FALLBACK to the nominal value for %s: %s", dataset, name, reason)
    write_identification(result, runs, kinds, snakemake.output, dataset, log)
    supply = snakemake.params.get("supply")
    notes = [w for w in [k2_warning(result.to_valve_params().k2, metas, supply)] if w]
    notes += list(result.warnings)
    for note in notes:
        log.warning("%s: %s", dataset, note)
    return notes


run_stage(snakemake, "identify", main, log)
