"""spa._memo: a part of a stage's work kept between runs is the same bits as computed, and
never served for other arguments or other code."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from spa import _memo
from spa.model.params import ValveParams
from spa.pipeline.reuse import code_digest
from spa.tuning import tables
from spa.tuning.recommend import TuningOptions

VALVE = ValveParams(c1=0.45, k2=1.05, tau2=0.70, t_on=0.004, t_off=0.009)
BOX = {"c1": (0.44, 0.46), "k2": (1.04, 1.06), "t_on": (0.0035, 0.0045)}
SWEEPS = {
    "pwm": {"start": 2.0, "stop": 80.0, "step": 6.0},
    "ipfm": {"start": 0.0125, "stop": 0.5, "step": 0.0375},
    "iipfm": {"start": 0.0125, "stop": 0.5, "step": 0.0375},
    "dsm": {"start": 0.0125, "stop": 0.5, "step": 0.0375},
}


@pytest.fixture
def folder(tmp_path):
    _memo.use_folder(tmp_path / "memo", code_digest())
    yield tmp_path / "memo"
    _memo.use_folder(None)


def counted(value: np.ndarray, calls: list[int]):
    def compute() -> np.ndarray:
        calls.append(1)
        return value

    return compute


def test_without_a_folder_every_call_computes() -> None:
    calls: list[int] = []
    for _ in range(2):
        _memo.memoised("x", {"a": 1.0}, counted(np.arange(3.0), calls))
    assert len(calls) == 2


def test_a_kept_result_is_the_same_bits_and_is_not_computed_again(folder) -> None:
    calls: list[int] = []
    value = np.array([[0.1, np.nan], [1e-300, -np.inf]])
    first = _memo.memoised("x", {"v": VALVE, "n": 5}, counted(value, calls))
    again = _memo.memoised("x", {"v": VALVE, "n": 5}, counted(value * 2, calls))
    assert len(calls) == 1 and again.tobytes() == value.tobytes() == first.tobytes()


@pytest.mark.parametrize("change", ["argument", "order", "name", "code"])
def test_other_arguments_or_other_code_compute_again(folder, monkeypatch, change) -> None:
    calls: list[int] = []
    key = {"a": 0.1, "b": 2.0}
    _memo.memoised("x", key, counted(np.zeros(2), calls))
    name = "x"
    if change == "argument":
        key = {"a": 0.1 + 2.0**-55, "b": 2.0}
    elif change == "order":  # a mapping's order may be a table's row order
        key = {"b": 2.0, "a": 0.1}
    elif change == "name":
        name = "y"
    else:  # an edit anywhere in spa/, seen by the next job
        monkeypatch.setattr("spa.io.package_digest", lambda: "edited")
        _memo.use_folder(folder, code_digest())
    out = _memo.memoised(name, key, counted(np.ones(2), calls))
    assert len(calls) == 2 and out.tolist() == [1.0, 1.0]


def test_a_key_of_something_else_than_plain_data_is_refused(folder) -> None:
    with pytest.raises(TypeError, match="not plain data"):
        _memo.memoised("x", {"a": object()}, lambda: np.zeros(1))


def test_tuning_corners_kept_give_the_table_computed_without_them(folder, monkeypatch) -> None:
    """Table 2 with the box's corners taken from the memo (other constraints: a tuning:
    change) equals the table computed without any memo, byte for byte as CSV."""
    calls: list[int] = []
    real = tables._corner_optima

    def corner(grids, valves, n_xi):  # one call for the estimate and every corner
        calls.append(len(valves))
        return real(grids, valves, n_xi)

    monkeypatch.setattr(tables, "_corner_optima", corner)
    tables.tuning_table(SWEEPS, VALVE, 20, intervals=BOX)
    assert calls == [1 + 2**3]
    opts = TuningOptions(max_chattering=0.04)
    kept = tables.tuning_table(SWEEPS, VALVE, 20, intervals=BOX, options=opts)
    assert calls == [1 + 2**3]  # the corners came from the memo
    _memo.use_folder(None)
    fresh = tables.tuning_table(SWEEPS, VALVE, 20, intervals=BOX, options=opts)
    assert calls == [1 + 2**3] * 2
    assert kept.to_csv() == fresh.to_csv()
    pd.testing.assert_frame_equal(kept, fresh)
    wider = {**BOX, "tau2": (0.69, 0.71)}
    _memo.use_folder(folder, code_digest())
    tables.tuning_table(SWEEPS, VALVE, 20, intervals=wider, options=opts)
    assert calls == [1 + 2**3, 1 + 2**3, 1 + 2**4]


DRAWN: list[str] = []


def line_figure(data: pd.DataFrame, title: str = ""):
    from spa.plots.style import new_figure

    DRAWN.append(title)
    fig = new_figure(figsize=(3, 2))
    ax = fig.add_subplot()
    ax.plot(data["x"], data["y"])
    ax.set_title(title)
    return fig


def test_a_figure_of_the_same_data_is_copied_not_drawn(folder, tmp_path) -> None:
    from spa.plots.save import FIGURE_FORMATS, draw, set_figure_formats

    formats = list(FIGURE_FORMATS)
    set_figure_formats(["png"])
    try:
        DRAWN.clear()
        data = pd.DataFrame({"x": np.arange(5.0), "y": np.arange(5.0) ** 2})
        a, b = tmp_path / "a.png", tmp_path / "b.png"
        draw(a, line_figure, data, title="one")
        draw(b, line_figure, data.copy(), title="one")
        assert DRAWN == ["one"] and a.read_bytes() == b.read_bytes()
        _memo.use_folder(None)
        draw(tmp_path / "fresh.png", line_figure, data, title="one")
        assert (tmp_path / "fresh.png").read_bytes() == b.read_bytes()
        _memo.use_folder(folder, code_digest())
        changed = data.assign(y=data["y"] + 1e-12)
        draw(tmp_path / "c.png", line_figure, changed, title="one")
        draw(tmp_path / "d.png", line_figure, data, title="two")
        set_figure_formats(["png", "svg"])
        draw(tmp_path / "e.png", line_figure, data, title="one")
        assert DRAWN == ["one", "one", "one", "two", "one"]
        assert (tmp_path / "e.svg").is_file()
        draw(tmp_path / "f.png", lambda d: line_figure(d, "l"), data)
        draw(tmp_path / "g.png", lambda d: line_figure(d, "l"), data)
        assert DRAWN[-2:] == ["l", "l"]
    finally:
        set_figure_formats(formats)


def test_tuning_exact_sweep_kept_gives_the_frame_computed_without_it(folder) -> None:
    kept_first = tables.sweep_frame(SWEEPS, VALVE, 20, exact=True)
    kept = tables.sweep_frame(SWEEPS, VALVE, 20, exact=True)
    assert any((folder / "tuning-exact-sweep").iterdir())
    _memo.use_folder(None)
    fresh = tables.sweep_frame(SWEEPS, VALVE, 20, exact=True)
    assert kept.to_csv() == fresh.to_csv() == kept_first.to_csv()
    pd.testing.assert_frame_equal(kept, fresh)
