"""Figures for papers: palette and order (spa.plots.style), saving (spa.plots.save), the
layouts of Figs. 4, 7b, 8 and 9 (spa.plots)."""

from __future__ import annotations

import struct
import subprocess
import sys

import numpy as np
import pandas as pd
import pytest
from matplotlib.collections import QuadMesh
from matplotlib.colors import to_hex
from matplotlib.figure import Figure

import spa
from spa.model.params import ValveParams
from spa.plots.analytic import plot_cost_sweeps
from spa.plots.openloop import fig6, fig7b, fig8, fig9, fig9_data, tau_outliers
from spa.plots.save import MIN_WIDTH_PX, PNG_DPI, save_figure, vector_path
from spa.plots.style import (
    MODULATOR_COLOURS,
    MODULATOR_NAMES,
    OKABE_ITO,
    ordered_settings,
    setting_colours,
    setting_sort_key,
)
from spa.tuning.cost import linearity_cost


def _png_size(path) -> tuple[int, int]:
    return struct.unpack(">II", path.read_bytes()[16:24])


# --- palette and order ---------------------------------------------------------------------


def test_settings_sort_by_number_not_by_text():
    labels = ["ipfm-100ms", "dsm-5ms", "ipfm-10ms", "pwm-40Hz", "pwm-5Hz", "iipfm-20ms-G1.15"]
    labels += ["iipfm-20ms", "ipfm-20ms"]
    assert ordered_settings(labels) == [
        "pwm-5Hz",
        "pwm-40Hz",
        "ipfm-10ms",
        "ipfm-20ms",
        "ipfm-100ms",
        "iipfm-20ms",
        "iipfm-20ms-G1.15",
        "dsm-5ms",
    ]
    assert sorted(["ipfm-100ms", "ipfm-10ms"]) == ["ipfm-100ms", "ipfm-10ms"]  # text order
    # a run id standing for a setting sorts after its type's labels, a stranger last
    assert ordered_settings(["zz", "pwm_run_b", "pwm-20Hz", "ipfm-5ms"]) == [
        "pwm-20Hz",
        "pwm_run_b",
        "ipfm-5ms",
        "zz",
    ]
    assert setting_sort_key("ipfm-10ms") < setting_sort_key("ipfm-100ms")


def test_palette_is_okabe_ito_one_colour_per_modulator():
    assert set(MODULATOR_COLOURS.values()) <= set(OKABE_ITO)
    assert len(set(MODULATOR_COLOURS.values())) == len(MODULATOR_COLOURS)
    assert "#F0E442" not in MODULATOR_COLOURS.values()  # yellow: unreadable on white
    six = setting_colours(6)
    assert len(set(six)) == 6 and set(six) <= set(OKABE_ITO)
    many = setting_colours(9)
    assert len(set(many)) == 9
    with pytest.raises(ValueError, match="n must be"):
        setting_colours(-1)


def _aligned(settings: list[tuple[str, str]]) -> pd.DataFrame:
    xi = np.linspace(0.0, 1.0, 20)
    return pd.concat(
        pd.DataFrame({"modulator": kind, "setting": s, "xi": xi, "p_norm": xi**1.2, "rms": 0.1})
        for kind, s in settings
    )


def test_legends_and_colours_follow_the_numeric_order():
    # the data list 100 ms first; the legend and the colours put 10 ms first
    data = _aligned([("ipfm", "ipfm-100ms"), ("ipfm", "ipfm-10ms"), ("ipfm", "ipfm-20ms")])
    ax = fig8(data).axes[0]
    texts = [t.get_text() for t in ax.get_legend().get_texts()]
    assert [t.split()[0] for t in texts] == ["ipfm-10ms", "ipfm-20ms", "ipfm-100ms"]
    lines = [ln for ln in ax.get_lines() if ln.get_label().startswith("ipfm")]
    assert [to_hex(ln.get_color()).upper() for ln in lines] == [
        c.upper() for c in setting_colours(3)
    ]
    traces = data.rename(columns={"xi": "t", "p_norm": "p"})
    ax6 = fig6(traces).axes[0]
    assert [t.get_text() for t in ax6.get_legend().get_texts()] == [
        "ipfm-10ms",
        "ipfm-20ms",
        "ipfm-100ms",
    ]


