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


# A bench dataset from raw/<name>/, in one job: its manifest (every file's sha256), then its
# validated run tables. The `digest` parameter is computed when the DAG is built
# (spa.pipeline.provenance.dataset_digest, cached by stat), so the job reruns, and everything downstream
# with it, exactly when the content of raw/<name>/ changed: not when only a modification time
# moved, and also when a time went back with new content.
INGEST = job_stages("ingest")  # raw_manifest, then runs (script ingest_dataset)


rule ingest_dataset:
    output:
        **joined_outputs(INGEST, outputs),
    log:
        raw_manifest=logfile("raw_manifest"),
        runs=logfile("ingest_dataset"),
    wildcard_constraints:
        dataset=wildcard_choice(RAW_DATASETS),
    threads: 1
    resources:
        mem_mb=2500,
        runtime=30,
    params:
        code=SPA_CODE,
        digest=raw_digest,
        folder=lambda w: str(RAW_DIR / w.dataset),
        cache=DIGEST_CACHE,
        supply=lookup(
            dpath="datasets/plausible_supply_bar", within=config, default=[0.05, 20.0]
        ),
        stages=INGEST,
    script:
        "../scripts/run_job.py"
