"""The tuning stage for one valve: every table, curve and the recommendation at once.

:func:`tune` runs Section 5 of the paper on a valve's own parameters (a dataset's identified
ones, or any :class:`~spa.model.params.ValveParams`) and returns a :class:`TuningResult`
holding what the workflow writes to ``results/{dataset}/tuning/``: Table 1 at the selected
settings, the sweeps of Fig. 4 (``J`` and ``J_exact``), Table 2 with intervals, the curves of
Fig. 5 and the recommendation, from the valve that
:func:`spa.identification.identified.read_identified` reads (it refuses an identification
that failed with :class:`TuningError`).
"""

from __future__ import annotations

import json
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from spa import _checks as checks
from spa.identification.identified import Identified, TuningError, read_identified
from spa.io import dump_yaml
from spa.model.modulators import Modulator, get_kind
from spa.model.params import ValveParams
from spa.model.thresholds import threshold_table
from spa.model.usable import unusable_reason
from spa.openloop.paper import paper_case
from spa.tuning.cost import DEFAULT_SWEEPS, PAPER_SETTING, check_sweeps, paper_setting, setting
from spa.tuning.recommend import (
    TuningOptions,
    TuningSetup,
    candidate_frame,
    recommend,
    setting_metrics,
)
from spa.tuning.sentence import recommendation_sentence
from spa.tuning.tables import equilibrium_frame, sweep_frame, tuning_table

__all__ = [
    "TuningError",
    "TuningResult",
    "compact_table",
    "format_result",
    "tune",
    "tune_with_config",
]


@dataclass(frozen=True)
class TuningResult:
    """Everything the tuning stage writes for one valve.

    Attributes
    ----------
    identified : Identified
        The valve tuned.
    table1 : pandas.DataFrame
        Dead-zone and saturation (Table 1) at the selected settings (``case`` = ``paper``
        for the paper's, ``selected`` for others), at each modulator's optimum (``optimum``)
        and at the recommendation; ``unusable`` says why a setting cannot work on this
        valve (:func:`spa.model.usable.unusable_reason`), empty where it can.
    sweeps : pandas.DataFrame
        Fig. 4's data: :func:`spa.tuning.tables.sweep_frame` with ``J`` and ``J_exact``.
    table2 : pandas.DataFrame
        :func:`spa.tuning.tables.tuning_table`.
    curves : pandas.DataFrame
        Fig. 5's data at the optima: :func:`spa.tuning.tables.equilibrium_frame` with
        ``p_exact``.
    candidates : pandas.DataFrame
        :func:`spa.tuning.recommend.candidate_frame` (not written by the workflow).
    recommendation : dict
        :func:`spa.tuning.recommend.recommend`, plus ``params``, ``intervals``,
        ``fallback``, ``source`` and ``sentence`` (:func:`recommendation_sentence`).
    """

    identified: Identified
    table1: pd.DataFrame
    sweeps: pd.DataFrame
    table2: pd.DataFrame
    curves: pd.DataFrame
    candidates: pd.DataFrame = field(repr=False)
    recommendation: Mapping[str, Any] = field(default_factory=dict)

    @property
    def sentence(self) -> str:
        """The recommendation in one sentence."""
        return recommendation_sentence(self.recommendation)


def _table1(
    selected: Iterable[Mapping[str, Any] | Modulator],
    optima: Iterable[Modulator],
    recommended: Modulator | None,
    params: ValveParams,
) -> pd.DataFrame:
    chosen = [Modulator.from_mapping(m) for m in selected]
    cases = [("paper" if paper_case(m) else "selected", m) for m in chosen]
    cases += [("optimum", m) for m in optima]
    if recommended is not None:
        cases.append(("recommended", recommended))
    table = threshold_table([m for _, m in cases], params)
    table.insert(0, "case", [c for c, _ in cases])
    table.insert(2, "label", [m.label for _, m in cases])
    table["unusable"] = [unusable_reason(m, params) or "" for _, m in cases]
    return table


