"""Re-simulate every run of a dataset with its identified parameters; FIT table and overlays."""

from pathlib import Path

from spa.datasets import read_runs
from spa.io import get_logger, read_params, write_csv
from spa.pipeline.status import run_stage
from spa.plots.identification import validation_data, validation_figure
from spa.plots.save import draw
from spa.validation import validate_run, validate_runs, with_fit_before_refinement

log = get_logger("validate_model", snakemake.log[0])


def main() -> None:
    runs, metas = read_runs(snakemake.input.runs)
    params = read_params(snakemake.input.params)
    modulators = {rid: meta.get("modulator") for rid, meta in metas.items()}
    kinds = {rid: meta["kind"] for rid, meta in metas.items()}
    table = validate_runs(runs, params, modulators, kinds)
    table = with_fit_before_refinement(table, runs, snakemake.input.params, modulators, kinds)
    write_csv(table.drop(columns="p0"), snakemake.output.fit)
    for row in table.itertuples():
        log.info("%s: FIT %.2f %%", row.run, row.fit_percent)
    for rid, why in table.attrs.get("not_replayed", {}).items():
        log.warning("%s: not replayed: %s", rid, why)

    if snakemake.output.get("figures") is None:  # the run draws no figures for this dataset
        return
    figures = Path(snakemake.output.figures)
    figures.mkdir(parents=True, exist_ok=True)
    worst = table.loc[table.groupby("kind")["fit_percent"].idxmin()]  # the lowest FIT of each kind
    for row in worst.itertuples():
        data = validation_data(validate_run(runs[row.run], params, modulators[row.run]))
        write_csv(data, figures / f"{row.kind}.csv")
        title = f"{row.kind}: run {row.run} (lowest FIT of its kind, {row.fit_percent:.1f} %)"
        draw(figures / f"{row.kind}.png", validation_figure, data, title=title)


run_stage(snakemake, "validate_model", main, log)
