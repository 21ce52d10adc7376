# Open-loop linearity of every dataset (paper Section 6): staircase (Table 3, Figs. 6-7),
# sine (Fig. 8) and chirp (Fig. 9). A dataset without runs of a kind gets empty tables and
# a figure saying so, so that every dataset has the same outputs.


rule staircase:
    input:
        runs=f"{RESULTS}/{{dataset}}/runs",
        params=rules.identify.output.params,
    output:
        table3=f"{RESULTS}/{{dataset}}/staircase/table3.csv",
        levels=f"{RESULTS}/{{dataset}}/staircase/levels.csv",
        time_constants=f"{RESULTS}/{{dataset}}/staircase/time_constants.csv",
        fig6=f"{RESULTS}/{{dataset}}/staircase/fig6.png",
        fig7a=f"{RESULTS}/{{dataset}}/staircase/fig7a.png",
        fig7b=f"{RESULTS}/{{dataset}}/staircase/fig7b.png",
    log:
        f"{RESULTS}/logs/{{dataset}}/staircase.log",
    threads: 1
    resources:
        mem_mb=2000,
        runtime=20,
    params:
        code=SPA_CODE,
        cfg=config["linearity"]["staircase"],
    script:
        "../scripts/staircase.py"


rule sine:
    input:
        runs=f"{RESULTS}/{{dataset}}/runs",
    output:
        table=f"{RESULTS}/{{dataset}}/sine/linearity.csv",
        fig8=f"{RESULTS}/{{dataset}}/sine/fig8.png",
    log:
        f"{RESULTS}/logs/{{dataset}}/sine.log",
    threads: 1
    resources:
        mem_mb=2000,
        runtime=20,
    params:
        code=SPA_CODE,
        cfg=config["linearity"]["sine"],
    script:
        "../scripts/sine.py"


rule chirp:
    input:
        runs=f"{RESULTS}/{{dataset}}/runs",
    output:
        table=f"{RESULTS}/{{dataset}}/chirp/bicoherence.csv",
        fig9=f"{RESULTS}/{{dataset}}/chirp/fig9.png",
    log:
        f"{RESULTS}/logs/{{dataset}}/chirp.log",
    threads: 1
    resources:
        mem_mb=2000,
        runtime=20,
    params:
        code=SPA_CODE,
        cfg=config["linearity"]["chirp"],
    script:
        "../scripts/chirp.py"
