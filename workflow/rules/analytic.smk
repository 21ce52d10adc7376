# Analytic stage (paper Sections 4-5): Table 1, the linearity sweeps of Fig. 4, Table 2 and
# the equilibrium curves of Fig. 5, all from the averaged model at the nominal parameters.
ANALYTIC = Path(RESULTS) / "analytic"
ANALYTIC_LOGS = Path(RESULTS) / "logs" / "analytic"


rule analytic_table1:
    output:
        table=str(ANALYTIC / "table1.csv"),
    log:
        str(ANALYTIC_LOGS / "table1.log"),
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
        figure=str(ANALYTIC / "fig4.png"),
        data=str(ANALYTIC / "fig4.csv"),
    log:
        str(ANALYTIC_LOGS / "fig4.log"),
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
        table=str(ANALYTIC / "table2.csv"),
    log:
        str(ANALYTIC_LOGS / "table2.log"),
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
        figure=str(ANALYTIC / "fig5.png"),
        data=str(ANALYTIC / "fig5.csv"),
    log:
        str(ANALYTIC_LOGS / "fig5.log"),
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
