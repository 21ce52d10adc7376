# The report is a small static site (spa.report.site): each dataset's page,
# results/report/<dataset>.html, is written in that dataset's own job (analyse.smk, stage
# `page`, with its row of the overview); this rule writes the index (results/report/index.html,
# and results/report.html with its links into report/) and the analytic page. The index embeds
# Fig. O1 alone and reads a few small files per dataset: its memory stays about flat in the
# number of datasets (benchmarks/README.md).


# The overview across datasets: results/overview.csv (one row per dataset, in session order)
# and Fig. O1 (the identified valve against the session's date), from each dataset's row.
rule overview:
    input:
        rows=expand(inputs_from("page")["row"], dataset=DATASETS),
    output:
        **outputs("overview"),
    log:
        logfile("overview"),
    threads: 1
    resources:
        mem_mb=500,
        runtime=5,
    params:
        code=SPA_CODE,
    script:
        "../scripts/overview.py"


rule report:
    input:
        # every output but the report's and the check's (ALL_OUTPUTS less the report's)
        without(ALL_OUTPUTS, stage_outputs("report", RESULTS).values()),
    output:
        **outputs("report"),
    log:
        logfile("report"),
    threads: 1
    resources:
        mem_mb=500,
        runtime=5,
    params:
        datasets=DATASETS,
        seed=lookup(dpath="seed", within=config),
        code=SPA_CODE,
    script:
        "../scripts/report.py"


# The last job of reproduce-all: exits non-zero, naming them, when a dataset failed. Their
# placeholders let every other dataset and the report be built first (spa.pipeline.status). The
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
