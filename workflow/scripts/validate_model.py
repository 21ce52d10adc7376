"""Re-simulate every run of a dataset with its identified parameters; FIT table and overlays."""

from pathlib import Path

import yaml

from spa.io import get_logger, read_params, read_runs, write_csv
from spa.model.params import ValveParams
from spa.pipeline.status import run_stage
from spa.plots.identification import validation_data, validation_figure
from spa.plots.save import draw
from spa.validation import validate_run, validate_runs

log = get_logger("validate_model", snakemake.log[0])


def main() -> None:
    runs, metas = read_runs(snakemake.input.runs)
    params = read_params(snakemake.input.params)
    modulators = {rid: meta.get("modulator") for rid, meta in metas.items()}
    table = validate_runs(
        runs, params, modulators, {rid: meta["kind"] for rid, meta in metas.items()}
    )
    with open(snakemake.input.params) as fh:
        start = ((yaml.safe_load(fh) or {}).get("refinement") or {}).get("start")
    if start:  # each run's FIT with the estimates before the refinement, beside the refined
        kinds = {rid: meta["kind"] for rid, meta in metas.items()}
        before = validate_runs(runs, ValveParams(**start), modulators, kinds)
        table.insert(
            table.columns.get_loc("fit_percent"),
            "fit_before_refinement",
            before["fit_percent"].to_numpy(),
        )
    write_csv(table.drop(columns="p0"), snakemake.output.fit)
    for row in table.itertuples():
        log.info("%s: FIT %.2f %%", row.run, row.fit_percent)

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
