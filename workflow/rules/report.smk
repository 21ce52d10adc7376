# One self-contained HTML page with every table and figure of the run (results/report.html):
# figures embedded, no script, no external resource, so it opens offline in any browser.


rule report:
    input:
        analytic_targets(),
        dataset_targets(),
    output:
        report=f"{RESULTS}/report.html",
    log:
        f"{RESULTS}/logs/report.log",
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
