# Identification of the valve from each dataset (paper Section 3.2, Fig. 2). The validation of
# the identified model against every run shares a job with the open-loop analyses
# (characterise.smk).


rule identify:
    input:
        **inputs_from("runs"),
    output:
        **outputs("identify"),
    log:
        logfile("identify"),
    threads: 1
    resources:
        mem_mb=2000,
        runtime=20,
    params:
        code=SPA_CODE,
        cfg=config["identification"],
        nominal=config["nominal"],
        seed=config["seed"],
    script:
        "../scripts/identify.py"
