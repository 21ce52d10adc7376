"""Identify c1, k2, tau2, t_on, t_off of one dataset; write params.yaml and Fig. 2."""

import yaml

from spa.datasets.checks import k2_warning
from spa.identification import identify_with_config
from spa.io import get_logger, read_runs, write_csv
from spa.plots.identification import fig2a, fig2a_data, fig2b, fig2b_data, fig2c, fig2c_data
from spa.plots.openloop import write_no_runs
from spa.plots.save import draw
from spa.status import run_stage
from spa.validation import validate_run

log = get_logger("identify", snakemake.log[0])


def main() -> list[str]:
    out = snakemake.output
    supply = snakemake.params.get("supply")
    runs, metas = read_runs(snakemake.input.runs)
    kinds = {rid: m["kind"] for rid, m in metas.items()}
    config = {
        "identification": snakemake.params.cfg,
        "nominal": snakemake.params.nominal,
        "seed": snakemake.params.seed,
    }
    result = identify_with_config(runs, kinds, config)
    for name, reason in result.fallback.items():
        log.warning(
            "%s: FALLBACK to the nominal value for %s: %s",
            snakemake.wildcards.dataset,
            name,
            reason,
        )
    with open(out.params, "w") as fh:
        yaml.safe_dump(result.to_dict(), fh, sort_keys=False)
    log.info("identified %s", result.to_valve_params())
    notes = [w for w in [k2_warning(result.to_valve_params().k2, metas, supply)] if w]
    for note in notes:
        log.warning("%s: %s", snakemake.wildcards.dataset, note)

    dataset = snakemake.wildcards.dataset
    fallback = "; ".join(f"{k} from the fallback" for k in result.fallback)
    for data_fn, fig_fn, fit, png, csv, kind in (
        (fig2a_data, fig2a, result.charge, out.get("fig2a"), out.fig2a_csv, "charge"),
        (fig2b_data, fig2b, result.discharge, out.get("fig2b"), out.fig2b_csv, "discharge"),
    ):
        if fit is None:
            write_no_runs(f"{dataset}: no {kind} fit ({fallback})", [csv], [png])
            continue
        data = data_fn(fit)
        write_csv(data, csv)
        draw(png, fig_fn, data)

    pulse_ids = sorted(r for r, k in kinds.items() if k == "pulse")
    if not pulse_ids:
        write_no_runs(f"{dataset}: no pulse runs ({fallback})", [out.fig2c_csv], [out.get("fig2c")])
        return notes
    trace = validate_run(runs[pulse_ids[0]], result.to_valve_params()).trace
    data = fig2c_data(trace)
    write_csv(data, out.fig2c_csv)
    draw(out.get("fig2c"), fig2c, data)
    return notes


run_stage(snakemake, "identify", main, log)
