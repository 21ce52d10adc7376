"""What ``snakemake --report report.zip`` shows: each table and figure of the registry of
outputs (:data:`spa.pipeline.outputs.STAGES`) with its category, subcategory and caption file.

The category is the stage's (``Stage.category``: Analytic, Identification, Tuning, ...), the
subcategory the dataset (``{dataset}``, filled in by Snakemake) for a per-dataset stage. The
caption of an output is ``workflow/report/<stage>-<key>.rst``: its heading and caption in the
registry, written as reStructuredText by :func:`caption_rst`. The workflow wraps these outputs
in Snakemake's ``report()`` (``workflow/rules/common.smk``);
``python -m spa.pipeline.workflow_report workflow/report`` rewrites the caption files after a
caption changed in the registry, and a test checks that they agree.

This module imports nothing heavy: the workflow imports it to parse the Snakefile.

>>> [f"{s.name}-{o.key}" for s, o in report_outputs()][:3]
['analytic_table1-table', 'analytic_table2-table', 'analytic_fig4-figure']
>>> report_flags("validate_model", "workflow/report")["figures"]["patterns"]
['{name}.png']
"""

from __future__ import annotations

import re
import sys
from pathlib import Path
from typing import Any

from spa.pipeline.outputs import STAGES, get_stage
from spa.pipeline.stage_types import FIGURE, FIGURES, TABLE, Output, Stage

__all__ = ["caption_file", "caption_rst", "report_flags", "report_outputs", "write_captions"]

_SHOWN_KINDS = (TABLE, FIGURE, FIGURES)
_RST_SPECIAL = re.compile(r"([\\`*_|])")


def report_outputs() -> list[tuple[Stage, Output]]:
    """Every (stage, output) that ``snakemake --report`` shows: the report's tables and figures.

    Returns
    -------
    list of (Stage, Output)
        In the order of :data:`spa.pipeline.outputs.STAGES`; only stages with a category.
    """
    return [
        (stage, out)
        for stage in STAGES
        if stage.category
        for out in stage.outputs
        if out.shown and out.kind in _SHOWN_KINDS
    ]


def caption_file(stage: Stage, out: Output) -> str:
    """The caption's file name, ``<stage>-<key>.rst``."""
    return f"{stage.name}-{out.key}.rst"


def _escape(text: str) -> str:
    """Text with reStructuredText's inline markup characters escaped (``paper_*``, ``t_l*``)."""
    return _RST_SPECIAL.sub(r"\\\1", text)


def caption_rst(stage: Stage, out: Output) -> str:
    """The caption of an output as reStructuredText: its heading in bold, then its caption.

    A per-dataset output names its dataset (``{{ snakemake.wildcards.dataset }}``, which
    Snakemake's report fills in), and ``{name}`` of a folder of figures becomes the figure's
    name.

    Examples
    --------
    >>> stage = get_stage("validate_model")
    >>> print(caption_rst(stage, stage.outputs[1]), end="")
    **Validation: {{ snakemake.wildcards.name }}** (dataset ``{{ snakemake.wildcards.dataset }}``).
    <BLANKLINE>
    Measured against model pressure for the lowest-FIT {{ snakemake.wildcards.name }} run.
    """
    name = "{{ snakemake.wildcards.name }}"
    title = _escape(out.title or "").replace("{name}", name)
    where = " (dataset ``{{ snakemake.wildcards.dataset }}``)" if stage.per_dataset else ""
    body = _escape(out.caption).replace("{name}", name)
    return f"**{title}**{where}.\n\n{body}\n"


def report_flags(stage_name: str, caption_dir: str | Path) -> dict[str, dict[str, Any]]:
    """The arguments of Snakemake's ``report()`` for each reported output of a stage.

    Parameters
    ----------
    stage_name : str
        The stage (:func:`spa.pipeline.outputs.get_stage`).
    caption_dir : str or Path
        The folder of the caption files (``workflow/report``).

    Returns
    -------
    dict
        Output key -> ``caption`` (path), ``category``, ``subcategory`` (``"{dataset}"`` or
        ``None``) and ``patterns`` (``["{name}.png"]`` for a folder of figures, else ``[]``).
    """
    stage = get_stage(stage_name)
    return {
        out.key: {
            "caption": str(Path(caption_dir) / caption_file(stage, out)),
            "category": stage.category,
            "subcategory": "{dataset}" if stage.per_dataset else None,
            "patterns": ["{name}.png"] if out.kind == FIGURES else [],
        }
        for s, out in report_outputs()
        if s.name == stage_name
    }


def write_captions(folder: str | Path) -> list[Path]:
    """Write every caption file into ``folder``; return their paths."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    paths = []
    for stage, out in report_outputs():
        path = folder / caption_file(stage, out)
        path.write_text(caption_rst(stage, out), encoding="utf-8", newline="\n")
        paths.append(path)
    return paths


if __name__ == "__main__":  # pragma: no cover - a maintenance command
    for written in write_captions(sys.argv[1] if len(sys.argv) > 1 else "workflow/report"):
        print(written)
