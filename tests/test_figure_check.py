"""The figure check (spa.plots.check): each check fails on a deliberately bad figure and passes
on its mended twin; then every figure of the pipeline, drawn from the small config's run,
passes them all."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml
from matplotlib.figure import Figure

import spa.plots.save
from spa.plots.check import (
    cut_off,
    figure_problems,
    legend_overlaps,
    missing_tick_labels,
    shared_styles,
    small_axis_labels,
)

ROOT = Path(__file__).resolve().parents[1]


# --- each check on a bad figure and a good one -----------------------------------------------


def _legend_over_a_line(loc: str) -> Figure:
    fig = Figure(figsize=(4.0, 3.0))
    ax = fig.add_subplot()
    x = np.linspace(0.0, 1.0, 50)
    ax.plot(x, 1.0 - x, label="falling")  # crosses the upper left corner, not the lower left
    ax.legend(loc=loc)
    return fig


def test_a_legend_over_a_line_fails_and_one_beside_it_passes():
    bad = legend_overlaps(_legend_over_a_line("upper left"))
    assert bad == ["the legend of axes 0 covers its lines"]
    assert legend_overlaps(_legend_over_a_line("lower left")) == []


def test_a_line_crossing_the_legend_without_a_vertex_inside_it_counts():
    fig = Figure(figsize=(4.0, 3.0))
    ax = fig.add_subplot()
    ax.plot([0.0, 1.0], [0.9, 0.9], label="two points, far apart")
    ax.set_ylim(0.0, 1.0)
    ax.legend(loc="upper center")
    assert legend_overlaps(fig) == ["the legend of axes 0 covers its lines"]
    ax.set_ylim(0.0, 3.0)  # the line now runs below the legend
    assert legend_overlaps(fig) == []


@pytest.mark.parametrize("what", ["markers", "bars", "image"])
def test_a_legend_over_markers_bars_or_an_image_fails(what):
    def make(top: float) -> Figure:
        fig = Figure(figsize=(4.0, 3.0))
        ax = fig.add_subplot()
        if what == "markers":
            ax.plot([0.05, 0.5, 0.95], [top, 0.1, 0.1], "o", label="points")
        elif what == "bars":
            ax.bar([0, 1, 2], [top, 0.1, 0.1], label="bars")
        else:
            ax.imshow(np.eye(3), extent=(0, 1, 0, top), label="image")
            ax.plot([], [], label="an entry")
        ax.set_xlim(-0.5 if what == "bars" else 0.0, 2.5 if what == "bars" else 1.0)
        ax.set_ylim(0.0, 1.0)
        ax.set_aspect("auto")
        ax.legend(loc="upper left")
        return fig

    assert legend_overlaps(make(0.95)), what
    assert legend_overlaps(make(0.3)) == [], what


def test_a_figure_legend_is_checked_against_every_axes():
    fig = Figure(figsize=(4.0, 3.0))
    ax = fig.add_subplot()
    ax.plot([0.0, 1.0], [0.5, 0.5], label="flat")
    fig.legend(loc="center")
    assert legend_overlaps(fig) == ["the figure's legend covers those of axes 0: lines"]
    fig.legends.clear()
    fig.legend(loc="outside upper center")
    fig.set_layout_engine("constrained")
    assert legend_overlaps(fig) == []


def _panels(label_last: bool) -> Figure:
    fig = Figure(figsize=(6.0, 4.0), layout="constrained")
    axes = fig.subplots(2, 2, sharex=True).ravel()
    for ax in axes[:3]:
        ax.plot([0, 1], [0, 1])
    axes[3].axis("off")  # three panels: the upper right one sits above an empty slot
    if label_last:
        axes[1].xaxis.set_tick_params(labelbottom=True)
    return fig


def test_a_panel_without_x_tick_labels_above_an_empty_slot_fails():
    assert missing_tick_labels(_panels(False)) == ["axes 1: the x-axis has no tick labels"]
    assert missing_tick_labels(_panels(True)) == []


def test_ticks_turned_off_fail_and_a_twin_or_a_colour_bar_passes():
    fig = Figure(figsize=(4.0, 3.0))
    ax = fig.add_subplot()
    mesh = ax.pcolormesh(np.eye(3))
    fig.colorbar(mesh, ax=ax)  # a colour bar labels one axis only: left out
    twin = ax.twinx()
    twin.plot([0, 3], [0, 1])  # the twin's x-axis is labelled by its host
    assert missing_tick_labels(fig) == []
    ax.set_yticks([])
    assert missing_tick_labels(fig) == ["axes 0: the y-axis has no tick labels"]


def test_an_axis_label_smaller_than_its_tick_labels_fails():
    fig = Figure(figsize=(4.0, 3.0))
    ax = fig.add_subplot()
    ax.plot([0, 1], [0, 1])
    ax.set_ylabel("small", fontsize=7)
    ax.tick_params(labelsize=9)
    ax.set_xlabel("as large", fontsize=9)
    assert small_axis_labels(fig) == [
        "axes 0 ('small'): y-label 'small' is 7 pt, its tick labels 9 pt"
    ]
    ax.set_ylabel("small", fontsize=9)
    assert small_axis_labels(fig) == []


def test_two_series_of_one_colour_and_style_fail_and_a_marker_tells_them_apart():
    fig = Figure(figsize=(4.0, 3.0))
    ax = fig.add_subplot()
    ax.plot([0, 1], [0, 1], "-", color="#0072B2", label="a")
    second = ax.plot([0, 1], [1, 2], "-", color="#0072B2", label="b")[0]
    ax.plot([0, 1], [2, 3], "--", color="#0072B2", label="c")  # dashed: apart
    ax.plot([2, 3], [0, 1], "-", color="#0072B2", label="a")  # a's second piece
    ax.errorbar([0, 1], [1, 1], yerr=0.1, fmt="o", color="k", label="d")  # caps belong to d
    assert shared_styles(fig) == [
        "axes 0: series 'a' and 'b' share colour #0072b2, line style '-' and no marker"
    ]
    second.set_marker("s")
    assert shared_styles(fig) == []
    assert figure_problems(fig) == []


def test_a_title_or_a_legend_past_the_figures_edge_fails():
    fig = Figure(figsize=(3.0, 2.0), layout="constrained")
    ax = fig.add_subplot()
    ax.plot([0, 1], [0, 1], label="a line")
    ax.set_title("a title far too long for a figure three inches wide, cut at both ends")
    assert cut_off(fig) == [
        "the text 'a title far too long for a figure three inches wide, cut at both ends' "
        "reaches past the figure's edge"
    ]
    ax.set_title("a short title")
    fig.legend(["a line with a label wider than the whole figure, cut"], loc="outside lower center")
    assert cut_off(fig) == [
        "the legend with 'a line with a label wider than the whole figure, cut' reaches past "
        "the figure's edge"
    ]
    fig.legends.clear()
    assert cut_off(fig) == []


# --- every figure of the pipeline -------------------------------------------------------------


def _config() -> dict:
    def merged(base: dict, over: dict) -> dict:
        out = dict(base)
        for key, value in over.items():
            both = isinstance(value, dict) and isinstance(base.get(key), dict)
            out[key] = merged(base[key], value) if both else value
        return out

    full = yaml.safe_load((ROOT / "config" / "config.yaml").read_text(encoding="utf-8"))
    small = yaml.safe_load((ROOT / "config" / "small.yaml").read_text(encoding="utf-8"))
    return merged(full, small)  # as --configfile merges them


def pipeline_figures(results: Path, config: dict, out: Path) -> dict[str, Figure]:
    """Every figure of a finished run, drawn again by the functions the pipeline draws it with.

    The open-loop stages run again on the run tables (their figures' inputs are more than
    the CSV beside them); every other figure is drawn from the CSV written beside it, which
    is the table it plots.
    """
    figures: dict[str, Figure] = {}
    drawn: dict[str, str] = {}  # a stage's figure path -> its name

    def collect(fig: Figure, path, **_) -> None:
        figures[drawn[str(path)]] = fig

    keep = spa.plots.save.save_figure
    spa.plots.save.save_figure = collect  # spa.plots.save.draw saves through it
    try:
        _draw_all(results, config, out, figures, drawn)
    finally:
        spa.plots.save.save_figure = keep
    return figures


def _draw_all(
    results: Path, config: dict, out: Path, figures: dict[str, Figure], drawn: dict[str, str]
) -> None:
    from spa.io import read_params, read_runs
    from spa.model.params import ValveParams
    from spa.pipeline.outputs import stage_outputs, stage_settings
    from spa.plots.analytic import plot_cost_sweeps, plot_equilibrium
    from spa.plots.closedloop import fig10, fig11
    from spa.plots.identification import fig2a, fig2b, fig2c, validation_figure
    from spa.plots.overview import plot_overview
    from spa.plots.tuning import plot_tuning_equilibrium, plot_tuning_sweeps
    from spa.stages.chirp import run_chirp, write_chirp
    from spa.stages.sine import run_sine, write_sine
    from spa.stages.staircase import run_staircase, write_staircase

    def csv(path: Path) -> pd.DataFrame | None:
        return pd.read_csv(path) if path.is_file() and path.stat().st_size > 1 else None

    def add(name: str, make, path: Path, *args, **kwargs) -> None:
        data = csv(path)
        if data is not None and len(data):
            figures[name] = make(data, *args, **kwargs)

    nominal = ValveParams(**config["nominal"])
    add("analytic/fig4", plot_cost_sweeps, results / "analytic" / "fig4.csv", params=nominal)
    add("analytic/fig5", plot_equilibrium, results / "analytic" / "fig5.csv")
    add("overview", plot_overview, results / "overview.csv")
    datasets = sorted(p.parent.name for p in results.glob("*/runs"))
    for ds in datasets:
        d = results / ds
        for name, make in (("fig2a", fig2a), ("fig2b", fig2b), ("fig2c", fig2c)):
            add(f"{ds}/{name}", make, d / "identification" / f"{name}.csv")
        params = read_params(d / "identification" / "params.yaml")
        tune = d / "tuning"
        add(f"{ds}/tuning/fig4", plot_tuning_sweeps, tune / "fig4.csv", title=ds, params=params)
        add(f"{ds}/tuning/fig5", plot_tuning_equilibrium, tune / "fig5.csv")
        fit = csv(d / "validation" / "fit.csv")
        for row in fit.loc[fit.groupby("kind")["fit_percent"].idxmin()].itertuples():
            title = f"{row.kind}: run {row.run} (lowest FIT of its kind, {row.fit_percent:.1f} %)"
            add(
                f"{ds}/validation/{row.kind}",
                validation_figure,
                d / "validation" / "figures" / f"{row.kind}.csv",
                title=title,
            )
        add(f"{ds}/fig10", fig10, d / "closed_loop" / "fig10.csv")
        add(f"{ds}/fig11", fig11, d / "closed_loop" / "fig11.csv")
        runs, metas = read_runs(d / "runs")
        settings = stage_settings(config, ["staircase", "sine", "chirp"])
        for stage, run, write in (
            ("staircase", run_staircase, write_staircase),
            ("sine", run_sine, write_sine),
            ("chirp", run_chirp, write_chirp),
        ):
            result = run(runs, metas, params, {**settings[stage]})
            paths = {
                key: str(p)
                for key, p in stage_outputs(stage, str(out), ds).items()
                if key != "status"
            }
            for key, path in paths.items():
                drawn[path] = f"{ds}/{key}"
            write(result, paths, ds)


@pytest.fixture(scope="module")
def small_figures(small_run, tmp_path_factory) -> dict[str, Figure]:
    return pipeline_figures(small_run, _config(), tmp_path_factory.mktemp("figure_check"))


def test_every_figure_of_the_small_run_passes_the_check(small_figures):
    names = set(small_figures)
    for ds in ("sim", "example"):  # each kind of figure is there
        for fig in ("fig2a", "fig2c", "tuning/fig4", "fig6", "fig7a", "fig8", "fig9", "fig10"):
            assert f"{ds}/{fig}" in names, (ds, fig, sorted(names))
    assert {"analytic/fig4", "analytic/fig5", "overview", "sim/fig11"} <= names
    problems = {name: figure_problems(fig) for name, fig in small_figures.items()}
    assert {k: v for k, v in problems.items() if v} == {}