def tune(
    valve: ValveParams | Identified | str | Path | Mapping[str, Any],
    *,
    sweeps: Mapping[str, Mapping[str, float]] | None = None,
    n_xi: int = 100,
    options: TuningOptions | Mapping[str, Any] | None = None,
    selected: Iterable[Mapping[str, Any] | Modulator] | None = None,
    linearity: Mapping[str, float] | None = None,
) -> TuningResult:
    """Tune every registered modulator kind for one valve and recommend a setting (Section 5).

    Parameters
    ----------
    valve : ValveParams, Identified, path or mapping
        The valve: parameters (no intervals), or an identification's ``params.yaml`` (path
        or content, :func:`read_identified`), whose 95 % intervals are propagated.
    sweeps : mapping, optional
        ``kind -> {start, stop, step}`` (the config's ``analytic.sweeps``); the paper's grids
        (:data:`spa.tuning.cost.DEFAULT_SWEEPS`) when omitted.
    n_xi : int, default 100
        Points of ``xi`` in the costs (Eq. 25's ``N``).
    options : TuningOptions or mapping, optional
        The config's ``tuning:`` section (score, constraints, gain sweep, staircase).
    selected : iterable, optional
        Settings for Table 1's ``paper`` rows (the config's ``analytic.selected``); the
        paper's four at 20 Hz / 20 ms when omitted.
    linearity : mapping, optional
        Keyword arguments of :func:`spa.openloop.staircase_analysis` for the predicted
        staircase metrics (the config's ``linearity.staircase``).

    Returns
    -------
    TuningResult

    Raises
    ------
    TuningError
        For an identification that failed (:func:`read_identified`).
    ValueError
        For parameters outside the model's domain or a delay longer than a whole sweep
        (:func:`spa.tuning.cost.check_sweeps`), or bad options; the message names them.

    Examples
    --------
    >>> from spa.tuning import tune
    >>> small = {k: {**g, "step": g["step"] * 10} for k, g in DEFAULT_SWEEPS.items()}
    >>> result = tune(ValveParams(), sweeps=small, n_xi=50)
    >>> result.recommendation["recommended"]["modulator"]
    'lpwm'
    """
    if isinstance(valve, Identified):
        ident = valve
    elif isinstance(valve, ValveParams):
        ident = Identified(valve)
    else:
        ident = read_identified(valve)
    p = ident.params
    n = checks.integer("n_xi", n_xi, minimum=2)
    opts = options if isinstance(options, TuningOptions) else TuningOptions.from_mapping(options)
    grids = check_sweeps(DEFAULT_SWEEPS if sweeps is None else sweeps, p)

    data = sweep_frame(grids, p, n, exact=True)
    candidates = candidate_frame(grids, p, n, opts, data)
    table2 = tuning_table(grids, p, n, ident.intervals, data, opts, candidates)
    optima = [
        setting(k, v * get_kind(k).unscale, p)
        for k, v in zip(table2["modulator"], table2["optimum"], strict=True)
    ]
    curves = equilibrium_frame({m.kind: m.value for m in optima}, p, n, exact=True)
    rec = dict(recommend(candidates, TuningSetup(p, n, opts, linearity or {})))
    best = rec["recommended"]
    chosen = Modulator.from_mapping(best["setting"]) if best else None
    if selected is None:
        selected = [paper_setting(k, p) for k in PAPER_SETTING]
    table1 = _table1(selected, optima, chosen, p)
    rec = {
        "source": ident.source,
        "params": p.as_dict(),
        "intervals": {k: list(v) for k, v in ident.intervals.items()},
        "fallback": dict(ident.fallback),
        **({"intervals_clipped": dict(ident.clipped)} if ident.clipped else {}),
        **(
            {"unresolved": {k: list(v) for k, v in ident.unresolved.items()}}
            if ident.unresolved
            else {}
        ),
        "n_xi": n,
        **rec,
    }
    if ident.adequacy is not None:
        from spa.identification.adequacy import adequacy_clause

        kind = str(best["setting"].get("type", "")) if best else ""
        rec["adequacy"] = dict(ident.adequacy)
        rec["verified"] = (
            bool(best) and not adequacy_clause(ident.adequacy, kind) and not ident.unresolved
        )
    rec["sentence"] = recommendation_sentence(rec)
    return TuningResult(ident, table1, data, table2, curves, candidates, rec)


def tune_with_config(
    valve: ValveParams | Identified | str | Path | Mapping[str, Any],
    config: Mapping[str, Any] | None = None,
    **options: Any,
) -> TuningResult:
    """:func:`tune` with the sections of a pipeline configuration (``config/config.yaml``).

    Parameters
    ----------
    valve
        As :func:`tune`.
    config : mapping, optional
        A configuration: ``analytic.sweeps``, ``analytic.n_xi``, ``analytic.selected``,
        ``tuning`` and ``linearity.staircase`` are used where present; the paper's grids and
        the defaults of :class:`~spa.tuning.recommend.TuningOptions` otherwise.
    **options
        Entries of the ``tuning:`` section that override the configuration's (None values
        are ignored), e.g. ``score="J_exact"``.

    Returns
    -------
    TuningResult

    Raises
    ------
    TuningError, ValueError
        As :func:`tune`.
    """
    cfg = dict(config or {})
    analytic = dict(cfg.get("analytic") or {})
    tuning = {
        **dict(cfg.get("tuning") or {}),
        **{k: v for k, v in options.items() if v is not None},
    }
    return tune(
        valve,
        sweeps=analytic.get("sweeps"),
        n_xi=analytic.get("n_xi", 100),
        options=tuning,
        selected=analytic.get("selected"),
        linearity=dict(cfg.get("linearity") or {}).get("staircase"),
    )


