# Open-loop linearity of every dataset (paper Section 6): staircase (Table 3, Figs. 6-7),
# sine (Fig. 8) and chirp (Fig. 9). A dataset without runs of a kind gets empty tables and
# a figure saying so, so that every dataset has the same outputs.


rule staircase:
    input:
        **inputs_from("runs"),
        params=rules.identify.output.params,
    output:
        **outputs("staircase"),
    log:
        logfile("staircase"),
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
        **inputs_from("runs"),
        params=rules.identify.output.params,
    output:
        **outputs("sine"),
    log:
        logfile("sine"),
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
        **inputs_from("runs"),
        params=rules.identify.output.params,
    output:
        **outputs("chirp"),
    log:
        logfile("chirp"),
    threads: 1
    resources:
        mem_mb=2000,
        runtime=20,
    params:
        code=SPA_CODE,
        cfg=config["linearity"]["chirp"],
    script:
        "../scripts/chirp.py"
