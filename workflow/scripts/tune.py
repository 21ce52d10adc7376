"""Tune the modulators for one dataset's identified valve; tables, figures, recommendation."""

import yaml

from spa.io import get_logger, write_csv
from spa.plots.save import draw
from spa.plots.tuning import plot_tuning_equilibrium, plot_tuning_sweeps
from spa.status import run_stage
from spa.tuning import tune

log = get_logger("tune", snakemake.log[0])


def main() -> None:
    out = snakemake.output
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
    write_csv(result.table1, out.table1)
    write_csv(result.table2, out.table2)
    write_csv(result.sweeps, out.fig4_csv)
    draw(
        out.get("fig4"),
        plot_tuning_sweeps,
        result.sweeps,
        title=dataset,
        params=result.identified.params,
    )
    write_csv(result.curves, out.fig5_csv)
    draw(out.get("fig5"), plot_tuning_equilibrium, result.curves)
    with open(out.recommendation, "w") as fh:
        yaml.safe_dump(dict(result.recommendation), fh, sort_keys=False, allow_unicode=True)
    log.info("%s: %s", dataset, result.sentence)


run_stage(snakemake, "tune", main, log)
