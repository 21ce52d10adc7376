"""The one registry of what every stage of the pipeline writes, and where.

Each :class:`~spa.pipeline.stage_types.Stage` names its outputs
(:class:`~spa.pipeline.stage_types.Output`): a key, a path relative to the results
folder (``results/``) or to a dataset's folder (``results/<dataset>/``), what kind of file it
is, and how the HTML report shows it (heading and caption, or not at all). The workflow's rules
take their ``output:`` from here (:func:`stage_outputs`), the ``reproduce-all`` target and the
report rule their inputs (:func:`all_targets`), and :mod:`spa.report` its sections, in the
order of :data:`STAGES`. Logs are named here too (:func:`log_path`).

A new stage is one more :class:`~spa.pipeline.stage_types.Stage` in the stage table,
:mod:`spa.pipeline.stage_table`, at its place in the pipeline (the report shows a section's
items in this order), and a rule whose ``output:`` is ``**outputs("<stage>")``. The kinds of
output (``FIGURE``, ``TABLE``, ...) are imported from :mod:`spa.pipeline.stage_types`.

This module imports nothing heavy: the workflow imports it to parse the Snakefile.

>>> stage_outputs("sine", "results")["table"]
'results/{dataset}/sine/linearity.csv'
>>> stage_outputs("sine", "results")["status"]  # every dataset stage: worked or failed
'results/{dataset}/status/sine.json'
>>> log_path("identify", "results", "sim")
'results/logs/sim/identify.log'
"""

from __future__ import annotations

import re
from collections.abc import Callable, Collection, Iterable, Mapping
from pathlib import Path
from typing import Any

from spa.pipeline.stage_table import STAGES
from spa.pipeline.stage_types import FIGURE, FIGURES, VECTOR, Output, Stage

__all__ = [
    "STAGES",
    "all_targets",
    "dataset_folder",
    "figure_paths",
    "get_stage",
    "job_stages",
    "log_path",
    "section_outputs",
    "stage_outputs",
    "stage_settings",
    "wildcard_choice",
]


_DRAWN = (FIGURE, VECTOR, FIGURES)
"""Kinds of output that are figures (left out for a dataset without figures)."""


def job_stages(job: str) -> dict[str, str]:
    """The stages a shared job runs, in the table's order, each with its script's name.

    Parameters
    ----------
    job : str
        ``"ingest"`` or ``"analyse"`` (:attr:`Stage.job`).

    Examples
    --------
    >>> job_stages("ingest")
    {'raw_manifest': 'raw_manifest', 'runs': 'ingest_dataset'}
    >>> list(job_stages("analyse"))[:3]
    ['identify', 'tune', 'validate_model']
    """
    stages = {s.name: s.script or s.name for s in STAGES if s.job == job}
    if not stages:
        raise KeyError(
            f"no stage runs in the job {job!r}; jobs: {sorted({s.job for s in STAGES if s.job})}"
        )
    return stages


def stage_settings(config: Mapping[str, Any], stages: Iterable[str]) -> dict[str, Any]:
    """Each stage's settings: the config section its :attr:`Stage.config` names (``{}`` when
    the config lacks it or the stage names none), as a shared job's ``params.cfg``.

    Examples
    --------
    >>> stage_settings({"linearity": {"sine": {"settle": 2.0}}}, ["sine", "validate_model"])
    {'sine': {'settle': 2.0}, 'validate_model': {}}
    """
    out: dict[str, Any] = {}
    for name in stages:
        value: Any = config
        for key in (get_stage(name).config or "").split("."):
            if not key:
                value = {}
                break
            value = value.get(key, {}) if isinstance(value, Mapping) else {}
        out[name] = value
    return out


def get_stage(name: str) -> Stage:
    """The stage called ``name``.

    Raises
    ------
    KeyError
        If there is none; the message lists the stages.
    """
    for stage in STAGES:
        if stage.name == name:
            return stage
    raise KeyError(f"no stage {name!r}; the stages are {[s.name for s in STAGES]}")


def _root(stage: Stage, results: str | Path, dataset: str) -> Path:
    return Path(results) / dataset if stage.per_dataset else Path(results)


def _output_path(stage: Stage, out: Output, results: str | Path, dataset: str, root: Path) -> Path:
    """Where an output is: under ``root``; a per-dataset output whose path names
    ``{dataset}`` (its report page) under the results folder."""
    if stage.per_dataset and "{dataset}" in out.path:
        return Path(results) / out.path.replace("{dataset}", dataset)
    return root / out.path


def stage_outputs(
    name: str,
    results: str | Path,
    dataset: str = "{dataset}",
    mark_directory: Callable[[str], object] | None = None,
    figures: bool = True,
    vectors: bool = True,
) -> dict[str, object]:
    """The outputs of a stage: key -> path, for a rule's ``output:`` or input.

    Parameters
    ----------
    name : str
        The stage.
    results : str or Path
        The results folder.
    dataset : str, optional
        The dataset of a per-dataset stage; default the wildcard ``{dataset}``.
    mark_directory : callable, optional
        Applied to the path of each folder output (Snakemake's ``directory``).
    figures : bool, optional
        False: without the figures (:data:`FIGURE`, :data:`VECTOR`, :data:`FIGURES`), for a
        dataset whose figures the run does not draw (config ``figures``); their data stay.
    vectors : bool, optional
        False: a per-dataset stage's figures without their SVG copies (:data:`VECTOR`;
        config ``figure_formats`` without ``svg``). The analytic figures keep theirs.

    Returns
    -------
    dict
        Output key -> path (as a string, or as ``mark_directory`` returns it), in order.
    """
    stage = get_stage(name)
    root = _root(stage, results, dataset)
    paths: dict[str, object] = {}
    for out in stage.outputs:
        if not figures and out.kind in _DRAWN:
            continue
        if not vectors and stage.per_dataset and out.kind == VECTOR:
            continue
        path = str(_output_path(stage, out, results, dataset, root))
        paths[out.key] = mark_directory(path) if mark_directory and out.directory else path
    return paths