# --- Fig. 8: small multiples -----------------------------------------------------------------


@pytest.mark.parametrize("n", [1, 2, 3, 4])
def test_fig8_has_one_panel_per_modulator(n):
    kinds = ["pwm", "ipfm", "iipfm", "dsm"][:n]
    settings = [(k, f"{k}-{v}ms") for k in kinds for v in (10, 20)]
    settings = [(k, "pwm-20Hz" if k == "pwm" else s) for k, s in settings]
    ref = pd.DataFrame({"xi": [0.0, 1.0], "p_norm": [0.0, 1.0], "rms": 0.01})
    fig = fig8(_aligned(settings), reference=ref, note="a title")
    axes = [ax for ax in fig.axes if ax.get_title()]
    assert len(fig.axes) == len(axes) == n
    assert [ax.get_title() for ax in axes] == [MODULATOR_NAMES[k] for k in kinds]
    assert len(fig.legends) == 1  # ideal line and linear reference once, for every panel


# --- Fig. 9: the colour scale ---------------------------------------------------------------


def _maps(scale: float) -> list:
    n = 32
    f = np.fft.fftshift(np.fft.fftfreq(n, d=1 / 64))
    rng = np.random.default_rng(1)
    bic = scale * rng.random((n, n))
    return [("pwm-20Hz", f, bic, 0.05, 2.0), ("linear", f, 0.2 * bic, 0.05, 2.0)]


@pytest.mark.parametrize("scale", [0.1, 1.0])
def test_fig9_maps_share_a_fixed_zero_to_one_scale(scale):
    fig = fig9(_maps(scale))
    meshes = [c for ax in fig.axes for c in ax.collections if isinstance(c, QuadMesh)]
    coloured = [m for m in meshes if m.get_cmap().name == "viridis"]
    assert len(coloured) == 3  # the two maps and the colour bar
    assert all(m.get_clim() == (0.0, 1.0) for m in coloured)
    colorbar = fig.axes[-1]
    assert colorbar.get_ylim() == (0.0, 1.0)


def test_fig9_data_holds_the_principal_domain_and_what_is_coloured():
    maps = _maps(1.0)
    data = fig9_data(maps)
    assert list(data.columns) == ["setting", "f1", "f2", "bicoherence", "significant"]
    assert set(data["setting"]) == {"pwm-20Hz", "linear"}
    assert (data["f2"] >= 0).all() and (data["f2"] <= data["f1"]).all()
    assert (data["f1"] + data["f2"] <= 32.0).all()  # fs/2
    sig = data[data["significant"]]
    assert (sig["bicoherence"] > 0.05).all() and (sig["f2"] >= 2.0).all()


# --- Fig. 4: PWM periods shorter than t_on + t_off -------------------------------------------


def test_pwm_cost_plateaus_where_its_linear_range_is_closed():
    """Above f_W = 1/(t_on + t_off) (76.9 Hz) P_eq is a 0 -> k2 step at xi = t_on*f_W: J is
    the closed form of that step on the xi grid, constant between grid points, jumping at
    them. This is Fig. 4's 'glitch' near 77-80 Hz (README)."""
    p = ValveParams()
    assert 1.0 / (p.t_on + p.t_off) == pytest.approx(76.923, abs=1e-3)
    xi = np.linspace(0.0, 1.0, 101)
    for f in (78.0, 80.0):
        eq = spa.equilibrium("pwm", xi, p, f_w=f)
        assert set(np.round(eq, 12)) == {0.0, round(p.k2, 12)}
    n = 100
    grid = np.linspace(0.0, 1.0, n)
    for f in (77.0, 77.3, 77.6, 79.0, 80.0):
        step = np.where(grid > p.t_on * f, p.k2, 0.0)
        assert linearity_cost("pwm", f, p, n) == pytest.approx(
            np.abs(step - p.k2 * grid).sum(), rel=1e-12
        )
    j = linearity_cost("pwm", np.array([77.0, 77.3, 77.6, 80.0]), p, n)
    assert j[0] == j[1] and j[2] == j[3] and j[2] < j[1]  # plateau, jump at 23/99 / t_on


