# Tuning for every dataset's own valve (paper Section 5 on its identified parameters): Table 1
# at the selected settings and the optima, Fig. 4 (J and J_exact), Table 2 with the 95 %
# intervals propagated, Fig. 5 and the recommended modulator setting.


rule tune:
    input:
        params=rules.identify.output.params,
    output:
        **outputs("tune"),
    log:
        logfile("tune"),
    threads: 1
    resources:
        mem_mb=2000,
        runtime=10,
    params:
        code=SPA_CODE,
        tuning=lookup(dpath="tuning", within=config),
        sweeps=lookup(dpath="analytic/sweeps", within=config),
        n_xi=lookup(dpath="analytic/n_xi", within=config),
        selected=lookup(dpath="analytic/selected", within=config),
        linearity=lookup(dpath="linearity/staircase", within=config),
    script:
        "../scripts/tune.py"
