# Identification of the valve from each dataset (paper Section 3.2, Fig. 2), then validation
# of the identified model against every run of the dataset.


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


rule validate_model:
    input:
        **inputs_from("runs"),
        params=rules.identify.output.params,
    output:
        **outputs("validate_model"),
    log:
        logfile("validate_model"),
    threads: 1
    resources:
        mem_mb=2000,
        runtime=20,
    params:
        code=SPA_CODE,
    script:
        "../scripts/validate_model.py"
