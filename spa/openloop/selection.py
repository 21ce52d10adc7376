"""Which runs an analysis takes and which settings its figures show.

`runs_of_kind` and `run_tags` pick and label a dataset's runs; `paper_settings` chooses the
rows that Figs. 7a, 7b and 9 show: the paper's own settings (`PAPER_SETTINGS`), as the paper
does, and where a dataset lacks one of them the best setting of that group by a score,
named as a fallback; a modulator the paper did not test (`beyond_paper`) shows its best
setting too. `best_settings` is that ranking alone; `fallback_note` says which is which.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
import pandas as pd

from spa.model.modulators import MODULATOR_ORDER, Modulator, get_kind
from spa.openloop.paper import PAPER_SETTINGS

__all__ = [
    "best_settings",
    "beyond_paper",
    "fallback_note",
    "paper_settings",
    "run_tags",
    "runs_of_kind",
]


def _group_rank(group: str) -> int:
    """Display order of the groups: a modulator's settings with a gain other than 1 are a
    group of their own, right after it (the paper shows IIPFM with G = 1 and G = 1.15)."""
    kind, gained = group.removesuffix("+G"), group.endswith("+G")
    if kind not in MODULATOR_ORDER or (gained and not get_kind(kind).has_gain):
        return 2 * len(MODULATOR_ORDER) + 1
    return 2 * MODULATOR_ORDER.index(kind) + int(gained)


def runs_of_kind(metas: Mapping[str, Mapping[str, Any]], kind: str) -> list[str]:
    """Run ids of one kind whose metadata names a modulator, in the order of their settings.

    The order is :attr:`spa.model.modulators.Modulator.sort_key`: the paper's modulator order
    (PWM, IPFM, IIPFM, ΔΣM), then the setting's value as a number (10 ms before 100 ms),
    then the gain; runs of the same setting by id.

    Examples
    --------
    >>> runs_of_kind({"b": {"kind": "sine", "modulator": {"type": "pwm", "f_w": 20}},
    ...               "a": {"kind": "charge"}}, "sine")
    ['b']
    """
    ids = [r for r, m in metas.items() if m.get("kind") == kind and m.get("modulator")]
    return sorted(ids, key=lambda r: (Modulator.from_mapping(metas[r]["modulator"]).sort_key, r))


def run_tags(metas: Mapping[str, Mapping[str, Any]], ids: Sequence[str]) -> pd.DataFrame:
    """What tells runs apart in tables and legends: modulator, setting label and gain.

    Parameters
    ----------
    metas : mapping
        Run id -> run metadata with a ``modulator`` mapping.
    ids : sequence of str
        The runs, in the order wanted.

    Returns
    -------
    pandas.DataFrame
        Indexed by run id, with ``modulator`` (type), ``setting`` (its label, or the run id
        when two runs share a label) and ``gain`` (the IPFM/IIPFM gain, 1 for the others).

    Examples
    --------
    >>> m = {"a": {"modulator": {"type": "pwm", "f_w": 20}},
    ...      "b": {"modulator": {"type": "pwm", "f_w": 20}},
    ...      "c": {"modulator": {"type": "iipfm", "t_l": 0.02, "gain": 1.15}}}
    >>> run_tags(m, ["a", "b", "c"])
      modulator           setting  gain
    a       pwm                 a  1.00
    b       pwm                 b  1.00
    c     iipfm  iipfm-20ms-G1.15  1.15
    """
    rows = {}
    for r in ids:
        setting = Modulator.from_mapping(metas[r]["modulator"])
        rows[r] = (setting.kind, setting.label, setting.gain)
    tags = pd.DataFrame.from_dict(rows, orient="index", columns=["modulator", "setting", "gain"])
    shared = tags["setting"].duplicated(keep=False)
    tags.loc[shared, "setting"] = tags.index[shared]
    return tags


def _check_table(table: pd.DataFrame, score: str) -> None:
    for c in ("modulator", "setting", "gain", score):
        if c not in table.columns:
            raise ValueError(f"table lacks column {c!r}; has {list(table.columns)}")


def _groups(table: pd.DataFrame) -> pd.Series:
    return table["modulator"] + np.where(table["gain"] != 1.0, "+G", "")


def _in_order(rows: pd.DataFrame, groups: pd.Series) -> pd.DataFrame:
    order = groups.loc[rows.index].map(_group_rank)
    return rows.assign(_order=order).sort_values(["_order", "setting"]).drop(columns="_order")


def best_settings(table: pd.DataFrame, score: str = "fit", higher: bool = True) -> pd.DataFrame:
    """The best row of each modulator, with the settings of gain other than 1 apart.

    Parameters
    ----------
    table : pandas.DataFrame
        Rows with columns ``modulator``, ``setting``, ``gain`` and ``score``.
    score : str, default "fit"
        Column ranking the settings of one modulator.
    higher : bool, default True
        Whether a higher score is better.

    Returns
    -------
    pandas.DataFrame
        The chosen rows, in the paper's order PWM, IPFM, IIPFM, IIPFM with gain, ΔΣM
        (a modulator's settings with ``gain != 1`` compete only among themselves).
    """
    _check_table(table, score)
    if table.empty:
        return table.copy()
    groups = _groups(table)
    ranked = table[table[score].notna()].sort_values(
        [score, "setting"], ascending=[not higher, True]
    )
    best = ranked.loc[~groups.loc[ranked.index].duplicated()]
    return _in_order(best, groups)


def _paper_groups() -> set[str]:
    """The groups (`_groups`) of the paper's settings."""
    return {m.kind + ("+G" if m.gain != 1.0 else "") for m in PAPER_SETTINGS}


def paper_settings(
    table: pd.DataFrame, score: str = "fit", higher: bool = True
) -> tuple[pd.DataFrame, list[str]]:
    """The rows of the paper's settings, each group falling back to its best when absent.

    Parameters
    ----------
    table : pandas.DataFrame
        Rows with columns ``modulator``, ``setting`` (the `run_tags` label), ``gain`` and
        ``score``.
    score : str, default "fit"
        Column ranking a group's settings when the paper's setting is missing.
    higher : bool, default True
        Whether a higher score is better.

    Returns
    -------
    rows : pandas.DataFrame
        One row per group present (PWM, IPFM, IIPFM, IIPFM with gain, ΔΣM, then the
        modulators the paper did not test, in that order): the paper's setting
        (`PAPER_SETTINGS`: PWM 20 Hz, IPFM 20 ms, IIPFM 20 ms with G = 1 and 1.15, ΔΣM 20 ms)
        when the table has it, else the group's best by ``score``.
    fallbacks : list of str
        The labels of the rows that stand in for a paper's setting the table lacks (a
        group's best). The best of a group the paper has no setting for (`beyond_paper`) is
        not one.

    Examples
    --------
    >>> t = pd.DataFrame({"modulator": ["pwm", "pwm", "iipfm", "lpwm"],
    ...                   "gain": [1.0, 1.0, 1.2, 1.0],
    ...                   "setting": ["pwm-10Hz", "pwm-20Hz", "iipfm-20ms-G1.2", "lpwm-20Hz"],
    ...                   "fit": [80.0, 70.0, 85.0, 90.0]})
    >>> rows, fallbacks = paper_settings(t)
    >>> rows["setting"].tolist(), fallbacks, beyond_paper(rows)
    (['pwm-20Hz', 'iipfm-20ms-G1.2', 'lpwm-20Hz'], ['iipfm-20ms-G1.2'], ['lpwm-20Hz'])
    """
    _check_table(table, score)
    paper = {m.label for m in PAPER_SETTINGS}
    chosen = table[table["setting"].isin(paper)].drop_duplicates("setting")
    groups = _groups(table)
    missing = ~groups.isin(set(groups.loc[chosen.index]))
    best = best_settings(table[missing], score, higher)
    rows = _in_order(pd.concat([chosen, best]), groups)
    stand_in = groups.loc[best.index].isin(_paper_groups())
    return rows, best.loc[stand_in, "setting"].tolist()


def beyond_paper(rows: pd.DataFrame) -> list[str]:
    """The settings of ``rows`` whose group the paper has no setting for (a modulator it did
    not test, such as LPWM, or a gain other than 1 where it showed none), in order.

    Parameters
    ----------
    rows : pandas.DataFrame
        Rows with ``modulator``, ``gain`` and ``setting`` (:func:`paper_settings`' rows).

    Returns
    -------
    list of str

    Examples
    --------
    >>> beyond_paper(pd.DataFrame({"modulator": ["pwm", "lpwm"], "gain": [1.0, 1.0],
    ...                            "setting": ["pwm-20Hz", "lpwm-20Hz"]}))
    ['lpwm-20Hz']
    """
    if rows.empty:
        return []
    return rows.loc[~_groups(rows).isin(_paper_groups()), "setting"].tolist()


def fallback_note(
    fallbacks: Sequence[str],
    score: str,
    higher: bool = True,
    beyond: Sequence[str] = (),
) -> str:
    """What a figure's title says about the settings it shows (:func:`paper_settings`).

    Parameters
    ----------
    fallbacks : sequence of str
        The settings standing in for a paper's setting the dataset lacks.
    score : str
        The column that ranked them (a column name's underscores are read as spaces).
    higher : bool, default True
        Whether a higher score is better: the note says "highest" or "lowest".
    beyond : sequence of str, optional
        The settings shown of modulators the paper did not test (:func:`beyond_paper`).

    Returns
    -------
    str

    Examples
    --------
    >>> fallback_note([], "FIT")
    "the paper's settings"
    >>> fallback_note(["iipfm-20ms-G1.2"], "FIT")
    "the paper's settings; not in this dataset, so iipfm-20ms-G1.2 (its modulator's highest FIT)"
    >>> fallback_note([], "mean_bicoherence", higher=False, beyond=["lpwm-20Hz"])
    "the paper's settings; not in the paper: lpwm-20Hz (its modulator's lowest mean bicoherence)"
    """
    word = "highest" if higher else "lowest"
    name = score.replace("_", " ")
    note = "the paper's settings"
    if fallbacks:
        note += f"; not in this dataset, so {', '.join(fallbacks)} (its modulator's {word} {name})"
    if beyond:
        note += f"; not in the paper: {', '.join(beyond)} (its modulator's {word} {name})"
    return note
