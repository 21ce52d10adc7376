# Analytic stage (paper Sections 4-5): Table 1, the linearity sweeps of Fig. 4, Table 2 and
# the equilibrium curves of Fig. 5, all from the averaged model at the nominal parameters.


rule analytic_table1:
    output:
        **outputs("analytic_table1"),
    log:
        logfile("analytic_table1"),
    threads: 1
    resources:
        mem_mb=500,
        runtime=5,
    params:
        code=SPA_CODE,
        nominal=lookup(dpath="nominal", within=config),
        selected=lookup(dpath="analytic/selected", within=config),
    script:
        "../scripts/analytic_table1.py"


rule analytic_fig4:
    output:
        **outputs("analytic_fig4"),
    log:
        logfile("analytic_fig4"),
    threads: 1
    resources:
        mem_mb=1000,
        runtime=5,
    params:
        code=SPA_CODE,
        nominal=lookup(dpath="nominal", within=config),
        sweeps=lookup(dpath="analytic/sweeps", within=config),
        n_xi=lookup(dpath="analytic/n_xi", within=config),
    script:
        "../scripts/analytic_fig4.py"


rule analytic_table2:
    output:
        **outputs("analytic_table2"),
    log:
        logfile("analytic_table2"),
    threads: 1
    resources:
        mem_mb=1000,
        runtime=5,
    params:
        code=SPA_CODE,
        nominal=lookup(dpath="nominal", within=config),
        sweeps=lookup(dpath="analytic/sweeps", within=config),
        n_xi=lookup(dpath="analytic/n_xi", within=config),
    script:
        "../scripts/analytic_table2.py"


rule analytic_fig5:
    input:
        table2=rules.analytic_table2.output.table,
    output:
        **outputs("analytic_fig5"),
    log:
        logfile("analytic_fig5"),
    threads: 1
    resources:
        mem_mb=500,
        runtime=5,
    params:
        code=SPA_CODE,
        nominal=lookup(dpath="nominal", within=config),
        n_xi=lookup(dpath="analytic/n_xi", within=config),
    script:
        "../scripts/analytic_fig5.py"
