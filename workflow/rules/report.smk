# One self-contained HTML page with every table and figure of the run (results/report.html):
# figures embedded, no script, no external resource, so it opens offline in any browser.
# It holds every dataset's figures: its memory grows by about 15 MB a dataset (1.46 GB peak
# for 100 datasets, benchmarks/README.md), which its resources follow for a cluster.


rule report:
    input:
        all_targets(
            RESULTS, DATASETS, exclude=["report", "check"], figures=FIGURE_DATASETS
        ),
    output:
        **outputs("report"),
    log:
        logfile("report"),
    threads: 1
    resources:
        mem_mb=1000 + 20 * len(DATASETS),
        runtime=5 + len(DATASETS) // 10,
    params:
        datasets=DATASETS,
        figures=FIGURE_DATASETS,
        seed=lookup(dpath="seed", within=config),
        code=SPA_CODE,
    script:
        "../scripts/report.py"


# The last job of reproduce-all: exits non-zero, naming them, when a dataset failed. Their
# placeholders let every other dataset and the report be built first (spa.status). The
# report's inputs are every output of the run, so the report alone is this rule's input:
# each file is named once in the DAG (with 100 datasets, 1.5 s less to build it).
rule check:
    input:
        **inputs_from("report"),
    output:
        **outputs("check"),
    log:
        logfile("check"),
    threads: 1
    resources:
        mem_mb=500,
        runtime=5,
    params:
        datasets=DATASETS,
        figures=FIGURE_DATASETS,
        ledger=OUTPUT_LEDGER,
        code=SPA_CODE,
    script:
        "../scripts/check.py"
