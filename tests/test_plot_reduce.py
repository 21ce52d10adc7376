"""Figures at the cost of their pixels (spa.plots.reduce): a long trace is drawn through at
most four samples per pixel column (M4), and the figure looks the same as one drawn through
every sample: at most 0.5 % of the pixels differ by more than 16 grey levels."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from matplotlib.figure import Figure

from spa.plots import reduce as reduce_
from spa.plots.reduce import PER_COLUMN, axes_columns, plot_reduced, reduce_indices
from spa.plots.save import save_figure

SHARE = 0.005  # of the pixels
LEVELS = 16  # grey levels


def _pixels(fig: Figure, path) -> np.ndarray:
    from PIL import Image

    save_figure(fig, path, vector=False)
    return np.asarray(Image.open(path).convert("L")).astype(int)


def _both_ways(make, tmp_path, name: str) -> tuple[float, int, int]:
    """Share of pixels differing by more than LEVELS, and the points drawn each way."""

    def points(fig: Figure) -> int:
        return sum(len(line.get_xdata()) for ax in fig.axes for line in ax.get_lines())

    reduce_.REDUCE["on"] = False
    try:
        whole = make()
        n_whole = points(whole)
        ref = _pixels(whole, tmp_path / f"{name}-whole.png")
    finally:
        reduce_.REDUCE["on"] = True
    reduced = make()
    n_reduced = points(reduced)
    new = _pixels(reduced, tmp_path / f"{name}-reduced.png")
    assert new.shape == ref.shape
    return float((np.abs(new - ref) > LEVELS).mean()), n_whole, n_reduced


def _staircase(n: int = 55_000, seed: int = 3) -> tuple[np.ndarray, np.ndarray]:
    """A 1 kHz staircase with 20 Hz chattering, noise and isolated spikes."""
    t = np.arange(n) * 1e-3
    rng = np.random.default_rng(seed)
    p = 0.1 * np.floor(t / 5.0) + 0.02 * (np.sin(2 * np.pi * 20 * t) > 0)
    p = p + rng.normal(0, 2e-3, t.size)
    p[rng.choice(t.size, 12, replace=False)] += 0.3
    return t, p


# --- the reduction ----------------------------------------------------------------------------


def test_the_reduction_keeps_every_columns_extremes_and_the_ends():
    t, p = _staircase()
    keep = reduce_indices(t, p, columns=1000)
    assert len(keep) <= PER_COLUMN * 1000 + 2
    assert keep[0] == 0 and keep[-1] == t.size - 1 and np.all(np.diff(keep) > 0)
    # per column of equal width, the largest and smallest sample are kept
    col = np.minimum((t / t[-1] * 1000).astype(int), 999)
    kept = np.zeros(t.size, bool)
    kept[keep] = True
    for c in range(0, 1000, 37):
        inside = np.flatnonzero(col == c)
        assert kept[inside[np.argmax(p[inside])]] and kept[inside[np.argmin(p[inside])]]


def test_a_short_trace_or_a_flat_abscissa_is_kept_whole():
    t = np.arange(100.0)
    assert np.array_equal(reduce_indices(t, t, columns=25), np.arange(100))
    assert np.array_equal(reduce_indices(np.zeros(1000), np.ones(1000), 10), np.arange(1000))


def test_nan_gaps_stay_gaps():
    t, p = _staircase(20_000)
    p[5_000:6_000] = np.nan
    keep = reduce_indices(t, p, columns=200)
    assert np.isnan(p[keep]).any()


def test_bad_input_is_named():
    with pytest.raises(ValueError, match="non-decreasing"):
        reduce_indices(np.r_[np.arange(1000.0), 5.0], np.zeros(1001), columns=10)
    with pytest.raises(ValueError, match="columns"):
        reduce_indices(np.arange(10.0), np.zeros(10), columns=0)


def test_plot_reduced_uses_the_axes_pixel_width_and_draws_a_non_monotonic_x_whole():
    fig = Figure(figsize=(10.0, 3.0))
    ax = fig.add_subplot()
    t, p = _staircase()
    (line,) = plot_reduced(ax, t, p)
    cols = axes_columns(ax)
    assert 1000 < cols < 2000  # 10 in at 200 dpi, less the margins
    assert len(line.get_xdata()) <= PER_COLUMN * cols + 2
    (loop,) = plot_reduced(ax, np.sin(t), p)  # a Lissajous figure: no pixel columns
    assert len(loop.get_xdata()) == t.size


# --- the figures, drawn both ways -------------------------------------------------------------


def test_fig6_reduced_looks_like_every_sample(tmp_path):
    from spa.plots.openloop import fig6

    t, p = _staircase()
    traces = pd.concat(
        [
            pd.DataFrame({"t": t, "p": p * k, "modulator": kind, "setting": setting})
            for k, kind, setting in ((1.0, "pwm", "pwm-20Hz"), (0.9, "dsm", "dsm-20ms"))
        ]
    )
    share, whole, reduced = _both_ways(lambda: fig6(traces), tmp_path, "fig6")
    assert share <= SHARE and reduced < whole / 4


def test_validation_overlay_and_fig2c_reduced_look_like_every_sample(tmp_path):
    from spa.plots.identification import fig2c, validation_figure

    t, p = _staircase(60_000, seed=5)
    valve = (np.sin(2 * np.pi * 7 * t) > 0).astype(float)
    data = pd.DataFrame({"t": t, "valve": valve, "p": p, "p_model": p + 0.01 * np.cos(t)})
    data["error"] = data["p"] - data["p_model"]
    share, whole, reduced = _both_ways(
        lambda: validation_figure(data, "staircase: run s1 (FIT 90 %)"), tmp_path, "val"
    )
    assert share <= SHARE and reduced < whole / 4
    share, whole, reduced = _both_ways(lambda: fig2c(data), tmp_path, "fig2c")
    assert share <= SHARE and reduced < whole / 2


def test_fig10_reduced_looks_like_every_sample(tmp_path):
    from spa.plots.closedloop import fig10

    t = np.arange(8_000) * 0.05  # cycle means of a 20 Hz modulator over a 400 s staircase
    r = 0.1 * (1 + np.floor(t / 50.0))
    rows = []
    for k, controller in enumerate(("fixed", "scheduled", "scheduled_ff")):
        # a cycle mean is smooth: its ripple is below a pixel (a dashed line through a
        # trace that zigzags within each pixel column would move its dashes, see the docs)
        p = r * (1 - np.exp(-(t % 50.0) / (0.3 + 0.1 * k))) + 2e-4 * np.sin(4 * t)
        for setting in ("pwm-20Hz", "iipfm-20ms"):
            rows.append(
                pd.DataFrame(
                    {"modulator": setting, "controller": controller, "t": t, "r": r, "p_mean": p}
                )
            )
    traces = pd.concat(rows, ignore_index=True)
    share, whole, reduced = _both_ways(lambda: fig10(traces), tmp_path, "fig10")
    assert share <= SHARE and reduced < whole / 4


def test_a_log_axis_is_reduced_in_its_own_columns(tmp_path):
    f = np.logspace(-2, 2, 80_000)
    rng = np.random.default_rng(1)
    y = 1.0 / np.sqrt(1 + f**2) + rng.normal(0, 0.01, f.size)

    def make() -> Figure:
        fig = Figure(figsize=(8.0, 3.0), layout="constrained")
        ax = fig.add_subplot()
        ax.set_xscale("log")
        plot_reduced(ax, f, y, lw=0.8, color="#0072B2")
        return fig

    share, whole, reduced = _both_ways(make, tmp_path, "log")
    assert share <= SHARE and reduced < whole / 4


def test_every_kth_sample_differs_from_every_sample(tmp_path):
    """The test can fail: every k-th sample (no extremes kept) loses the spikes and the
    chattering's envelope, and differs in more than 0.5 % of the pixels."""
    from spa.plots.openloop import fig6

    t, p = _staircase()
    full = pd.DataFrame({"t": t, "p": p, "modulator": "pwm", "setting": "pwm-20Hz"})
    every_kth = full.iloc[:: -(-len(full) // 6000)]
    reduce_.REDUCE["on"] = False
    try:
        ref = _pixels(fig6(full), tmp_path / "full.png")
        kth = _pixels(fig6(every_kth), tmp_path / "kth.png")
    finally:
        reduce_.REDUCE["on"] = True
    assert (np.abs(kth - ref) > LEVELS).mean() > SHARE


def test_the_csv_beside_fig6_keeps_every_sample(small_run):
    """Only the drawing is reduced: Fig. 6's CSV holds every sample of each staircase run."""
    from spa.datasets import read_runs

    for ds in ("sim", "example"):
        csv = pd.read_csv(small_run / ds / "staircase" / "fig6.csv")
        runs, _ = read_runs(small_run / ds / "runs")
        for run, rows in csv.groupby("run"):
            assert len(rows) == len(runs[run]), (ds, run)


# --- formats: PNG by default, the layout computed once ------------------------------------------


def test_constrained_layout_is_computed_once_for_png_and_svg(tmp_path, monkeypatch):
    from matplotlib.layout_engine import ConstrainedLayoutEngine

    calls = []
    execute = ConstrainedLayoutEngine.execute
    monkeypatch.setattr(
        ConstrainedLayoutEngine, "execute", lambda self, fig: calls.append(1) or execute(self, fig)
    )
    fig = Figure(figsize=(6.0, 3.0), layout="constrained")
    ax = fig.add_subplot()
    t, p = _staircase(5_000)
    plot_reduced(ax, t, p)
    ax.set_title("one layout")
    save_figure(fig, tmp_path / "f.png", vector=True)
    assert (tmp_path / "f.png").is_file() and (tmp_path / "f.svg").is_file()
    assert len(calls) == 1


def test_figure_formats_decide_the_svg_copy_and_the_declared_outputs(tmp_path):
    from spa.pipeline.outputs import all_targets, get_stage, stage_outputs
    from spa.pipeline.stage_types import VECTOR
    from spa.plots import save

    keep = list(save.FIGURE_FORMATS)
    try:
        assert save.set_figure_formats(["png"]) == ["png"]
        save_figure(Figure(figsize=(3.0, 2.0)), tmp_path / "a.png")
        assert save.set_figure_formats(["png", "svg"]) == ["png", "svg"]
        save_figure(Figure(figsize=(3.0, 2.0)), tmp_path / "b.png")
        with pytest.raises(ValueError, match="figure_formats"):
            save.set_figure_formats(["svg"])
        with pytest.raises(ValueError, match="figure_formats"):
            save.set_figure_formats(["png", "pdf"])
    finally:
        save.FIGURE_FORMATS[:] = keep
    assert not (tmp_path / "a.svg").exists() and (tmp_path / "b.svg").is_file()
    # the stage table: a dataset's figures lose their SVG outputs, the analytic ones keep them
    sine = stage_outputs("sine", "results", "d1", vectors=False)
    assert "fig8" in sine and "fig8_svg" not in sine
    assert "fig8_svg" in stage_outputs("sine", "results", "d1")
    vectors = [o.key for o in get_stage("analytic_fig4").outputs if o.kind == VECTOR]
    assert vectors and all(
        k in stage_outputs("analytic_fig4", "results", vectors=False) for k in vectors
    )
    targets = all_targets("results", ["d1"], vectors=False)
    assert "results/analytic/fig4.svg" in targets
    assert not [t for t in targets if t.startswith("results/d1/") and t.endswith(".svg")]


def test_the_config_defaults_to_png_and_the_schema_checks_the_formats():
    import yaml

    from spa.pipeline.config import validate_config

    root = __import__("pathlib").Path(__file__).resolve().parents[1]
    config = yaml.safe_load((root / "config" / "config.yaml").read_text(encoding="utf-8"))
    assert config["figure_formats"] == ["png"]
    schema = root / "workflow" / "schemas" / "config.schema.yaml"
    validate_config({**config, "figure_formats": ["png", "svg"]}, schema)
    with pytest.raises(Exception, match="figure_formats"):
        validate_config({**config, "figure_formats": ["svg"]}, schema)


def test_asking_for_svg_copies_declares_them_for_every_dataset(small_run, isolated_config):
    """A finished run (PNG alone) asked for `figure_formats: [png, svg]` has its analyses
    to redo, for the SVG copies they now declare; the default asks for nothing."""
    import subprocess
    import sys
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]

    def dry(*extra: str) -> str:
        res = subprocess.run(
            [sys.executable, "-m", "snakemake", "reproduce-all", "-n", "--configfile",
             "config/small.yaml", str(isolated_config), "--config", f"results={small_run}",
             *extra],
            cwd=root, capture_output=True, text=True, timeout=300,
        )  # fmt: skip
        assert res.returncode == 0, res.stderr[-2000:]
        return res.stdout + res.stderr

    assert "Nothing to be done" in dry()
    plan = dry("figure_formats=[png, svg]")
    import re

    assert re.search(r"^analyse\s+2$", plan, re.M), plan  # both datasets' analyses
    assert not list(small_run.glob("*/staircase/*.svg"))
    assert (small_run / "analytic" / "fig4.svg").is_file()