def log_path(rule: str, results: str | Path, dataset: str = "{dataset}") -> str:
    """The log file of a rule: ``results/logs/...``, as :data:`STAGES` names it.

    Raises
    ------
    KeyError
        If no stage names a log for ``rule``.
    """
    for stage in STAGES:
        if rule in stage.logs:
            return str(Path(results) / "logs" / stage.logs[rule].format(dataset=dataset))
    raise KeyError(f"no stage has a log for rule {rule!r}")


def all_targets(
    results: str | Path,
    datasets: Iterable[str],
    exclude: Iterable[str] = (),
    figures: Collection[str] | None = None,
    vectors: bool = True,
) -> list[str]:
    """Every output of every stage, for every dataset: what ``reproduce-all`` makes.

    Parameters
    ----------
    results : str or Path
        The results folder.
    datasets : iterable of str
        The datasets.
    exclude : iterable of str, optional
        Stages to leave out (the report rule's inputs are everything but the report).
    figures : collection of str, optional
        The datasets whose figures are drawn (config ``figures``); default all of them.
    vectors : bool, optional
        Whether per-dataset figures have SVG copies (config ``figure_formats``).

    Returns
    -------
    list of str
        Paths: the stages that are not per dataset first, then each dataset's outputs.
    """
    skip = set(exclude)
    stages = [s for s in STAGES if s.name not in skip and s.target]
    once = [s for s in stages if not s.per_dataset]
    each = [s for s in stages if s.per_dataset]
    paths = [p for s in once for p in stage_outputs(s.name, results).values()]
    for d in datasets:
        drawn = figures is None or d in figures
        for s in each:
            paths += stage_outputs(s.name, results, d, figures=drawn, vectors=vectors).values()
    return [str(p) for p in paths]


def dataset_folder(stage: str, paths: Mapping[str, object]) -> Path:
    """The dataset folder (``results/<dataset>``) that a per-dataset stage's outputs are in.

    Parameters
    ----------
    stage : str
        The stage.
    paths : mapping
        Some of its outputs, key -> path, as a job sees them.

    Raises
    ------
    ValueError
        If the stage is not per dataset, or no path ends as the registry says it should.

    Examples
    --------
    >>> dataset_folder("sine", {"table": "results/d1/sine/linearity.csv"})
    PosixPath('results/d1')
    """
    stage_ = get_stage(stage)
    if stage_.per_dataset:
        for out in stage_.outputs:
            if "{dataset}" in out.path:
                continue
            path = Path(str(paths.get(out.key, "")))
            if (
                out.key in paths
                and path.parts[-len(Path(out.path).parts) :] == Path(out.path).parts
            ):
                return Path(*path.parts[: -len(Path(out.path).parts)])
    raise ValueError(f"{stage}: no output of a per-dataset stage among {dict(paths)}")


def figure_paths(stages: Iterable[str], results: str | Path, dataset: str) -> list[str]:
    """The figures (PNG, SVG, folders of figures) of a dataset's ``stages``: what a job that
    does not draw them removes, so that no figure of an earlier run outlives its tables.

    Examples
    --------
    >>> figure_paths(["sine"], "results", "d1")
    ['results/d1/sine/fig8.png', 'results/d1/sine/fig8.svg']
    """
    paths: list[str] = []
    for name in stages:
        kept = stage_outputs(name, results, dataset, figures=False)
        paths += [str(p) for k, p in stage_outputs(name, results, dataset).items() if k not in kept]
    return paths


def section_outputs(section: str) -> list[Output]:
    """The outputs of a report section (``"analytic"`` or ``"dataset"``), in report order.

    The section's key item (if any) comes first, then the others in the order of
    :data:`STAGES`. Paths are relative to the results folder (``"analytic"``) or to the
    dataset's folder (``"dataset"``).

    Examples
    --------
    >>> [o.path for o in section_outputs("analytic") if o.shown]
    ['analytic/table1.csv', 'analytic/table2.csv', 'analytic/fig4.png', 'analytic/fig5.png']
    """
    outs = [o for s in STAGES if s.section == section for o in s.outputs]
    return [o for o in outs if o.key_item] + [o for o in outs if not o.key_item]


def wildcard_choice(names: Iterable[str]) -> str:
    """A wildcard constraint (regular expression) matching exactly these names, or nothing.

    Examples
    --------
    >>> print(wildcard_choice(["sim", "a.b"]))
    sim|a\\.b
    >>> wildcard_choice([])
    '(?!x)x'
    """
    names = list(names)
    return "|".join(re.escape(n) for n in names) if names else "(?!x)x"
