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
    from spa.datasets import read_runs
    from spa.io import read_params
    from spa.model.params import ValveParams
    from spa.pipeline.outputs import stage_outputs, stage_settings
    from spa.plots.analytic import plot_cost_sweeps, plot_equilibrium
    from spa.plots.closedloop import fig10, fig11
    from spa.plots.identification import fig2a, fig2b, fig2c, validation_figure
    from spa.plots.tuning import plot_tuning_equilibrium, plot_tuning_sweeps
    from spa.report.overview_figure import plot_overview
    from spa.stages._common import OpenLoopInputs
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
            result = run(OpenLoopInputs(runs, metas, params, {**settings[stage]}))
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


def _caption(name: str) -> str | None:
    """The registry's caption of a figure of :func:`pipeline_figures` by its name."""
    from spa.pipeline.outputs import get_stage

    where = {
        "analytic/fig4": ("analytic_fig4", "figure"),
        "analytic/fig5": ("analytic_fig5", "figure"),
        "overview": ("overview", "figure"),
        "tuning/fig4": ("tune", "fig4"),
        "tuning/fig5": ("tune", "fig5"),
        "validation": ("validate_model", "figures"),
    }
    part = name.split("/", 1)[1] if name.split("/")[0] not in ("analytic", "overview") else name
    key = where.get(name) or where.get(part) or where.get(part.split("/")[0])
    stages = {"fig2": "identify", "fig6": "staircase", "fig7": "staircase", "fig8": "sine",
              "fig9": "chirp", "fig10": "closed_loop", "fig11": "closed_loop"}  # fmt: skip
    if key is None:
        stage = next((v for k, v in stages.items() if part.rstrip("abc") == k), None)
        key = (stage, part) if stage else None
    if key is None:
        return None
    return next((o.caption for o in get_stage(key[0]).outputs if o.key == key[1]), None)


def test_every_figure_of_the_small_run_draws_what_its_caption_says(small_figures):
    from spa.plots.check import caption_problems
    from spa.plots.words import O1_CONDITIONAL

    captions = {name: _caption(name) for name in small_figures}
    assert None not in captions.values(), [n for n, c in captions.items() if c is None]
    problems = {
        n: caption_problems(f, captions[n], O1_CONDITIONAL if n == "overview" else ())
        for n, f in small_figures.items()
    }
    assert {k: v for k, v in problems.items() if v} == {}


# --- what the captions and legends say, against what is drawn ----------------------------------


def _fig10_traces() -> pd.DataFrame:
    t = np.linspace(0.0, 4.0, 50)
    return pd.concat(
        pd.DataFrame({"modulator": label, "controller": c, "t": t, "r": 0.5, "p_mean": 0.4 + k})
        for label in ("pwm-20Hz", "dsm-20ms")
        for k, c in enumerate(("fixed", "scheduled", "scheduled_ff"))
    )


def _fig11_steps() -> pd.DataFrame:
    rows = []
    for label in ("pwm-20Hz", "iipfm-20ms", "iipfm-20ms-G1.15"):
        for c in ("fixed", "scheduled"):
            for r0, r1 in ((0.1, 0.3), (0.3, 0.5), (0.5, 0.3), (0.3, 0.1)):
                rows.append(
                    {"experiment": "staircase", "modulator": label, "controller": c,
                     "r0": r0, "r1": r1, "rise_time": 0.2 + r1, "overshoot": 3.0 * r1}
                )  # fmt: skip
    return pd.DataFrame(rows)


OLD_FIG10 = (
    "Cycle-mean pressure over the set-point staircase up and down, one panel per setting: "
    "fixed PI (black), gain-scheduled PI (blue) and gain-scheduled PI with the averaged "
    "model's feed-forward (orange, dashed); dotted: the set-point."
)
OLD_FIG11 = (
    "Rise time (10-90 %) and overshoot of each staircase step against the set-point after it, "
    "one column per controller, one colour per setting (triangles up, solid: rising steps; "
    "down, dotted: falling steps, which the exhaust limits)."
)


def test_fig10_and_fig11_captions_come_from_their_style_tables_and_match_the_artists():
    from spa.pipeline.outputs import get_stage
    from spa.plots.check import caption_problems
    from spa.plots.closedloop import fig10, fig11
    from spa.plots.words import FIG10_CAPTION, FIG11_CAPTION

    captions = {o.key: o.caption for o in get_stage("closed_loop").outputs}
    assert captions["fig10"] == FIG10_CAPTION and captions["fig11"] == FIG11_CAPTION
    ten, eleven = fig10(_fig10_traces()), fig11(_fig11_steps())
    assert caption_problems(ten, FIG10_CAPTION) == []
    assert caption_problems(eleven, FIG11_CAPTION) == []
    # the captions of before: words the figures do not draw
    assert "the caption says 'black' but nothing is drawn black" in caption_problems(ten, OLD_FIG10)
    assert caption_problems(eleven, OLD_FIG11) == [
        "the caption says 'triangle' but no marker is a triangle"
    ]
    # and the style words of FIG10_CAPTION are those of the table the figure is drawn with
    assert {"solid", "dashed", "dash-dot", "dotted", "darker", "lighter"} <= set(
        FIG10_CAPTION.replace(",", " ").replace(")", " ").replace("(", " ").split()
    )


