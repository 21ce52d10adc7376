"""The report as a static site (spa.report.site) and the overview across datasets
(spa.report.overview, Fig. O1) on fabricated results and a simulated series of sessions."""

from __future__ import annotations

import re
import shutil
from datetime import date, timedelta

import numpy as np
import pytest
import yaml

import spa
from spa.report.overview import (
    UNDATED,
    interval_changes,
    overview_row,
    overview_table,
    read_rows,
    write_row,
)
from spa.report.site import build_analytic_page, build_dataset_page, build_index, page_name

META = {"seed": 20251128, "spa version": spa.__version__}


@pytest.fixture(scope="module")
def site(fake_results, tmp_path_factory):
    """The fabricated results with each dataset's overview row and the overview written."""
    from spa.io import write_csv
    from spa.plots.overview import plot_overview
    from spa.plots.save import save_figure

    root = tmp_path_factory.mktemp("site") / "results"
    shutil.copytree(fake_results.root, root)
    rows = []
    for i, name in enumerate(fake_results.datasets):
        rows.append(overview_row(root / name, name, f"2025-0{i + 1}-01", "bench"))
    table = overview_table(rows)
    write_csv(table, root / "overview.csv")
    save_figure(plot_overview(table), root / "overview.png")
    return root


def test_a_dataset_page_shows_its_own_figures_and_the_recommended_block(fake_results, site):
    page = build_dataset_page(site, "sim", META)
    own = [p for p in fake_results.pngs if p.relative_to(fake_results.root).parts[0] == "sim"]
    assert page.count("<img ") == len(own) > 5
    assert "a&lt;b&amp;c" not in page  # nothing of the other dataset
    assert '<a href="index.html">Index of the run</a>' in page
    # the recommended setting as the dataset.yaml block of a run (recommended.setting)
    block = re.search(r"<pre>(modulator:.*?)</pre>", page, flags=re.S)[1]
    assert yaml.safe_load(block) == {"modulator": {"type": "iipfm", "t_l": 0.0195, "gain": 1.154}}
    assert "<script" not in page.lower() and "http" not in page.replace("http-equiv", "")
    assert build_dataset_page(site, "sim", META) == page  # byte-stable
    bare = build_dataset_page(site, "sim", META, drawn=False)
    assert "<img " not in bare and "No figures for this dataset" in bare


def test_the_index_links_every_page_and_embeds_the_overview_alone(fake_results, site):
    index = build_index(site, fake_results.datasets, META)
    assert index.count("<img ") == 1  # Fig. O1 only, no dataset's figures
    assert "Fig. O1: the valve across sessions" in index
    for name in fake_results.datasets:
        href = re.escape(page_name(name).replace("&", "&amp;").replace("<", "&lt;"))
        assert len(re.findall(f'href="{href}"', index)) == 2  # summary row and list of pages
    assert 'href="analytic.html"' in index
    entry = build_index(site, fake_results.datasets, META, prefix="report/")
    assert 'href="report/sim.html"' in entry and 'href="report/analytic.html"' in entry
    assert "<script" not in index.lower()
    # the overview table: one row per dataset
    overview = index[index.index('<section id="overview">') :]
    assert overview.count("<td>bench</td>") == len(fake_results.datasets)


def test_failed_datasets_come_first_on_the_index(fake_results, site, tmp_path):
    from spa.pipeline.status import write_status

    root = tmp_path / "results"
    shutil.copytree(site, root)
    write_status(root / "sim" / "status" / "identify.json", "identify", "sim", ["no <charge>"])
    index = build_index(root, fake_results.datasets, META)
    assert index.index('<section id="failed">') < index.index('<section id="summary">')
    assert "Dataset sim (failed)" in index
    page = build_dataset_page(root, "sim", META)
    assert "<img " not in page and "no &lt;charge&gt;" in page


def test_analytic_page(fake_results, site):
    page = build_analytic_page(site, META)
    assert page.count("<img ") == 2 and "Table 1" in page and "Dataset" not in page


def test_reserved_dataset_names():
    with pytest.raises(ValueError, match="index"):
        page_name("index")


def test_interval_changes_compare_with_the_previous_session_of_the_rig():
    lo, hi = [1.0, 5.0, 1.1, 2.0, np.nan, 2.1], [1.2, 5.2, 1.3, 2.2, np.nan, 2.3]
    rigs = ["a", "b", "a", "a", "a", "a"]
    assert interval_changes(lo, hi, rigs).tolist() == [False, False, False, True, False, False]


def test_undated_sessions_follow_the_dated_ones_by_name(tmp_path):
    rows = [
        overview_row(tmp_path / n, n, d, "r", failed="identify")
        for n, d in (("b", None), ("z", "2024-01-02"), ("a", None), ("y", "2024-01-01"))
    ]
    table = overview_table(rows)
    assert table["dataset"].tolist() == ["y", "z", "a", "b"]
    assert table["recorded"].tolist()[2:] == [UNDATED, UNDATED]
    assert (table["status"] == "failed: identify").all() and table["k2"].isna().all()
    write_row(tmp_path / "r.json", rows[0])
    assert read_rows([tmp_path / "r.json"])[0]["dataset"] == "b"


def test_drift_figure_flags_the_valve_change_at_the_right_session(tmp_path):
    """Six simulated sessions, recorded a week apart, named so that name order is not date
    order; the valve's t_off steps from 9 to 13 ms at the fourth: only there is t_off flagged,
    and no other parameter anywhere."""
    from spa.identification import identify, simulate_identification
    from spa.model.params import ValveParams
    from spa.plots.overview import plot_overview

    names = ["f", "c", "e", "a", "d", "b"]  # in date order
    rows = []
    for i, name in enumerate(names):
        truth = ValveParams(c1=0.45, k2=1.05, tau2=0.7, t_on=0.004, t_off=0.009 if i < 3 else 0.013)
        runs = simulate_identification(truth)
        rng = np.random.default_rng(i)
        for table in runs.values():
            table["p"] = table["p"] + rng.normal(0.0, 0.002, len(table))
        result = identify(
            [runs["charge"]], [runs["discharge"]], [runs["pulse"]], seed=i, n_boot=100
        )
        folder = tmp_path / name / "identification"
        folder.mkdir(parents=True)
        (folder / "params.yaml").write_text(yaml.safe_dump(result.to_dict()))
        rows.append(
            overview_row(
                tmp_path / name, name, str(date(2025, 3, 1) + timedelta(days=7 * i)), "bench 1"
            )
        )
    table = overview_table(reversed(rows))
    assert table["dataset"].tolist() == names
    assert table["changed_t_off"].tolist() == [False, False, False, True, False, False]
    for p in ("t_on", "c1", "k2", "tau2"):
        assert not table[f"changed_{p}"].any(), p
    fig = plot_overview(table)
    ax = fig.axes[4]
    rings = [line for line in ax.get_lines() if line.get_label() == "changed"]
    assert len(rings) == 1 and rings[0].get_xdata().tolist() == [21.0]  # days since the first
    assert "days since the first session (2025-03-01)" in ax.get_xlabel()
