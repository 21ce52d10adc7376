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

__all__ = [
    "JOIN",
    "Names",
    "joined_outputs",
    "read_files",
    "read_stages",
    "remove_undrawn_figures",
    "stage_job",
    "stage_params",
]

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
        their own keys, the outputs of the earlier stages it reads (:attr:`Stage.reads
        <spa.pipeline.stage_types.Stage.reads>`, :func:`read_stages`; a
        key the job's inputs or an earlier stage already use is not overwritten:
        identify's ``params`` is tune's ``input.params``); ``output`` the stage's outputs
        under their own keys; ``log`` the stage's log alone; ``params``
        (:func:`stage_params`) ``cfg``, the stage's settings, and the job's parameters it
        declares it reads.

    Raises
    ------
    KeyError
        If the job has no outputs of ``stage``.
    """
    output = _stage_outputs(smk, stage)
    params = stage_params(smk, stage)
    inputs = dict(smk.input.items())
    for _, key, path in _read_outputs(smk, stage):
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


def stage_params(smk: Any, stage: str) -> dict[str, Any]:
    """The parameters one stage of a shared job sees: ``cfg`` (its settings), ``code`` and
    ``stages`` (the job's), and those the stage table says it reads (:attr:`Stage.params
    <spa.pipeline.stage_types.Stage.params>`), so that every setting it can read is one its
    digest covers (:mod:`spa.pipeline.reuse`). A stage not in the table sees them all.

    Examples
    --------
    >>> job = SimpleNamespace(params=Names({"cfg": {"tune": {"a": 1}}, "seed": 1, "n_xi": 5}))
    >>> stage_params(job, "tune")
    {'cfg': {'a': 1}, 'n_xi': 5}
    """
    from spa.pipeline.outputs import get_stage

    params = dict(smk.params.items())
    params["cfg"] = (params.get("cfg") or {}).get(stage, {})
    try:
        declared = set(get_stage(stage).params)
    except KeyError:
        return params
    return {k: v for k, v in params.items() if k in declared or k in ("cfg", "code", "stages")}


def read_stages(stage: str, order: Iterable[str]) -> list[str]:
    """The stages of a shared job whose outputs ``stage`` reads.

    Parameters
    ----------
    stage : str
        A stage of :data:`spa.pipeline.stage_table.STAGES`.
    order : iterable of str
        The stages of the job, in the order they run.

    Returns
    -------
    list of str
        Those before ``stage`` that it reads (:attr:`Stage.reads
        <spa.pipeline.stage_types.Stage.reads>`, else its ``upstream``, else all), in order.

    Examples
    --------
    >>> read_stages("tune", ["identify", "tune", "sine"])
    ['identify']
    >>> read_stages("sine", ["identify", "tune", "sine"])
    ['identify']
    >>> read_stages("page", ["identify", "tune", "page"])
    ['identify', 'tune']
    """
    from spa.pipeline.outputs import get_stage

    order = list(order)
    before = order[: order.index(stage)] if stage in order else []
    declared = get_stage(stage).reads
    if declared is None:
        declared = get_stage(stage).upstream
    if declared is None or "*" in declared:
        return before
    names = {d.split(".", 1)[0] for d in declared}
    return [s for s in before if s in names]


def _read_outputs(smk: Any, stage: str) -> list[tuple[str, str, Any]]:
    """``(earlier stage, output key, path)`` of every output of the earlier stages that
    ``stage`` reads: all of a stage its ``reads`` names, one output for ``"<stage>.<key>"``;
    an output of which it reads some fields (:attr:`Stage.read_keys
    <spa.pipeline.stage_types.Stage.read_keys>`) as the copy holding those alone
    (:func:`spa.pipeline.store.yaml_view`, in the results' store)."""
    from spa.pipeline.outputs import dataset_folder, get_stage
    from spa.pipeline.store import STORE, VIEWS, yaml_view

    try:
        spec = get_stage(stage)
    except KeyError:
        spec = None
    declared = () if spec is None else (spec.reads or ())
    fields = {} if spec is None else spec.read_keys
    out = []
    for before in _read_stages(smk, stage):
        outputs = _stage_outputs(smk, before)
        keys = {d.split(".", 1)[1] for d in declared if d.startswith(f"{before}.")}
        for key, path in outputs.items():
            if keys and before not in declared and key not in keys:
                continue
            part = fields.get(f"{before}.{key}")
            if part:
                views = dataset_folder(before, outputs).parent / STORE / VIEWS
                path = str(yaml_view(path, tuple(part), views))
            out.append((before, key, path))
    return out


def _read_stages(smk: Any, stage: str) -> list[str]:
    """The stages of the job before ``stage`` whose outputs it reads."""
    from spa.pipeline.outputs import get_stage

    order = list(smk.params.get("stages") or ())
    try:
        get_stage(stage)
    except KeyError:
        return order[: order.index(stage)] if stage in order else []
    return read_stages(stage, order)


def read_files(smk: Any, stage: str) -> dict[str, Any]:
    """Every file or folder one stage of a shared job reads, keyed ``<stage>__<key>`` for
    the outputs of the earlier stages it reads (:func:`_read_outputs`) and by their own keys
    for the job's inputs (a status file's key ends in ``status``)."""
    files = {f"input{JOIN}{k}": v for k, v in smk.input.items()}
    files.update({f"{before}{JOIN}{k}": v for before, k, v in _read_outputs(smk, stage)})
    return files


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