def _plain(value: Any) -> Any:
    """NumPy scalars and NaN to plain JSON/YAML values."""
    if isinstance(value, Mapping):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_plain(v) for v in value]
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, float) and not np.isfinite(value):
        return None
    return value


def compact_table(result: TuningResult) -> pd.DataFrame:
    """Table 2 in brief: one row per modulator kind, as ``spa tune`` prints it.

    Parameters
    ----------
    result : TuningResult
        :func:`tune`'s result.

    Returns
    -------
    pandas.DataFrame
        ``modulator``, ``optimum`` (the setting minimising ``J``, its label), ``J``,
        ``J_exact`` (at that setting, bar), ``chattering`` (its largest ``P+ - P-``, bar,
        :func:`spa.tuning.recommend.setting_metrics`), ``J 95 %`` (the interval of ``J``'s
        minimum, only where the identification has intervals) and ``at_grid_edge``: the
        optimum columns of Table 2 whose ``*_at_grid_edge`` flag is set (``-`` for none).

    Examples
    --------
    >>> small = {k: {**g, "step": g["step"] * 10} for k, g in DEFAULT_SWEEPS.items()}
    >>> table = compact_table(tune(ValveParams(), sweeps=small, n_xi=50))
    >>> list(table.columns)
    ['modulator', 'optimum', 'J', 'J_exact', 'chattering', 'at_grid_edge']
    """
    t2 = result.table2
    p = result.identified.params
    n = int(result.recommendation.get("n_xi", 100))
    chattering = [
        float(setting_metrics(k, v * get_kind(k).unscale, p, n)["chattering"])
        for k, v in zip(t2["modulator"], t2["optimum"], strict=True)
    ]
    flags = [c for c in t2.columns if c.endswith("_at_grid_edge")]
    edges = [
        ", ".join(c.removesuffix("_at_grid_edge") for c in flags if bool(row[c])) or "-"
        for _, row in t2.iterrows()
    ]
    table = pd.DataFrame(
        {
            "modulator": t2["modulator"],
            "optimum": t2["label"],
            "J": t2["J_min"],
            "J_exact": t2["J_exact"],
            "chattering": chattering,
        }
    )
    if (t2["interval_method"] != "none").any():
        bounds = zip(t2["J_min_lo"], t2["J_min_hi"], strict=True)
        table["J 95 %"] = [f"{lo:.4g}-{hi:.4g}" for lo, hi in bounds]
    table["at_grid_edge"] = edges
    return table


def format_result(result: TuningResult, as_json: bool = False, as_yaml: bool = False) -> str:
    """Text for people (compact Table 2 and the sentence), or all of it as JSON or YAML.

    Parameters
    ----------
    result : TuningResult
        :func:`tune`'s result.
    as_json : bool, default False
        ``{"table2": [rows], "recommendation": {...}}`` as JSON (every column of Table 2).
    as_yaml : bool, default False
        The same as YAML (:func:`spa.io.dump_yaml`: no aliases).

    Returns
    -------
    str
    """
    if as_json or as_yaml:
        rows = [_plain(r) for r in result.table2.to_dict(orient="records")]
        data = {"table2": rows, "recommendation": _plain(result.recommendation)}
        if as_json:
            return json.dumps(data, indent=2)
        return dump_yaml(data, sort_keys=False, allow_unicode=True)
    table = compact_table(result)
    text = table.to_string(index=False, float_format=lambda x: f"{x:.4g}")
    interval = result.table2["interval_method"].iloc[0]
    lines = [
        f"Table 2 for {result.identified.source} (intervals: {interval}): each modulator's "
        "optimum by J (bar)",
        text,
    ]
    if (table["at_grid_edge"] != "-").any():
        lines.append(
            "at_grid_edge: that optimum is an end of its sweep, the best setting may lie "
            "beyond (widen analytic.sweeps)"
        )
    lines += ["", result.sentence, "(all of Table 2 and the recommendation: --yaml or --json)"]
    return "\n".join(lines) + "\n"
