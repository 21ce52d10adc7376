"""What a pipeline stage and its outputs are: the vocabulary of :mod:`spa.pipeline.outputs`.

:class:`Output` (a key, a path, a kind, how the report shows it) and :class:`Stage` (a step of
the pipeline, its outputs and logs), the kinds of output, and the two constructors the
registry uses for analytic and per-dataset stages. Imports nothing heavy.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Final, Literal

TABLE: Final = "table"
"""A CSV table the report shows (``paper_*`` columns beside their own)."""
FIGURE: Final = "figure"
"""A PNG figure the report embeds."""
DATA: Final = "data"
"""A CSV of numbers (a figure's data, a long table): written, not shown in the report."""
PARAMS: Final = "params"
"""The identified parameters (``params.yaml``), shown as a table of the five parameters."""
VECTOR: Final = "vector"
"""The SVG copy of a :data:`FIGURE`, beside its PNG (:func:`spa.plots.save.save_figure`):
written, not shown. Every figure of :data:`STAGES` gets one (key ``<figure key>_svg``)."""
FIGURES: Final = "figures"
"""A folder of PNG figures (with their SVG copies and CSV data), each PNG embedded in the
report."""
RUNS: Final = "runs"
"""A folder of canonical run tables (``<run id>.parquet``)."""
PAGE: Final = "page"
"""The HTML report itself."""
RECOMMENDATION: Final = "recommendation"
"""The tuning stage's ``recommendation.yaml``, shown as its one-sentence summary."""

Kind = Literal[
    "table", "figure", "vector", "data", "params", "figures", "runs", "page", "recommendation"
]
_KINDS = (TABLE, FIGURE, VECTOR, DATA, PARAMS, FIGURES, RUNS, PAGE, RECOMMENDATION)


@dataclass(frozen=True)
class Output:
    """One output of a stage.

    Parameters
    ----------
    key : str
        Its name in the rule's ``output:`` (``rules.<rule>.output.<key>``).
    path : str
        Relative to the results folder, or to ``results/<dataset>`` for a per-dataset stage;
        a per-dataset path that names ``{dataset}`` is relative to the results folder (the
        dataset's report page, ``report/{dataset}.html``).
    kind : str
        One of :data:`TABLE`, :data:`FIGURE`, :data:`VECTOR`, :data:`DATA`, :data:`PARAMS`,
        :data:`FIGURES`, :data:`RUNS`, :data:`PAGE`, :data:`RECOMMENDATION`.
    title : str, optional
        Heading in the report, also its entry in the table of contents; ``None`` (default):
        the report does not show it. For a :data:`FIGURES` folder, ``{name}`` in the title and
        caption stands for each figure's file name without ``.png``.
    caption : str, optional
        What the table or figure shows, printed under it in the report.
    required : bool, optional
        The report fails when a required output it shows is missing and skips a missing
        optional one.
    key_item : bool, optional
        Shown first in its report section, highlighted (Table 3 of a dataset).
    mention : bool, optional
        A long table the report names (where to find it) without reproducing it.
    """

    key: str
    path: str
    kind: Kind
    title: str | None = None
    caption: str = ""
    required: bool = True
    key_item: bool = False
    mention: bool = False

    def __post_init__(self) -> None:
        if self.kind not in _KINDS:
            raise ValueError(f"output {self.key!r}: kind {self.kind!r} is not one of {_KINDS}")
        if self.title is not None and not self.caption:
            raise ValueError(f"output {self.key!r} is shown in the report but has no caption")

    @property
    def directory(self) -> bool:
        """True for a folder of files (:data:`RUNS`, :data:`FIGURES`)."""
        return self.kind in (RUNS, FIGURES)

    @property
    def shown(self) -> bool:
        """True when the report shows it."""
        return self.title is not None


@dataclass(frozen=True)
class Stage:
    """A step of the pipeline and the outputs it writes.

    Parameters
    ----------
    name : str
        What rules call it by (``outputs("<name>")``); the rule's name where one rule writes it.
    per_dataset : bool
        True: one set of outputs per dataset, under ``results/<dataset>``; False: one set under
        ``results``.
    outputs : tuple of Output
        In the order the report shows them.
    logs : mapping of str to str
        Rule name -> its log file, relative to ``results/logs`` (``{dataset}`` for the
        dataset). Several rules may write one stage's outputs (simulated and bench runs).
    section : str or None
        The report section its outputs belong to: ``"analytic"`` (paths relative to the
        results folder; the report's analytic page), ``"dataset"`` (one page per dataset) or
        ``"overview"`` (the report's index); ``None``: none.
    target : bool
        False for an intermediate step that only some datasets have (the raw-data manifest
        of bench datasets): ``reproduce-all`` gets it through the stages that read it.
    upstream : tuple of str or None
        The dataset stages whose outputs it reads (a failure there skips it, spa.pipeline.status);
        None: every dataset stage before it.
    category : str
        Its category in ``snakemake --report`` (:mod:`spa.pipeline.workflow_report`); ``""``: none.
    job : str or None
        The shared job that runs it (``"ingest"``, ``"analyse"``: one per dataset,
        :mod:`spa.pipeline.jobs`), in the table's order; None: a rule of its own.
    script : str or None
        Its script in ``workflow/scripts/`` (without ``.py``); None: the stage's name.
    config : str or None
        The config section of its settings, dotted (``"linearity.staircase"``): in a shared
        job, the stage's script gets it as ``params.cfg``; None: none of its own.
    function : str
        The ``spa`` function that does its work, dotted (``"spa.stages.staircase.run_staircase"``).
    reads : tuple of str or None
        In a shared job, the earlier stages whose outputs its script reads (their outputs are
        its inputs, and their content is part of its digest, :mod:`spa.pipeline.reuse`), or
        ``"<stage>.<output key>"`` for one output of a stage alone;
        ``("*",)``: every stage before it; None: its ``upstream`` (every stage before it when
        that is None too). The job's own inputs are always read.
    read_keys : mapping of str to tuple of str
        ``"<stage>.<output key>"`` of a YAML file it reads -> the dotted keys of it that it
        reads: its script is given a copy holding those alone
        (:func:`spa.pipeline.store.yaml_view`), and its digest covers only them.
    params : tuple of str
        In a shared job, the job's parameters its script reads besides ``cfg`` (the names of
        ``params:`` in ``workflow/rules/analyse.smk``): the stage sees these alone, and their
        values are part of its digest.
    raw_files : tuple of str
        Files of the dataset's raw folder (``<raw_dir>/<dataset>/``) the script reads itself
        (the page reads ``dataset.yaml``'s date and rig): part of its digest.
    """

    name: str
    per_dataset: bool
    outputs: tuple[Output, ...]
    logs: dict[str, str] = field(default_factory=dict)
    section: str | None = None
    target: bool = True
    upstream: tuple[str, ...] | None = None
    category: str = ""
    job: str | None = None
    script: str | None = None
    config: str | None = None
    function: str = ""
    reads: tuple[str, ...] | None = None
    read_keys: dict[str, tuple[str, ...]] = field(default_factory=dict)
    params: tuple[str, ...] = ()
    raw_files: tuple[str, ...] = ()


def _with_vectors(outputs: tuple[Output, ...]) -> tuple[Output, ...]:
    """The outputs, each figure followed by its SVG copy (:data:`VECTOR`)."""
    out: list[Output] = []
    for o in outputs:
        out.append(o)
        if o.kind == FIGURE:
            out.append(Output(f"{o.key}_svg", str(Path(o.path).with_suffix(".svg")), VECTOR))
    return tuple(out)


def _analytic(name: str, *outputs: Output) -> Stage:
    """An analytic step: rule ``analytic_<name>``, log ``logs/analytic/<name>.log``."""
    rule = f"analytic_{name}"
    logs = {rule: f"analytic/{name}.log"}
    return Stage(rule, False, _with_vectors(outputs), logs, section="analytic", category="Analytic")


def _per_dataset(
    name: str,
    *outputs: Output,
    logs: dict[str, str] | None = None,
    upstream: tuple[str, ...] = ("runs", "identify"),
    category: str = "",
    **declared: object,
) -> Stage:
    """A per-dataset step, after ``upstream``: by default written by the rule ``name``, which
    logs to ``logs/{dataset}/<name>.log``; ``logs`` names other rules (rule -> log file);
    ``declared``: the :class:`Stage`'s ``job``, ``script``, ``config``, ``function``,
    ``reads``, ``read_keys``, ``params`` and ``raw_files``."""
    logs = logs or {name: f"{{dataset}}/{name}.log"}
    status = Output("status", f"status/{name}.json", DATA)  # spa.pipeline.status: worked or failed
    outputs = _with_vectors((*outputs, status))
    return Stage(
        name,
        True,
        outputs,
        logs,
        section="dataset",
        upstream=upstream,
        category=category,
        **declared,  # type: ignore[arg-type]
    )