def test_fig4_shades_the_closed_pwm_range_only_with_the_valve():
    sweeps = pd.DataFrame(
        {"modulator": "pwm", "x_ms": [12.5, 20.0, 50.0], "J": [13.0, 8.0, 5.0]},
    )
    labels = plot_cost_sweeps(sweeps, params=ValveParams()).axes[0].get_legend_handles_labels()
    assert any("t_on + t_off = 13 ms (76.9 Hz)" in lab for lab in labels[1])
    plain = plot_cost_sweeps(sweeps).axes[0].get_legend_handles_labels()[1]
    assert not any("t_on" in lab for lab in plain)


# --- Fig. 7b: outlying time constants --------------------------------------------------------


def test_tau_outliers_are_a_decade_off_the_median():
    tau = np.array([0.5, 0.6, 0.75, 0.8, 0.9, 0.013, 0.05, 0.076, 7.6, np.nan])
    # median of the finite ones 0.75: outside [0.075, 7.5]
    assert tau_outliers(tau).tolist() == [False] * 5 + [True, True, False, True, False]
    assert not tau_outliers(np.full(4, np.nan)).any()
    with pytest.raises(ValueError, match="factor"):
        tau_outliers(tau, factor=1.0)


def test_fig7b_marks_the_outliers():
    steps = pd.DataFrame(
        {
            "modulator": "pwm",
            "setting": "pwm-20Hz",
            "gain": 1.0,
            "xi_to": [0.2, 0.3, 0.4, 0.5],
            "tau": [0.013, 0.6, 0.7, 0.8],
        }
    )
    steps["outlier"] = tau_outliers(steps["tau"])
    ax = fig7b(steps).axes[0]
    marked = [ln for ln in ax.get_lines() if ln.get_label().startswith("outlier")]
    assert len(marked) == 1 and marked[0].get_xydata().tolist() == [[0.2, 0.013]]
    sweep = pd.DataFrame(
        {
            "modulator": ["pwm", "pwm"],
            "setting": ["pwm-5Hz", "pwm-20Hz"],
            "tau_mean": [0.5, 0.6],
            "tau_sd": [0.1, 0.2],
            "n_outliers": [2, 0],
        }
    )
    right = fig7b(steps, sweep=sweep).axes[1]
    notes = [(t.get_text(), t.xy) for t in right.texts]
    assert notes == [("×2", (0, pytest.approx(0.6)))]  # pwm-5Hz first, above mean + sd
    assert not any(
        ln.get_label().startswith("outlier")
        for ln in fig7b(steps.drop(columns="outlier")).axes[0].get_lines()
    )


# --- saving ----------------------------------------------------------------------------------


def _figure(width: float) -> Figure:
    fig = Figure(figsize=(width, 2.0))
    ax = fig.add_subplot()
    ax.plot([0, 1], [0, 1], label="ΔΣM ξ")
    ax.pcolormesh(np.arange(4), np.arange(4), np.eye(3), rasterized=True)
    ax.legend()
    return fig


@pytest.mark.parametrize(("width", "pixels"), [(2.0, MIN_WIDTH_PX), (8.0, 8 * PNG_DPI)])
def test_png_is_print_resolution_and_at_least_1000_px_wide(tmp_path, width, pixels):
    save_figure(_figure(width), tmp_path / "f.png")
    w, h = _png_size(tmp_path / "f.png")
    assert w == pixels and h == round(2.0 * pixels / width)
    assert vector_path(tmp_path / "f.png").read_text().startswith("<?xml")


