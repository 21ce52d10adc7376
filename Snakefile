# spa: reproduce Serrano-Balbontín et al., Robotics 2025, 14(12), 177, and characterise new benches.
from snakemake.utils import min_version

min_version("9.0")


configfile: "config/config.yaml"


include: "workflow/rules/common.smk"
include: "workflow/rules/analytic.smk"
include: "workflow/rules/datasets.smk"
include: "workflow/rules/identify.smk"
include: "workflow/rules/linearity.smk"
include: "workflow/rules/report.smk"


rule reproduce_all:
    name:
        "reproduce-all"
    default_target: True
    input:
        analytic_targets(),
        dataset_targets(),
        rules.report.output.report,
