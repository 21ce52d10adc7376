"""A dataset's page of the report (results/report/<dataset>.html) and its overview row."""

from pathlib import Path

import spa
from spa.io import get_logger, peak_rss_mib
from spa.pipeline.status import dataset_failures, run_stage
from spa.report.overview import dataset_session, dataset_valve, overview_row, write_row
from spa.report.site import build_dataset_page

log = get_logger("page", snakemake.log[0])


def main() -> None:
    dataset = str(snakemake.wildcards.dataset)
    page = Path(snakemake.output.page)
    results = page.parent.parent  # the rule writes {RESULTS}/report/{dataset}.html
    # the job draws its figures when its earlier stages' outputs include them (config figures)
    drawn = any(str(path).endswith(".png") for path in snakemake.input)
    meta = {"seed": snakemake.params.seed, "spa version": spa.__version__}
    raw = snakemake.params.raw_dir
    text = build_dataset_page(results, dataset, meta, drawn=drawn, raw_dir=raw)
    page.parent.mkdir(parents=True, exist_ok=True)
    page.write_text(text, encoding="utf-8", newline="\n")
    failed = dataset_failures(results, [dataset]).get(dataset, [])
    first = next(
        (r["stage"] for r in failed if r["stage"] != "page" and not r.get("upstream")), None
    )
    recorded, rig = dataset_session(snakemake.params.raw_dir, dataset)
    valve = dataset_valve(snakemake.params.raw_dir, dataset)
    row = overview_row(results / dataset, dataset, recorded, rig, first, valve=valve)
    write_row(snakemake.output.row, row)
    size = len(text.encode()) / 1024
    log.info("wrote %s (%.0f KB); peak RSS of the job so far %.0f MiB", page, size, peak_rss_mib())


run_stage(snakemake, "page", main, log)
