"""No figure text has empty parentheses (issue 46: Fig. 2b read "no discharge fit ()").

The identification's figures of a dataset with a missing fit are rendered (every figure the
stage draws, captured as it is saved) and every text of each, legends first, is checked
with spa.plots.check.empty_parentheses.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from spa import ValveParams, simulate
from spa.identification import identification_commands, identify
from spa.plots.check import empty_parentheses
from spa.plots.words import noted
from spa.stages.identify import write_identification

DT = 1e-3


def _measure(u: np.ndarray, params: ValveParams, p0: float, seed: int) -> pd.DataFrame:
    p = simulate(u, DT, params, p0)
    p = p + np.random.default_rng(seed).normal(0.0, 0.005, p.size)
    return pd.DataFrame({"t": DT * np.arange(u.size), "p": p, "valve": u})


def _drawn(monkeypatch, result, runs, kinds, tmp_path) -> dict[str, object]:
    """Every figure write_identification draws, by file name, as it would be saved."""
    import spa.plots.save as save

    figures: dict[str, object] = {}
    monkeypatch.setattr(save, "save_figure", lambda fig, path, **_: figures.update({path: fig}))
    out = {"params": tmp_path / "params.yaml"}
    for key in ("fig2a", "fig2b", "fig2c"):
        out[key], out[f"{key}_csv"] = tmp_path / f"{key}.png", tmp_path / f"{key}.csv"
    write_identification(result, runs, kinds, out, "d")
    return {str(p).rsplit("/", 1)[-1]: f for p, f in figures.items()}


@pytest.mark.parametrize("with_fallback", [True, False])
def test_no_legend_or_title_has_empty_parentheses_with_a_fit_missing(
    monkeypatch, tmp_path, with_fallback
):
    truth = ValveParams()
    cmds = identification_commands(DT)
    runs = {
        "charge": _measure(cmds["charge"], truth, 0.0, 1),
        "pulse": _measure(cmds["pulse"], truth, 0.0, 2),
    }
    kinds = {"charge": "charge", "pulse": "pulse"}
    fallback = ValveParams(c1=0.5, k2=0.8, tau2=0.8, t_on=0.004, t_off=0.009)
    result = identify([runs["charge"]], None, [runs["pulse"]], fallback=fallback, n_boot=20)
    assert result.discharge is None and "c1" in result.fallback
    if not with_fallback:  # the parenthetical's content is empty: no fallback named
        object.__setattr__(result, "fallback", {})
    figures = _drawn(monkeypatch, result, runs, kinds, tmp_path)
    assert set(figures) == {"fig2a.png", "fig2b.png", "fig2c.png"}
    legends = 0
    for name, fig in figures.items():
        for ax in fig.axes:
            legend = ax.get_legend()
            if legend is not None:
                legends += 1
                for text in legend.get_texts():
                    assert "()" not in text.get_text().replace(" ", ""), (name, text.get_text())
        assert empty_parentheses(fig) == [], name
    assert legends >= 2  # Fig. 2a's and Fig. 2c's legends were read
    texts = [t.get_text() for t in figures["fig2b.png"].findobj(lambda a: hasattr(a, "get_text"))]
    said = [t for t in texts if "no discharge fit" in t]
    assert said and all(("(" in t) is with_fallback for t in said)


def test_noted_drops_empty_parentheses():
    assert noted("no pulse runs", " ") == "no pulse runs"
    assert noted("no pulse runs", "c1 from the fallback") == "no pulse runs (c1 from the fallback)"
