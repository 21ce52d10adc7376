"""The stage table: every stage of the pipeline, in order, with what it writes.

Each :class:`~spa.pipeline.stage_types.Stage` names its outputs (paths relative to
``results/`` or ``results/<dataset>/``, kind, report heading and caption) and its log files.
The order is the pipeline's: the rules, ``ANALYSE`` (the stages of a dataset's analysis
job, ``workflow/rules/analyse.smk``), ``reproduce-all`` and the report all follow it
(:mod:`spa.pipeline.outputs` reads it). A new stage is one entry here, at its place.

This module imports nothing heavy: the workflow imports it to parse the Snakefile.
"""

from __future__ import annotations

from spa.pipeline.stage_types import (
    DATA,
    FIGURE,
    FIGURES,
    PAGE,
    PARAMS,
    RECOMMENDATION,
    RUNS,
    TABLE,
    Output,
    Stage,
    _analytic,
    _per_dataset,
    _with_vectors,
)
from spa.plots.words import FIG10_CAPTION, FIG11_CAPTION, O1_CAPTION

__all__ = ["STAGES"]


STAGES: tuple[Stage, ...] = (
    _analytic(
        "table1",
        Output(
            "table",
            "analytic/table1.csv",
            TABLE,
            "Table 1: dead-zone and saturation",
            "Dead-zone and saturation thresholds of the input fraction for each selected "
            "modulator setting, from the averaged model at the nominal parameters.",
        ),
    ),
    _analytic(
        "table2",
        Output(
            "table",
            "analytic/table2.csv",
            TABLE,
            "Table 2: optimal modulator parameters",
            "Minimum linearity cost J_min and optimal parameter per modulator, the paper's "
            "printed values beside them, and the analytic IIPFM optimum t_l* (Eq. 29).",
        ),
    ),
    _analytic(
        "fig4",
        Output(
            "figure",
            "analytic/fig4.png",
            FIGURE,
            "Fig. 4: linearity cost",
            "Linearity cost J against the modulator parameter, every modulator kind on one axis. "
            "Grey: PWM periods below t_on + t_off (above 76.9 Hz for the nominal valve), where "
            "PWM has no linear range (dead-zone and saturation meet): P_eq is a 0 → k2 step, "
            "and J moves in plateaus and jumps as the step passes the points of the ξ grid.",
        ),
        Output("data", "analytic/fig4.csv", DATA),
    ),
    _analytic(
        "fig5",
        Output(
            "figure",
            "analytic/fig5.png",
            FIGURE,
            "Fig. 5: equilibrium pressure and time constant",
            "Equilibrium pressure and time constant against the input fraction ξ at each "
            "modulator's optimum, with the linear target.",
        ),
        Output("data", "analytic/fig5.csv", DATA),
    ),
    Stage(
        "raw_manifest",
        True,
        (Output("manifest", "provenance/raw.json", DATA),),
        {"raw_manifest": "{dataset}/raw_manifest.log"},
        target=False,
        job="ingest",
        function="spa.pipeline.provenance.write_manifest",
        params=("folder", "cache", "digest"),
    ),
    _per_dataset(
        "runs",
        Output("runs", "runs", RUNS),
        logs={
            "simulate_dataset": "{dataset}/simulate.log",
            "ingest_dataset": "{dataset}/ingest.log",
        },
        upstream=(),
        job="ingest",
        script="ingest_dataset",
        function="spa.datasets.ingest_dataset",
        params=("folder", "supply", "digest"),
    ),
    _per_dataset(
        "identify",
        Output(
            "params",
            "identification/params.yaml",
            PARAMS,
            "Identified valve parameters",
            "c1, k2, tau2, t_on and t_off identified from this dataset, each with its 95 % "
            "interval, unit, method and any fallback to the nominal value.",
        ),
        Output(
            "fig2a",
            "identification/fig2a.png",
            FIGURE,
            "Fig. 2a: charging",
            "dP/dt against P while charging, with the line fit that gives k2 and tau2.",
        ),
        Output("fig2a_csv", "identification/fig2a.csv", DATA),
        Output(
            "fig2b",
            "identification/fig2b.png",
            FIGURE,
            "Fig. 2b: discharging",
            "dP/dt against P while discharging, with the power-law fit that gives c1.",
        ),
        Output("fig2b_csv", "identification/fig2b.csv", DATA),
        Output(
            "fig2c",
            "identification/fig2c.png",
            FIGURE,
            "Fig. 2c: pulse run",
            "The pulse run: command, measured and model pressure; below, a zoom on the opening "
            "edge after which the pressure rises most, showing the t_on hold before the rise.",
        ),
        Output("fig2c_csv", "identification/fig2c.csv", DATA),
        Output(
            "laws",
            "identification/laws.png",
            FIGURE,
            "Charge and discharge laws",
            "dP/dt against P with the valve open and closed: the laws the identification "
            "fitted (solid) inside their simultaneous 95 % band (a bootstrap over the runs), "
            "the paper's laws with the identified c1, k2 and tau2 (dashed), and the pressures "
            "the runs visited in each mode (grey); outside the grey the laws are extrapolated. "
            "Which laws the stages use is params.yaml's laws: chosen.",
        ),
        Output("laws_csv", "identification/laws.csv", DATA),
        upstream=("runs",),
        category="Identification",
        job="analyse",
        config="identification",
        function="spa.identification.identify_with_config",
        params=("nominal", "seed", "supply"),
    ),
    _per_dataset(
        "tune",
        Output(
            "recommendation",
            "tuning/recommendation.yaml",
            RECOMMENDATION,
            "Recommended modulator for this valve",
            "The modulator setting that minimises the linearity cost for this dataset's "
            "identified valve within the tuning: constraints, as a dataset.yaml modulator entry, "
            "with its predicted dead-zone, saturation, chattering and switching rate; the full "
            "record, with the best setting of each other modulator, is tuning/recommendation.yaml. "
            "It is the open-loop recommendation: run without feedback, a constant input "
            "fraction then gives a pressure closest to proportional to it. The closed loop's "
            "choice (Closed loop: the PI to use) answers another question and may name "
            "another modulator.",
            required=False,
        ),
        Output(
            "table2",
            "tuning/table2.csv",
            TABLE,
            "Table 2 for this valve",
            "Each modulator's optimum of J for this valve, J there, Eq. 29's t_l*, J at the "
            "paper's setting, J_exact from the exact periodic steady state, and the range over "
            "the corners of the identification's 95 % intervals. optimum_exact is J_exact's "
            "minimum over the settings that meet the tuning constraints (chattering, switching "
            "rate, shortest pulse): J_exact alone keeps falling as the period grows, because "
            "the pressure then fills and empties every cycle and its mean tends to k2 times the "
            "duty, while it swings by most of k2. *_at_grid_edge: the optimum is the first or "
            "last setting of the sweep.",
            required=False,
        ),
        Output(
            "fig4",
            "tuning/fig4.png",
            FIGURE,
            "Fig. 4 for this valve: linearity cost",
            "Linearity cost J (solid) and J_exact from the exact periodic steady state (dashed) "
            "against each modulator's parameter, for this dataset's identified valve. Grey: PWM "
            "periods below t_on + t_off, where PWM has no linear range and J moves in steps "
            "with the ξ grid (see Fig. 4 of the analytic section).",
            required=False,
        ),
        Output("fig4_csv", "tuning/fig4.csv", DATA),
        Output(
            "table1",
            "tuning/table1.csv",
            TABLE,
            "Table 1 for this valve: dead-zone and saturation",
            "Dead-zone and saturation with this valve's parameters at the paper's settings, at "
            "each optimum and at the recommendation.",
            required=False,
        ),
        Output(
            "fig5",
            "tuning/fig5.png",
            FIGURE,
            "Fig. 5 for this valve: equilibrium and time constant",
            "Averaged equilibrium pressure, exact cycle mean and time constant against the input "
            "fraction at each modulator's optimum.",
            required=False,
        ),
        Output("fig5_csv", "tuning/fig5.csv", DATA),
        category="Tuning",
        job="analyse",
        config="tuning",
        function="spa.tuning.tune",
        reads=("identify",),
        params=("tuning", "sweeps", "n_xi", "selected", "linearity"),
    ),
    _per_dataset(
        "validate_model",
        Output(
            "fit",
            "validation/fit.csv",
            TABLE,
            "Model validation: FIT per run",
            "Every run re-simulated with the identified parameters: FIT %, RMSE and largest "
            "error (bar).",
        ),
        Output(
            "figures",
            "validation/figures",
            FIGURES,
            "Validation: {name}",
            "Measured against model pressure for the lowest-FIT {name} run.",
        ),
        category="Validation",
        job="analyse",
        function="spa.validation.validate_runs",
    ),
    _per_dataset(
        "staircase",
        Output(
            "table3",
            "staircase/table3.csv",
            TABLE,
            "Table 3: static linearity of the staircase",
            "One row per modulator setting: line P = m ξ + n through the equilibrium pressure "
            "of each staircase level, MSE, MAD (mean absolute residual, which is what the "
            "paper's MD is: paper_md beside it), max_dev (largest residual) and FIT %, with the "
            "paper's values (paper_*, shaded) beside its five cases; then the measured against "
            "the averaged-model equilibrium, drift_max (how far the levels are from settled), "
            "dead-zone and saturation brackets, step time constants, switching rate, the "
            "sensor's noise (noise_sd, from the levels where the valve is still) and the "
            "chattering: measured, with the noise's variance subtracted, noise-free (simulated "
            "data) and Appendix B's.",
            key_item=True,
            required=False,
        ),
        Output("levels", "staircase/levels.csv", DATA, mention=True),
        Output("time_constants", "staircase/time_constants.csv", DATA, mention=True),
        Output(
            "fig6",
            "staircase/fig6.png",
            FIGURE,
            "Fig. 6: staircase responses",
            "Pressure against time for the staircase input fraction, one panel per modulator "
            "(every setting).",
            required=False,
        ),
        Output("fig6_csv", "staircase/fig6.csv", DATA),
        Output(
            "fig7a",
            "staircase/fig7a.png",
            FIGURE,
            "Fig. 7a: equilibrium pressure",
            "Equilibrium pressure against ξ for the paper's settings (PWM 20 Hz, IPFM 20 ms, "
            "IIPFM 20 ms with G = 1 and 1.15, ΔΣM 20 ms; a group's best by FIT where the "
            "dataset lacks one, named in the title), with the ideal line k2·ξ; right: FIT of "
            "every setting.",
            required=False,
        ),
        Output("fig7a_csv", "staircase/fig7a.csv", DATA),
        Output(
            "fig7b",
            "staircase/fig7b.png",
            FIGURE,
            "Fig. 7b: time constants",
            "Time constant of each staircase step (time to 63.2 % of the step's change) for "
            "the paper's settings; right: mean ± sd of every setting. Crosses: outliers, over "
            "ten times off the median time constant of all the dataset's steps (a crossing of "
            "the 63.2 % level by one pulse or by the chattering of a long-period modulator on a "
            "step of a few mbar); they are marked, not removed: the means include them (×n "
            "above a bar: that setting's outliers).",
            required=False,
        ),
        Output("fig7b_csv", "staircase/fig7b.csv", DATA),
        category="Staircase",
        job="analyse",
        config="linearity.staircase",
        function="spa.stages.staircase.run_staircase",
    ),
    _per_dataset(
        "sine",
        Output(
            "table",
            "sine/linearity.csv",
            TABLE,
            "Sine linearity",
            "Per setting: sine frequency, lag found by cross-correlation within max_lag (by "
            "default half the sine's period; a lag on that limit is NaN, with lag_at_limit "
            "true), RMS and largest "
            "(max_dev) deviation of P/max(P) from the line (0, 0)–(1, 1); the row 'linear' is "
            "the same input through a noise-free linear first-order plant (gain k2, the "
            "dataset's τ_m at ξ = 0.5, Eq. 9), analysed identically: the deviation a linear "
            "plant gets. The full config drives the sine at 0.02 Hz, well below the plant's "
            "corner frequency 1/(2π τ_m); the small (CI) config at 0.5 Hz to stay fast, where "
            "the linear row shows how much of the deviation is the plant's dynamics.",
            required=False,
        ),
        Output(
            "fig8",
            "sine/fig8.png",
            FIGURE,
            "Fig. 8: sine linearity",
            "Lag-compensated P/max(P) against the input fraction of the sine runs, one panel "
            "per modulator with its settings in numeric order, with the line (0, 0)–(1, 1) and "
            "the linear reference (grey); the title gives the sine's frequency against the "
            "plant's corner frequency.",
            required=False,
        ),
        Output("fig8_csv", "sine/fig8.csv", DATA),
        category="Sine",
        job="analyse",
        config="linearity.sine",
        function="spa.stages.sine.run_sine",
    ),
    _per_dataset(
        "chirp",
        Output(
            "table",
            "chirp/bicoherence.csv",
            TABLE,
            "Chirp bicoherence",
            "Per setting: bounded (Kim and Powers) bicoherence of the pressure response to the "
            "chirp, its significance threshold 1 − α^(1/(K−1)) for K segments, the fraction "
            "of the principal domain above it (the two rows next to DC left out), and the "
            "mean, median and largest value; for simulated runs the spread of the fraction "
            "over sensor-noise seeds, and significant_fraction_no_ringing: the same runs and "
            "seeds logged without the sensor's ringing after each valve edge, which is locked "
            "to the edges and reads as coupling. The row 'linear' is the same input through a "
            "linear first-order plant, logged (simulated data) by the first run's sensor: its "
            "noise, and its ringing after that run's valve edges; without the ringing its "
            "fraction is the test's false-alarm rate (noise-free for bench data).",
            required=False,
        ),
        Output(
            "fig9",
            "chirp/fig9.png",
            FIGURE,
            "Fig. 9: bicoherence",
            "Bicoherence maps over (f1, f2) of the pressure response to the chirp, on a fixed "
            "[0, 1] scale with the insignificant bins grey, for the paper's settings (a "
            "group's best where the dataset lacks one, named in the title) and the linear "
            "reference (simulated data: through the first run's sensor); below, the "
            "significant fraction of every setting (bars: range over noise seeds; dashed: the "
            "linear reference; hollow circles and dotted: the same without the sensor's "
            "ringing).",
            required=False,
        ),
        Output("fig9_csv", "chirp/fig9.csv", DATA),
        category="Chirp",
        job="analyse",
        config="linearity.chirp",
        function="spa.stages.chirp.run_chirp",
    ),
    # Closed loop (spa.closedloop): PI through the modulator, designed and simulated exactly.
    _per_dataset(
        "closed_loop",
        Output(
            "controllers",
            "closed_loop/controllers.yaml",
            RECOMMENDATION,
            "Closed loop: the PI to use",
            "The modulator setting and PI controller with the smallest worst-case rise time "
            "over the set-point staircase among those overshooting at most "
            "closed_loop.max_overshoot (10 %; tau_c lengthened until one does, else none is "
            "chosen), for this dataset's identified valve (SIMC on the averaged model's local "
            "gain, time constant and dead time); closed_loop/controllers.yaml holds the gains "
            "of every setting (fixed, gain-scheduled, and gain-scheduled with feed-forward) "
            "and the settings left out on this valve, each with its reason. When the promise "
            "over the 95 % box holds only at a longer tau_c, the chosen entry, the sentence and "
            "the header are the loop designed there; the design at the stage's tau_c is kept "
            "under for_comparison. It is the closed-loop recommendation, judged on the promise "
            "verified over the 95 % box (worst overshoot and settling), not on open-loop "
            "linearity: feedback corrects a curved static map but not the modulator's delay and "
            "ripple, so it may differ from the open-loop recommendation above.",
            required=False,
        ),
        Output(
            "table",
            "closed_loop/table.csv",
            TABLE,
            "Closed loop: metrics per setting and controller",
            "Exact closed-loop simulation of each setting with each PI: per experiment "
            "(staircase up and down, steps from 0 bar, sine) and metric, the median, smallest "
            "and largest value over the operating points and their spread (max - min). Step "
            "metrics on the cycle-mean pressure (docs/model.md section 8); n_missing: steps "
            "where a metric is undefined (not reached, or not settled within 2 %). Rows of "
            "experiment box_95: the chosen loop's worst case over the 95 % box (and its "
            "robust tau_c); supply_drop and sensor_noise: each setting's recovery from a 10 % "
            "drop of k2 and the ripple the sensor's noise adds (robust.csv has them by "
            "setting). A controller named '... (for comparison, not shipped)' is the stage's "
            "design at its tau_c, kept beside the shipped loop at a longer one.",
            required=False,
        ),
        Output(
            "robust",
            "closed_loop/robust.csv",
            TABLE,
            "Closed loop: over the 95 % box and under bench disturbances",
            "One row per setting, with the chosen kind of PI: a 10 % drop of the supply "
            "pressure k2 in the middle of the staircase's middle level (the set-point there; "
            "the time until the cycle-mean pressure is back within 2 % of it from the same "
            "run without the drop, NaN: not before the level ends; the dip and the "
            "steady-state error after it, bar) and the "
            "sensor's noise (params.yaml's noise.sensor; without it, unknown, and the pulse "
            "fit's residual is used as its upper bound) read by the controller (the "
            "actuator's added ripple, median over the steps, bar). The chosen setting's row "
            "is the shipped loop's (the header's) and also holds "
            "its worst case over the staircase with the plant at every corner of the "
            "identification's 95 % box (PI designed at the estimate) and the robust tau_c: "
            "the shortest tau_c*1.5^j whose worst overshoot is at most 10 % (NaN: none up to "
            "8 tau_c; docs/model.md section 8).",
            required=False,
        ),
        Output("header", "closed_loop/controller.h", DATA),
        Output("sketch", "closed_loop/controller.ino", DATA),
        Output(
            "fig10",
            "closed_loop/fig10.png",
            FIGURE,
            "Fig. 10: closed-loop staircase",
            FIG10_CAPTION,  # written from the style table Fig. 10 is drawn with
            required=False,
        ),
        Output("fig10_csv", "closed_loop/fig10.csv", DATA),
        Output(
            "fig11",
            "closed_loop/fig11.png",
            FIGURE,
            "Fig. 11: closed-loop metrics against the operating point",
            FIG11_CAPTION,  # written from the style table Fig. 11 is drawn with
            required=False,
        ),
        Output("fig11_csv", "closed_loop/fig11.csv", DATA),
        Output(
            "recorded",
            "closed_loop/runs.csv",
            TABLE,
            "Closed loop: recorded runs against the model",
            "Every closed_loop run of the dataset (a PI on the bench, or simulated): the worst "
            "rise time, overshoot and steady-state error over its set-point steps as recorded "
            "and as the same controller and modulator replayed on the identified model give "
            "them (*_model), and the replay's FIT %, RMSE and largest error (bar). The loop "
            "hides much of a model's error, so compare the RMSE with the sensor's noise.",
            required=False,
        ),
        upstream=("runs", "identify"),
        category="Closed loop",
        job="analyse",
        config="closed_loop",
        function="spa.closedloop.comparison.closed_loop",
        # of the tuning, the recommended setting and the bench's adequacy alone: a tuning:
        # change that leaves them as they were leaves the closed loop reused
        reads=("identify", "tune.recommendation"),
        read_keys={"tune.recommendation": ("recommended.setting", "adequacy")},
        params=("selected",),
    ),
    # Its dataset's page of the report and its row of the overview, in the dataset's own job.
    _per_dataset(
        "page",
        Output("page", "report/{dataset}.html", PAGE),
        Output("row", "report/overview.json", DATA),
        upstream=(),
        job="analyse",
        function="spa.report.site.build_dataset_page",
        reads=("*",),
        params=("seed", "raw_dir"),
        raw_files=("dataset.yaml", "verification.csv"),
    ),
    Stage(
        "overview",
        False,
        _with_vectors(
            (
                Output(
                    "figure",
                    "overview.png",
                    FIGURE,
                    "Fig. O1: the valve across sessions",
                    O1_CAPTION,
                ),
                Output(
                    "table",
                    "overview.csv",
                    TABLE,
                    "Overview across datasets",
                    "One row per dataset in session order: date, rig, valve (the rig and "
                    "the dataset's own valve name; a simulated dataset is a valve of its "
                    "own), the five identified "
                    "parameters with their 95 % intervals, validation FIT (median and lowest), "
                    "the recommended setting with its J and J_exact (bar), the status, and "
                    "changed_<parameter>: the interval excludes the previous session's of the "
                    "same valve. Also the data of Fig. O1.",
                ),
            )
        ),
        {"overview": "overview.log"},
        section="overview",
        category="Overview",
    ),
    Stage(
        "report",
        False,
        (
            Output("report", "report.html", PAGE),
            Output("index", "report/index.html", PAGE),
            Output("analytic", "report/analytic.html", PAGE),
        ),
        {"report": "report.log"},
    ),
    # Last: fails the run, naming them, when any dataset failed (spa.pipeline.status).
    Stage("check", False, (Output("status", "status.yaml", DATA),), {"check": "check.log"}),
)
"""Every stage, in pipeline order; the report shows each section's outputs in this order."""
