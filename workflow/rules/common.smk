# Helpers that compute targets from the config. No analysis here: that lives in spa/.
from pathlib import Path

from spa.config import validate_config

validate_config(config, Path(workflow.basedir) / "workflow" / "schemas" / "config.schema.yaml")

RESULTS = config.get("results", "results")


def analytic_targets():
    out = Path(RESULTS) / "analytic"
    names = ["table1.csv", "table2.csv", "fig4.png", "fig4.csv", "fig5.png", "fig5.csv"]
    return [str(out / n) for n in names]
