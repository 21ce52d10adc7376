"""Several dataset stages in one Snakemake job.

A job costs a new interpreter and its imports (about a second, ``benchmarks/bench_imports.py``)
before any work; stages that read the same inputs and that a user does not rerun one by one
share a job. The rule's outputs are every stage's outputs, keys joined as ``<stage>__<key>``
(:func:`joined_outputs`), its logs named by stage; the job's script runs each stage's own
script with a view of the job that holds that stage's outputs, log and ``cfg`` alone
(:func:`stage_job`), so a stage's script is the same whether it runs alone or shared, and
each stage still records its own status (:mod:`spa.status`).
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Iterator, Mapping
from types import SimpleNamespace
from typing import Any

__all__ = ["JOIN", "Names", "joined_outputs", "stage_job"]

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
        Stage names (:data:`spa.outputs.STAGES`).
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
        stage, ``params.cfg`` a mapping stage -> that stage's settings (optional).
    stage : str
        The stage.

    Returns
    -------
    types.SimpleNamespace
        ``input``, ``wildcards``, ``config`` as the job's; ``output`` the stage's outputs
        under their own keys; ``log`` the stage's log alone; ``params`` the job's, with
        ``cfg`` the stage's settings.
    """
    prefix = f"{stage}{JOIN}"
    output = {k[len(prefix) :]: v for k, v in smk.output.items() if k.startswith(prefix)}
    if not output:
        raise KeyError(f"the job has no outputs of stage {stage!r} (keys {prefix}...)")
    params = dict(smk.params.items())
    params["cfg"] = (params.get("cfg") or {}).get(stage, {})
    return SimpleNamespace(
        input=smk.input,
        output=Names(output),
        log=Names({"log": getattr(smk.log, stage)}),
        params=Names(params),
        wildcards=smk.wildcards,
        config=getattr(smk, "config", {}),
        rule=stage,
    )
