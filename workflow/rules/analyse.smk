# Everything a dataset's run tables say, in one job per dataset (spa.pipeline.jobs): the valve
# identified (paper Section 3.2, Fig. 2); the modulators tuned for it (Section 5: Tables 1-2,
# Figs. 4-5, the recommended setting); the model replayed on each run (validate_model); the
# open-loop linearity of Section 6: staircase (Table 3, Figs. 6-7), sine (Fig. 8) and chirp
# (Fig. 9); the closed loop; last, the dataset's page of the report and its row of the
# overview (page: it reads the dataset's date and rig from raw/<dataset>/dataset.yaml). Each
# stage is a second or two of work and a job costs about a second of imports and Snakemake's
# own bookkeeping, so they share one (benchmarks/README.md, "Growth"); each
# stage keeps its own outputs, log, status and script. A change to one stage's settings
# (tuning:, linearity:) reruns the job, but inside it every stage whose inputs, settings and
# code are unchanged is restored from results/.store (spa.pipeline.reuse, `store`); its
# status says "reused". A dataset without runs of a kind gets empty tables and a figure
# saying so, so that every dataset has the same outputs.
# The stages of the job, in order, from the stage table (spa/pipeline/stage_table.py: job "analyse"):
# identify, tune, validate_model, staircase, sine, chirp, closed_loop, page.
ANALYSE = job_stages("analyse")


# Two rules, one per kind of dataset: `analyse` draws the figures, `analyse_tables` (the
# datasets left out by config `figures`) writes the tables and the figures' data alone and
# removes figures an earlier run drew there. Their parameters are the same, so moving a
# dataset out of `figures` reruns nothing; moving it in draws its figures (they are missing).
# A rule no dataset needs is left out (every file of the DAG is matched against each rule).
for _rule, _drawn in (("analyse", True), ("analyse_tables", False)):
    if not any((d in FIGURE_DATASETS) == _drawn for d in DATASETS):
        continue

    rule:
        name:
            _rule
        input:
            **inputs_from("runs"),
        output:
            **joined_outputs(ANALYSE, lambda stage: outputs(stage, figures=_drawn)),
        log:
            **{stage: logfile(stage) for stage in ANALYSE},
        wildcard_constraints:
            dataset=wildcard_choice(
                d for d in DATASETS if (d in FIGURE_DATASETS) == _drawn
            ),
        threads: 1
        resources:
            mem_mb=2000,
            runtime=60,
        params:
            code=SPA_CODE,
            stages=ANALYSE,
            store=True,
            cfg=stage_settings(config, ANALYSE),
            nominal=config["nominal"],
            seed=config["seed"],
            raw_dir=str(RAW_DIR),
            tuning=lookup(dpath="tuning", within=config),
            sweeps=lookup(dpath="analytic/sweeps", within=config),
            n_xi=lookup(dpath="analytic/n_xi", within=config),
            selected=lookup(dpath="analytic/selected", within=config),
            linearity=lookup(dpath="linearity/staircase", within=config),
            supply=lookup(
                dpath="datasets/plausible_supply_bar",
                within=config,
                default=[0.05, 20.0],
            ),
        script:
            "../scripts/run_job.py"
