# Every dataset becomes results/<name>/runs/<run id>.parquet in the canonical form:
# simulated ones from the model, bench ones from raw/<name>/ (never written).


rule simulate_dataset:
    output:
        **outputs("runs"),
    log:
        logfile("simulate_dataset"),
    wildcard_constraints:
        dataset=wildcard_choice(SIM_DATASETS),
    threads: 1
    resources:
        mem_mb=2000,
        runtime=15,
    params:
        code=SPA_CODE,
        cfg=lambda w: config["simulated"][w.dataset],
        experiments=config["experiments"],
        seed=config["seed"],
    script:
        "../scripts/simulate_dataset.py"


rule ingest_dataset:
    input:
        raw_files,
    output:
        **outputs("runs"),
    log:
        logfile("ingest_dataset"),
    wildcard_constraints:
        dataset=wildcard_choice(RAW_DATASETS),
    threads: 1
    resources:
        mem_mb=2500,
        runtime=30,
    params:
        code=SPA_CODE,
        folder=lambda w: str(RAW_DIR / w.dataset),
    script:
        "../scripts/ingest_dataset.py"