def test_svg_and_png_bytes_are_the_same_every_time(tmp_path):
    for name in ("a", "b"):
        save_figure(_figure(5.0), tmp_path / name / "f.png")
    for suffix in (".png", ".svg"):
        a = (tmp_path / "a" / "f").with_suffix(suffix).read_bytes()
        assert a == (tmp_path / "b" / "f").with_suffix(suffix).read_bytes()
    svg = (tmp_path / "a" / "f.svg").read_text()
    assert "<dc:date>" not in svg and "Matplotlib v" not in svg
    # and in another process (the ids of an SVG are random unless salted)
    code = (
        "import sys; sys.path.insert(0, sys.argv[2]); from test_plots import _figure; "
        "from spa.plots.save import save_figure; save_figure(_figure(5.0), sys.argv[1])"
    )
    other = tmp_path / "c" / "f.png"
    subprocess.run([sys.executable, "-c", code, str(other), str(_here())], check=True)
    assert other.with_suffix(".svg").read_bytes() == (tmp_path / "a" / "f.svg").read_bytes()


def _here():
    from pathlib import Path

    return Path(__file__).parent


def test_save_figure_refuses_what_is_not_a_png(tmp_path):
    with pytest.raises(ValueError, match=r"f\.svg: a figure is saved as \.png"):
        save_figure(_figure(5.0), tmp_path / "f.svg")
    with pytest.raises(ValueError, match="dpi must be positive"):
        save_figure(_figure(5.0), tmp_path / "f.png", dpi=0)


def test_a_failed_stage_leaves_a_valid_svg_beside_its_png(tmp_path):
    from spa.pipeline.status import write_placeholder

    write_placeholder(tmp_path / "fig8.svg", "vector", "sine failed")
    assert (tmp_path / "fig8.svg").read_text().startswith("<svg xmlns=")


def _pixels(fig: Figure, path) -> np.ndarray:
    from PIL import Image

    save_figure(fig, path, vector=False)
    return np.asarray(Image.open(path).convert("L")).astype(int)


def test_thin_keeps_every_peak():
    """The sine stage's thinning (spa.plots.openloop.thin, min-max per column of t) keeps
    the largest sample; the drawing of long traces is spa.plots.reduce's
    (tests/test_plot_reduce.py)."""
    from spa.plots.openloop import thin

    t = np.arange(55_000) * 1e-3
    p = np.sin(t)
    p[31_337] = 5.0
    small = thin(pd.DataFrame({"t": t, "p": p}), 6000)
    assert len(small) <= 6000 and small["p"].max() == 5.0


# --- colours from each modulator's module, stable; Figs. 9, 10, 11 and O1 ---------------------


def test_setting_styles_take_each_kinds_colour_and_tell_its_settings_apart():
    from spa.model.modulators import MODULATOR_ORDER, get_kind
    from spa.plots.style import setting_styles

    labels = ["lpwm-49Hz", "iipfm-20ms-G1.15", "pwm-20Hz", "iipfm-20ms", "lpwm-20Hz", "dsm-20ms"]
    styles = setting_styles(labels)
    assert list(styles) == ordered_settings(labels)
    kinds = [k for k in MODULATOR_ORDER if any(lab.startswith(f"{k}-") for lab in labels)]
    assert kinds == ["pwm", "iipfm", "dsm", "lpwm"], "the labels take four kinds of the order"
    for kind in kinds:  # the first setting of a kind: the colour its module declares
        first = next(s for lab, s in styles.items() if lab.startswith(f"{kind}-"))
        assert first["color"] == get_kind(kind).colour.lower()
    pairs = [(s["color"], s["marker"]) for s in styles.values()]
    assert len(set(pairs)) == len(pairs)
    assert styles["iipfm-20ms"]["marker"] != styles["iipfm-20ms-G1.15"]["marker"]
    assert setting_styles(reversed(labels)) == styles  # whatever the order of the data


def _steps() -> pd.DataFrame:
    rows = []
    for label in ["pwm-20Hz", "iipfm-20ms", "iipfm-20ms-G1.15", "dsm-20ms"]:
        for controller in ("fixed", "scheduled"):
            for r0, r1 in ((0.1, 0.4), (0.4, 0.7), (0.7, 0.4)):
                rows.append(
                    {"experiment": "staircase", "modulator": label, "controller": controller,
                     "r0": r0, "r1": r1, "rise_time": 0.5 + r1, "overshoot": 10 * r1}
                )  # fmt: skip
    return pd.DataFrame(rows)


