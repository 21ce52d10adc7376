"""Shared parameter descriptions for numpydoc docstrings (the ``fill_doc`` idiom of MNE-Python).

A docstring line that holds only ``%(name)s`` is replaced, at its indentation, by the entry
``name`` of :data:`DOCDICT`; a parameter shared by many functions is described once.
"""

from __future__ import annotations

import re
import textwrap
from collections.abc import Callable
from typing import TypeVar

F = TypeVar("F", bound=Callable[..., object])

#: Parameter descriptions, unindented; ``%(name)s`` in a docstring stands for one.
DOCDICT: dict[str, str] = {
    "kind": "kind : str\n    Modulator type: a registered kind (``spa.model.modulators.kinds()``).",
    "xi": "xi : array_like of float\n    Input fraction; clipped to [0, 1].",
    "params": "params : ValveParams, optional\n    Valve parameters; nominal when omitted.",
    "settings": (
        "**settings\n    Modulator settings as in :func:`spa.model.averaging.pulse_times`; may "
        "be arrays\n    broadcasting with ``xi``."
    ),
    "train": (
        "t_h, t_l : array_like of float\n    High and low durations of the command in s "
        "(>= 0, may be ``inf``); broadcast."
    ),
    "cost_args": "kind, value, params, n_xi, gain\n    As :func:`spa.tuning.cost.linearity_cost`.",
    "dataset_folder": "folder : str or path-like\n    The dataset folder, ``raw/<name>``.",
    "write_figure_stage": """\
Parameters
----------
result
    The stage's ``run_<stage>``'s result.
out : mapping-like
    Output key to path (``snakemake.output``, or a dict); the figure is drawn where its key
    is given.
dataset : str
    The dataset's name, for the placeholder figure of a dataset without runs of the stage's
    kind.
log : logging.Logger, optional
    Where to say that there is none.""",
    "setting_valve": (
        "modulator : Modulator or mapping\n    Modulator setting.\nparams : ValveParams, optional\n"
        "    The valve; nominal when omitted."
    ),
    "table_figure": (
        "Returns\n-------\nmatplotlib.figure.Figure\n\nRaises\n------\nValueError\n"
        "    If a column is missing."
    ),
    "figure_check": (
        "Parameters\n----------\nfig : matplotlib.figure.Figure\n\nReturns\n-------\nlist of str"
    ),
}

#: Slots that stand for several parameters at once, in signature order.
_GROUPS = {
    "modulator_args": ("kind", "xi", "params", "settings"),
    "kind_xi": ("kind", "xi"),
    "train_params": ("train", "params"),
}
DOCDICT.update({name: "\n".join(DOCDICT[p] for p in parts) for name, parts in _GROUPS.items()})

_SLOT = re.compile(r"^([ \t]*)%\((\w+)\)s[ \t]*$", re.M)


def fill_doc(func: F) -> F:
    """Replace each ``%(name)s`` line of ``func``'s docstring by ``DOCDICT[name]``.

    Examples
    --------
    >>> @fill_doc
    ... def f(xi):
    ...     '''Do nothing.
    ...
    ...     Parameters
    ...     ----------
    ...     %(xi)s
    ...     '''
    >>> print(f.__doc__.splitlines()[4])
        xi : array_like of float
    """
    if func.__doc__:
        func.__doc__ = _SLOT.sub(
            lambda m: textwrap.indent(DOCDICT[m.group(2)], m.group(1)), func.__doc__
        )
    return func
