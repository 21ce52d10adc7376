"""A dataset's page of the report (results/report/<dataset>.html) and its overview row."""

from pathlib import Path

import spa
from spa.io import get_logger, peak_rss_mib
from spa.report.overview import overview_row, rig_label, write_row
from spa.report.site import build_dataset_page
from spa.status import dataset_failures, run_stage

log = get_logger("page", snakemake.log[0])


def main() -> None:
    dataset = str(snakemake.wildcards.dataset)
    page = Path(snakemake.output.page)
    results = page.parent.parent  # the rule writes {RESULTS}/report/{dataset}.html
    # the job draws its figures when its earlier stages' outputs include them (config figures)
    drawn = any(str(path).endswith(".png") for path in snakemake.input)
    recorded, rig = spa_session(dataset)
    meta = {"seed": snakemake.params.seed, "spa version": spa.__version__}
    text = build_dataset_page(results, dataset, meta, drawn=drawn)
    page.parent.mkdir(parents=True, exist_ok=True)
    page.write_text(text, encoding="utf-8", newline="\n")
    failed = [
        r for r in dataset_failures(results, [dataset]).get(dataset, []) if r["stage"] != "page"
    ]
    first = next((r["stage"] for r in failed if not r.get("upstream")), None)
    write_row(snakemake.output.row, overview_row(results / dataset, dataset, recorded, rig, first))
    log.info(
        "wrote %s (%.0f KB, %d figures); peak RSS of the job so far %.0f MiB",
        page, len(text.encode()) / 1024, text.count("<img "), peak_rss_mib(),
    )  # fmt: skip


def spa_session(dataset: str) -> tuple[str | None, str]:
    """The session's date and rig from raw/<dataset>/dataset.yaml; a simulated dataset has
    neither (rig "simulated")."""
    from spa.datasets import DatasetError, load_spec

    folder = Path(snakemake.params.raw_dir) / dataset
    if not (folder / "dataset.yaml").is_file():
        return None, "simulated"
    try:
        spec = load_spec(folder)
    except DatasetError:
        return None, "unnamed rig"
    return spec.recorded, rig_label(spec.rig)


run_stage(snakemake, "page", main, log)
