# One self-contained HTML page with every table and figure of the run (results/report.html):
# figures embedded, no script, no external resource, so it opens offline in any browser.


rule report:
    input:
        all_targets(RESULTS, DATASETS, exclude=["report"]),
    output:
        **outputs("report"),
    log:
        logfile("report"),
    threads: 1
    resources:
        mem_mb=1000,
        runtime=5,
    params:
        datasets=DATASETS,
        seed=lookup(dpath="seed", within=config),
        code=SPA_CODE,
    script:
        "../scripts/report.py"
