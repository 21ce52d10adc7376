# Identification of the valve from each dataset (paper Section 3.2, Fig. 2), then validation
# of the identified model against every run of the dataset.


rule identify:
    input:
        runs=f"{RESULTS}/{{dataset}}/runs",
    output:
        params=f"{RESULTS}/{{dataset}}/identification/params.yaml",
        fig2a=f"{RESULTS}/{{dataset}}/identification/fig2a.png",
        fig2a_csv=f"{RESULTS}/{{dataset}}/identification/fig2a.csv",
        fig2b=f"{RESULTS}/{{dataset}}/identification/fig2b.png",
        fig2b_csv=f"{RESULTS}/{{dataset}}/identification/fig2b.csv",
        fig2c=f"{RESULTS}/{{dataset}}/identification/fig2c.png",
        fig2c_csv=f"{RESULTS}/{{dataset}}/identification/fig2c.csv",
    log:
        f"{RESULTS}/logs/{{dataset}}/identify.log",
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
        runs=f"{RESULTS}/{{dataset}}/runs",
        params=rules.identify.output.params,
    output:
        fit=f"{RESULTS}/{{dataset}}/validation/fit.csv",
        figures=directory(f"{RESULTS}/{{dataset}}/validation/figures"),
    log:
        f"{RESULTS}/logs/{{dataset}}/validate_model.log",
    threads: 1
    resources:
        mem_mb=2000,
        runtime=20,
    params:
        code=SPA_CODE,
    script:
        "../scripts/validate_model.py"
