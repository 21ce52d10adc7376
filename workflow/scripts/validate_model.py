"""Re-simulate every run of a dataset with its identified parameters; FIT table and overlays."""

from pathlib import Path

import pandas as pd
import yaml

from spa.identification import load_params
from spa.io import get_logger, read_runs, save_figure, write_csv
from spa.plots.identification import validation_data, validation_figure
from spa.validation import validate_run

log = get_logger("validate_model", snakemake.log[0])
runs, metas = read_runs(snakemake.input.runs)
with open(snakemake.input.params) as fh:
    params = load_params(yaml.safe_load(fh))
rows, worst = [], {}
for rid, table in runs.items():
    meta = metas[rid]
    mod = meta.get("modulator")
    res = validate_run(table, params, mod)
    setting = "" if not mod else " ".join(f"{k}={v:g}" for k, v in mod.items() if k != "type")
    rows.append(
        {
            "run": rid,
            "kind": meta["kind"],
            "modulator": mod["type"] if mod else "",
            "setting": setting,
            "fit_percent": res.fit_percent,
            "rmse": res.rmse,
            "max_abs_error": res.max_abs_error,
            "n": res.n,
        }
    )
    log.info("%s: FIT %.2f %%", rid, res.fit_percent)
    kind = meta["kind"]
    if kind not in worst or res.fit_percent < worst[kind][0]:
        worst[kind] = (res.fit_percent, rid, res)
write_csv(pd.DataFrame(rows), snakemake.output.fit)
figures = Path(snakemake.output.figures)
figures.mkdir(parents=True, exist_ok=True)
for kind, (fit, rid, res) in sorted(worst.items()):
    data = validation_data(res)
    write_csv(data, figures / f"{kind}.csv")
    title = f"{kind}: run {rid} (lowest FIT of its kind, {fit:.1f} %)"
    save_figure(validation_figure(data, title=title), figures / f"{kind}.png")
