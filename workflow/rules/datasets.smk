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


# The manifest of a bench dataset: every file's sha256. Its `digest` parameter is computed
# when the DAG is built (spa.provenance.dataset_digest, cached by stat), so the rule reruns,
# and everything downstream with it, exactly when the content of raw/<name>/ changed: not when
# only a modification time moved, and also when a time went back with new content.
rule raw_manifest:
    output:
        **outputs("raw_manifest"),
    log:
        logfile("raw_manifest"),
    wildcard_constraints:
        dataset=wildcard_choice(RAW_DATASETS),
    threads: 1
    resources:
        mem_mb=500,
        runtime=10,
    params:
        digest=raw_digest,
        folder=lambda w: str(RAW_DIR / w.dataset),
        cache=DIGEST_CACHE,
    script:
        "../scripts/raw_manifest.py"


rule ingest_dataset:
    input:
        **inputs_from("raw_manifest"),
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
