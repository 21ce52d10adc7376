# What the identified model says about every run of a dataset, in one job per dataset
# (spa.jobs): the model replayed on each run (validate_model), then the open-loop linearity
# of paper Section 6: staircase (Table 3, Figs. 6-7), sine (Fig. 8) and chirp (Fig. 9). The
# four read the same inputs, each is a second or two of work, and a job costs about a second
# of imports, so they share one; each stage keeps its own outputs, log and status, and its
# own script (run by workflow/scripts/characterise.py). A dataset without runs of a kind
# gets empty tables and a figure saying so, so that every dataset has the same outputs.

CHARACTERISE = ["validate_model", "staircase", "sine", "chirp"]


rule characterise:
    input:
        **inputs_from("runs"),
        params=rules.identify.output.params,
    output:
        **joined_outputs(CHARACTERISE, outputs),
    log:
        **{stage: logfile(stage) for stage in CHARACTERISE},
    threads: 1
    resources:
        mem_mb=2000,
        runtime=30,
    params:
        code=SPA_CODE,
        stages=CHARACTERISE,
        cfg={stage: config["linearity"][stage] for stage in CHARACTERISE[1:]},
    script:
        "../scripts/characterise.py"
