"""Several dataset stages in one Snakemake job.

A job costs a new interpreter and its imports (about a second, ``benchmarks/bench_imports.py``)
and Snakemake's bookkeeping before any work; the stages of a dataset run in two jobs, its
ingest (manifest and run tables) and its analysis (identify, tune, validate_model, staircase,
sine, chirp). The rule's outputs are every stage's outputs, keys joined as ``<stage>__<key>``
(:func:`joined_outputs`), its logs named by stage; the job's script runs each stage's own
script with a view of the job that holds that stage's outputs, log and ``cfg`` alone, and the
outputs of the stages before it as inputs (:func:`stage_job`), so a stage's script is the same
whether it runs alone or shared, and each stage still records its own status
(:mod:`spa.pipeline.status`). A job that does not draw its stages' figures (config
``figures``) first removes those an earlier run left (:func:`remove_undrawn_figures`).
"""

from __future__ import annotations

import shutil
from collections.abc import Callable, Iterable, Iterator, Mapping
from pathlib import Path
from types import SimpleNamespace
from typing import Any

__all__ = ["JOIN", "Names", "joined_outputs", "remove_undrawn_figures", "stage_job"]

JOIN = "__"
"""Between a stage's name and an output key in a shared job's outputs."""


class Names:
    """Named values with attribute, key and position access, like Snakemake's ``Namedlist``.

    Examples
    --------
    >>> n = Names({"table": "a.csv", "status": "s.json"})
    >>> n.table, n[1], list(n), dict(n.items())["status"]
    ('a.csv', 's.json', ['a.csv', 's.json'], 's.json')
    """

    def __init__(self, items: Mapping[str, Any]) -> None:
        self._items = dict(items)

    def __getattr__(self, name: str) -> Any:
        try:
            return self.__dict__["_items"][name]
        except KeyError:
            raise AttributeError(name) from None

    def __getitem__(self, key: int | str) -> Any:
        return list(self._items.values())[key] if isinstance(key, int) else self._items[key]

    def __iter__(self) -> Iterator[Any]:
        return iter(self._items.values())

    def __len__(self) -> int:
        return len(self._items)

    def items(self) -> Iterable[tuple[str, Any]]:
        """(name, value) pairs, in order."""
        return self._items.items()

    def get(self, key: str, default: Any = None) -> Any:
        """The value called ``key``, or ``default``."""
        return self._items.get(key, default)


def joined_outputs(
    stages: Iterable[str], outputs: Callable[[str], Mapping[str, Any]]
) -> dict[str, Any]:
    """Every output of ``stages``, keyed ``<stage>__<key>``: a shared job's ``output:``.

    Parameters
    ----------
    stages : iterable of str
        Stage names (:data:`spa.pipeline.outputs.STAGES`).
    outputs : callable
        A stage's named outputs (the workflow's ``outputs``).

    Examples
    --------
    >>> joined_outputs(["sine"], lambda s: {"table": f"{s}.csv"})
    {'sine__table': 'sine.csv'}
    """
    return {f"{stage}{JOIN}{key}": path for stage in stages for key, path in outputs(stage).items()}


def stage_job(smk: Any, stage: str) -> SimpleNamespace:
    """The view of a shared job that one stage's script sees as ``snakemake``.

    Parameters
    ----------
    smk : snakemake.script.Snakemake
        The shared job: outputs from :func:`joined_outputs`, one log per stage named by the
        stage, ``params.stages`` the stages in the order they run (optional),
        ``params.cfg`` a mapping stage -> that stage's settings (optional).
    stage : str
        The stage.

    Returns
    -------
    types.SimpleNamespace
        ``wildcards`` and ``config`` as the job's; ``input`` the job's inputs and, under
        their own keys, the outputs of the stages that run before this one (a key the job's
        inputs or an earlier stage already use is not overwritten: identify's ``params`` is
        tune's ``input.params``); ``output`` the stage's outputs under their own keys;
        ``log`` the stage's log alone; ``params`` the job's, with ``cfg`` the stage's
        settings.

    Raises
    ------
    KeyError
        If the job has no outputs of ``stage``.
    """
    output = _stage_outputs(smk, stage)
    params = dict(smk.params.items())
    params["cfg"] = (params.get("cfg") or {}).get(stage, {})
    order = list(params.get("stages") or ())
    inputs = dict(smk.input.items())
    for before in order[: order.index(stage)] if stage in order else ():
        for key, path in _stage_outputs(smk, before).items():
            inputs.setdefault(key, path)
    return SimpleNamespace(
        input=Names(inputs),
        output=Names(output),
        log=Names({"log": getattr(smk.log, stage)}),
        params=Names(params),
        wildcards=smk.wildcards,
        config=getattr(smk, "config", {}),
        rule=stage,
    )


def _stage_outputs(smk: Any, stage: str) -> dict[str, Any]:
    """One stage's outputs in a shared job, under their own keys."""
    prefix = f"{stage}{JOIN}"
    output = {k[len(prefix) :]: v for k, v in smk.output.items() if k.startswith(prefix)}
    if not output:
        raise KeyError(f"the job has no outputs of stage {stage!r} (keys {prefix}...)")
    return output


def remove_undrawn_figures(smk: Any) -> list[str]:
    """Remove the figures of the job's stages that the job does not draw (config
    ``figures``) but an earlier run left, so that no figure outlives the tables it shows.

    Parameters
    ----------
    smk : snakemake.script.Snakemake
        The shared job: outputs from :func:`joined_outputs` of per-dataset stages,
        ``params.stages`` its stages.

    Returns
    -------
    list of str
        The files and folders removed.
    """
    from spa.pipeline.outputs import dataset_folder, figure_paths

    stages = list(smk.params.get("stages") or ())
    if not stages:
        return []
    folder = dataset_folder(stages[0], _stage_outputs(smk, stages[0]))
    drawn = {str(path) for path in smk.output}
    removed = []
    for path in figure_paths(stages, folder.parent, folder.name):
        target = Path(path)
        if path in drawn or not (target.exists() or target.is_symlink()):
            continue
        if target.is_dir() and not target.is_symlink():
            shutil.rmtree(target)
        else:
            target.unlink()
        removed.append(path)
    return removed