def test_fig11_draws_each_setting_in_its_modulators_colour():
    from spa.plots.check import figure_problems
    from spa.plots.closedloop import fig11

    fig = fig11(_steps())
    ax = fig.axes[0]
    colours = {ln.get_label(): to_hex(ln.get_color()) for ln in ax.get_lines()}
    assert colours["pwm-20Hz"] == MODULATOR_COLOURS["pwm"].lower()
    assert colours["iipfm-20ms"] == MODULATOR_COLOURS["iipfm"].lower()
    assert colours["iipfm-20ms-G1.15"] != colours["iipfm-20ms"]  # a shade of the same green
    assert len(fig.legends) == 1 and not any(a.get_legend() for a in fig.axes)
    assert figure_problems(fig) == []


def test_fig10_labels_the_time_axis_under_every_column():
    from spa.plots.check import missing_tick_labels
    from spa.plots.closedloop import fig10

    t = np.linspace(0.0, 4.0, 50)
    traces = pd.concat(
        pd.DataFrame({"modulator": label, "controller": c, "t": t, "r": 0.5, "p_mean": 0.4})
        for label in ("pwm-20Hz", "ipfm-20ms", "dsm-20ms")
        for c in ("fixed", "scheduled")
    )
    fig = fig10(traces)
    assert missing_tick_labels(fig) == []  # the upper right panel sits above an empty slot
    assert [ax.get_xlabel() for ax in fig.axes if ax.axison] == ["", "t (s)", "t (s)"]


def test_fig9_says_what_the_outlines_mean():
    sweep = pd.DataFrame(
        {
            "modulator": ["pwm", "ipfm", "linear"],
            "setting": ["pwm-20Hz", "ipfm-20ms", "linear"],
            "significant_fraction": [0.2, 0.1, 0.03],
        }
    )
    fig = fig9(_maps(1.0), sweep=sweep, shown=["pwm-20Hz"])
    texts = [t.get_text() for t in fig.axes[-1].get_legend().get_texts()]
    assert "outlined: its map is shown above" in texts


def _overview(order: list[int], empty_rig: bool = False) -> pd.DataFrame:
    from spa.report.overview import overview_table
    from spa.report.params import PARAM_NAMES

    rows = []
    for i, (name, rig, day) in enumerate(
        [("a", "rig B", "2025-01-01"), ("b", "rig A", "undated"), ("c", "rig B", "undated")]
    ):
        row = {"dataset": name, "recorded": day, "rig": rig, "status": "ok"}
        for p in PARAM_NAMES:
            row |= {p: 1.0 + i, f"{p}_lo": 0.9 + i, f"{p}_hi": 1.1 + i}
        rows.append(row)
    if empty_rig:  # a failed dataset: no numbers
        nan = float("nan")
        failed = {"dataset": "d", "recorded": "undated", "rig": "unnamed rig", "status": "failed"}
        rows.append(failed | {f"{p}{s}": nan for p in PARAM_NAMES for s in ("", "_lo", "_hi")})
    return overview_table([rows[i] for i in order] + rows[3:])


def test_overview_colours_rigs_in_sorted_order_and_names_only_rigs_with_points():
    from spa.report.overview_figure import plot_overview

    def colours(fig) -> dict[str, str]:
        legend = fig.legends[0]
        return {
            t.get_text(): to_hex(h.get_color())
            for t, h in zip(legend.get_texts(), legend.legend_handles, strict=True)
        }

    one = plot_overview(_overview([0, 1, 2], empty_rig=True))
    other = plot_overview(_overview([2, 1, 0], empty_rig=True))
    assert colours(one) == colours(other)
    # sorted; the failed dataset's rig, without a point, has no entry ("changed": the red ring)
    assert list(colours(one)) == ["rig A", "rig B", "changed"]
    assert colours(one)["rig A"] == setting_colours(2)[0].lower()
    assert "$^{-1/2}$" in one.axes[0].get_ylabel()
    assert one.axes[-1].get_xlabel() == (
        "session: the dated ones by date, then the undated ones by name"
    )