def test_a_caption_naming_a_colour_marker_or_line_style_must_match_an_artist():
    from spa.plots.check import caption_problems

    fig = Figure(figsize=(4.0, 3.0))
    ax = fig.add_subplot()
    ax.plot([0, 1], [0, 1], "s:", color="#D55E00", mfc="none")
    assert caption_problems(fig, "vermillion, dotted, hollow squares") == []
    assert caption_problems(fig, "sky blue circles, filled") == [
        "the caption says 'sky blue' but nothing is drawn sky blue",
        "the caption says 'circle' but no marker is a circle",
        "the caption says 'filled' but no marker is filled",
    ]
    assert caption_problems(fig, "bluish markers") == []  # whole words only


def test_fig4_legend_names_the_optimum_of_table_2():
    """LPWM's J is 0 to round-off at every f_W: the legend named the smallest round-off
    (1.1 Hz) while Table 2, breaking ties within COST_TIE by J_exact, named 22.3 Hz."""
    from spa.plots.tuning import plot_tuning_sweeps
    from spa.tuning.exact import best_first

    f_w = np.array([1.1, 5.0, 22.3, 40.0])
    sweeps = pd.DataFrame(
        {
            "modulator": "lpwm", "parameter": "f_w", "value": f_w, "unit": "Hz",
            "x_ms": 1e3 / f_w, "J": [1e-15, 3e-15, 2e-15, 4e-15],
            "J_exact": [0.9, 0.5, 0.05, 0.2],
        }
    )  # fmt: skip
    table2 = best_first(sweeps, "J").iloc[0]  # Table 2's rule (spa.tuning.tables)
    assert table2["value"] == 22.3
    fig = plot_tuning_sweeps(sweeps, title="lab")
    labels = [t.get_text() for t in fig.legends[0].get_texts()]
    lpwm = next(label for label in labels if label.startswith("LPWM"))
    assert "(22.3 Hz)" in lpwm, lpwm


def test_fig5_tau_m_of_every_modulator_is_readable_when_one_is_orders_of_magnitude_apart():
    from spa.plots.analytic import plot_equilibrium

    xi = np.linspace(0.05, 0.95, 50)
    rows = []
    for kind, top in (("pwm", 1.0), ("ipfm", 2.0), ("lpwm", 600.0)):
        rows.append(
            pd.DataFrame(
                {"modulator": kind, "parameter": "f_w" if kind != "ipfm" else "t_h",
                 "value": 20.0 if kind != "ipfm" else 0.02, "gain": np.nan, "xi": xi,
                 "p_eq": xi, "p_target": xi, "tau_m": top * (0.2 + xi)}
            )
        )  # fmt: skip
    fig = plot_equilibrium(pd.concat(rows, ignore_index=True))
    from spa.plots.check import _draw

    _draw(fig)
    bottoms = fig.axes[len(fig.axes) // 2 :]
    for ax in bottoms:
        (line,) = ax.get_lines()
        y = ax.transData.transform(line.get_xydata())[:, 1]
        box = ax.get_window_extent()
        assert (y.max() - y.min()) / box.height > 0.15, ax.get_title()


def test_fig2c_legend_does_not_cover_its_title():
    from spa.plots.check import legend_over_titles
    from spa.plots.identification import fig2c

    t = np.arange(0.0, 2.0, 1e-3)
    valve = ((t % 0.5) < 0.1).astype(float)
    data = pd.DataFrame({"t": t, "valve": valve, "p": 0.3 * valve, "p_model": 0.3 * valve})
    fig = fig2c(data)
    assert legend_over_titles(fig) == []
    ax = fig.axes[0]  # the layout of before: legend left above the axes, title centred
    ax.legend(frameon=False, loc="lower left", bbox_to_anchor=(0.0, 1.0), ncols=2,
              borderaxespad=0)  # fmt: skip
    ax.set_title("", loc="left")
    ax.set_title("(c) pulse response")
    assert legend_over_titles(fig) != []


def test_overview_groups_by_valve_never_by_the_word_simulated():
    from spa.report.overview import overview_table, valve_identity
    from spa.report.overview_figure import plot_overview
    from spa.report.params import PARAM_NAMES

    rows = []
    for i, name in enumerate(("large-slow", "small-fast", "sim")):
        row = {"dataset": name, "recorded": "undated", "rig": "simulated", "status": "ok",
               "valve": valve_identity(None, name, simulated=True)}  # fmt: skip
        for p in PARAM_NAMES:  # three valves far apart: their intervals never overlap
            row |= {p: 1.0 + 5 * i, f"{p}_lo": 0.9 + 5 * i, f"{p}_hi": 1.1 + 5 * i}
        rows.append(row)
    table = overview_table(rows)
    assert not table[[f"changed_{p}" for p in PARAM_NAMES]].to_numpy().any()
    fig = plot_overview(table)
    for ax in fig.axes:
        assert not [ln for ln in ax.get_lines() if ln.get_linestyle() == "--"]  # no trend
    # two sessions of one bench valve still share a trend and are compared
    bench = [dict(r, rig="bench", valve="bench / V1") for r in rows[:2]]
    table = overview_table(bench)
    assert table["changed_k2"].tolist() == [False, True]
    from spa.plots.check import caption_problems
    from spa.plots.words import O1_CAPTION

    assert caption_problems(plot_overview(table), O1_CAPTION) == []  # trend and ring drawn


def test_table3_leaves_the_papers_case_of_a_bench_row_empty():
    from spa.report.table3 import table3_html

    df = pd.DataFrame(
        {"setting": ["pwm-20Hz", "bench_run"], "paper_case": ["PWM", np.nan],
         "mse": [0.0079, 0.01], "paper_mse": [0.0073, np.nan]}
    )  # fmt: skip
    html = table3_html(df)
    assert "nan" not in html.lower()
    assert '<td class="paper"></td>' in html
