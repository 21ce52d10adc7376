"""The HTML report (spa.report) on a fabricated results folder (``fake_results`` in conftest)."""

from __future__ import annotations

import base64
import re
import shutil

import pandas as pd
import pytest
import yaml

import spa
from spa.report import (
    PARAM_NAMES,
    build_report,
    embed_png,
    format_value,
    html_table,
    pair_paper_columns,
    params_table,
    png_size,
)

META = {"seed": 20251128, "spa version": spa.__version__}


@pytest.fixture(scope="module")
def report(fake_results):
    return build_report(fake_results.root, fake_results.datasets, META)


def sections(text: str) -> dict[str, str]:
    """Section id -> its HTML."""
    return dict(re.findall(r'<section id="([^"]+)">(.*?)</section>', text, flags=re.S))


def test_every_figure_is_embedded_once(fake_results, report):
    for png in fake_results.pngs:
        uri = "data:image/png;base64," + base64.b64encode(png.read_bytes()).decode()
        assert report.count(f'src="{uri}"') == 1, png
    assert report.count("<img ") == len(fake_results.pngs)


def test_every_table_is_shown_and_nothing_else(fake_results, report):
    # every table once, and the summary table (one row per dataset)
    assert report.count("<table") == len(fake_results.tables) + 1
    # numbers to about 4 significant digits, missing values empty, paper's values beside
    assert '<td class="num">97.45</td>' in report
    assert '<td class="num">5.405</td><td class="num paper">10.5</td>' in report
    # Table 3 grouped, in short units (10⁻³ bar²), the paper's beside ours
    assert '<td class="num">7.95</td><td class="paper">7.3</td>' in report
    assert '<th colspan="2">MSE (10⁻³ bar²)</th>' in report
    assert '<td class="num"></td><td>ms</td>' not in report  # column order: J_min, paper_J_min
    # the long staircase tables are mentioned, the CSVs beside the figures are not shown
    assert "sim/staircase/levels.csv and sim/staircase/time_constants.csv" in report
    assert "<th>x</th>" not in report


def test_params_yaml_is_a_table_of_the_five_parameters(report):
    sim = sections(report)["dataset-sim"]
    params = re.search(r'<figure id="dataset-sim-params">.*?</figure>', sim, flags=re.S)[0]
    for name in PARAM_NAMES:
        assert f"<td>{name}</td>" in params
    assert "<th>95 % lo</th><th>95 % hi</th><th>unit</th><th>method</th><th>fallback</th>" in params
    assert '<td class="num">0.5337</td><td class="num">0.5223</td><td class="num">0.5437</td>' in (
        params
    )
    assert "R² of the fits: charge 0.9625, discharge 0.9853." in params
    other = sections(report)["dataset-a-b-c"]
    assert "<td>no pulse run &lt;none&gt;</td>" in other  # the fallback's reason


def test_html_special_characters_are_escaped(fake_results, report):
    assert "<script" not in report.lower()
    assert "&lt;script&gt;alert(&quot;x&quot;)&lt;/script&gt; &amp; &#x27;y&#x27;" in report
    assert "Dataset a&lt;b&amp;c" in report
    assert "Validation: odd&lt;kind&gt;" in report
    assert 'alt="Validation: odd&lt;kind&gt;"' in report
    assert "fit of c1 &amp; friends" in report
    assert "a<b" not in report


def test_optional_outputs_are_skipped_when_missing(report):
    secs = sections(report)
    assert list(secs) == ["summary", "analytic", "dataset-sim", "dataset-a-b-c"]
    full, bare = secs["dataset-sim"], secs["dataset-a-b-c"]
    for title in (
        "Table 3",
        "Fig. 6",
        "Fig. 7a",
        "Fig. 7b",
        "Sine linearity",
        "Fig. 8",
        "Chirp bicoherence",
        "Fig. 9",
    ):
        assert title in full
        assert title not in bare
    assert "levels.csv" not in bare
    # Table 3 comes first in its dataset's section, highlighted
    assert full.index("Table 3") < full.index("Identified valve parameters")
    assert full.lstrip().startswith('<h2>Dataset sim</h2>\n<div class="key">')


def test_sections_show_what_the_registry_of_outputs_lists(fake_results, report):
    from spa.pipeline.outputs import section_outputs
    from spa.pipeline.stage_types import FIGURES

    secs = sections(report)
    for section, html in (("analytic", secs["analytic"]), ("dataset", secs["dataset-sim"])):
        shown = [o for o in section_outputs(section) if o.shown and o.kind != FIGURES]
        titles = re.findall(r"<h3>(.*?)</h3>", html)
        assert [t for t in titles if not t.startswith("Validation: ")] == [o.title for o in shown]
        for out in shown:
            assert f"<figcaption>{out.caption}" in html.replace("&#x27;", "'")


def test_a_dataset_without_figures_shows_its_tables_alone(fake_results, report):
    """config figures: the other datasets' figures are left out even when files are there
    (an earlier run's), and the section says where the figures' data are."""
    first, *others = fake_results.datasets
    text = build_report(fake_results.root, fake_results.datasets, META, figures=others)
    theirs = [p for p in fake_results.pngs if p.is_relative_to(fake_results.root / first)]
    assert theirs
    assert text.count("<img ") == len(fake_results.pngs) - len(theirs)
    assert text.count("No figures for this dataset") == 1
    assert text.count("<table>") == report.count("<table>")  # every table still shown


def test_missing_required_output_is_an_error(fake_results, tmp_path):
    root = tmp_path / "results"
    shutil.copytree(fake_results.root, root)
    (root / "sim" / "validation" / "fit.csv").unlink()
    with pytest.raises(FileNotFoundError, match=re.escape("sim/validation/fit.csv")):
        build_report(root, fake_results.datasets, META)


def test_same_inputs_same_bytes_wherever_the_folder_is(fake_results, report, tmp_path):
    copy = tmp_path / "elsewhere"
    shutil.copytree(fake_results.root, copy)
    assert build_report(fake_results.root, fake_results.datasets, META) == report
    assert build_report(copy, fake_results.datasets, META) == report
    assert str(fake_results.root) not in report
    assert str(tmp_path) not in report


def test_self_contained_no_script_no_external_resource(report):
    assert "<script" not in report.lower()
    assert re.search(r"https?:", report, flags=re.I) is None
    assert "url(" not in report and "@import" not in report
    assert re.search(r"\son\w+=", report) is None  # no event handlers
    for attr, value in re.findall(r'\s(src|href)="([^"]*)"', report):
        assert value.startswith(("data:", "#")), (attr, value[:40])


def test_contents_anchors_resolve_to_unique_ids(report):
    ids = re.findall(r'\sid="([^"]+)"', report)
    assert len(ids) == len(set(ids))
    links = re.findall(r'href="#([^"]+)"', report)
    assert set(links) <= set(ids)
    # every section and every table/figure is in the contents
    figures = re.findall(r'<figure id="([^"]+)"', report)
    assert set(figures) | set(sections(report)) == set(links)


def test_every_figure_and_table_has_a_caption(report):
    blocks = re.findall(r"<figure .*?</figure>", report, flags=re.S)
    recommendations = report.count('<p class="lead">')  # tuning's and closed_loop's sentences
    assert recommendations == 2
    assert len(blocks) == report.count("<img ") + report.count("<table") + recommendations
    for block in blocks:
        caption = re.search(r"<figcaption>(.+?)</figcaption>", block, flags=re.S)
        assert caption and len(caption[1]) > 20, block[:200]


def test_header_has_seed_version_and_datasets(report):
    assert "<dt>seed</dt><dd>20251128</dd>" in report
    assert f"<dt>spa version</dt><dd>{spa.__version__}</dd>" in report
    assert "<dt>datasets</dt><dd>sim, a&lt;b&amp;c</dd>" in report


@pytest.mark.parametrize(
    ("value", "text"),
    [
        (20000, "20000"),
        (18.0, "18"),
        (97.45077085, "97.45"),
        (0.0050258454, "0.005026"),
        (-0.1486589695, "-0.1487"),
        (123456.7, "123500"),
        (1.2344e-7, "1.234e-07"),
        (2.5e7, "2.5e+07"),
        (0.0, "0"),
        (float("nan"), ""),
        (None, ""),
        (True, "yes"),
        ("a < b", "a < b"),
    ],
)
def test_format_value(value, text):
    assert format_value(value) == text


def test_html_table_escapes_headers_and_cells():
    df = pd.DataFrame({"<b>": ["x & y"], "paper_<b>": [1.0]})
    out = html_table(df)
    assert '<th>&lt;b&gt;</th><th class="paper">paper_&lt;b&gt;</th>' in out
    assert '<td>x &amp; y</td><td class="num paper">1</td>' in out
    with pytest.raises(ValueError, match="DataFrame"):
        html_table([1, 2])


def test_pair_paper_columns_puts_each_printed_value_beside_its_own():
    df = pd.DataFrame(
        columns=["modulator", "J_min", "optimum", "paper_J_min", "paper_optimum", "paper_case"]
    )
    assert list(pair_paper_columns(df).columns) == [
        "modulator",
        "J_min",
        "paper_J_min",
        "optimum",
        "paper_optimum",
        "paper_case",
    ]


def test_params_table_names_what_is_missing(fake_results):
    params = yaml.safe_load((fake_results.root / "sim/identification/params.yaml").read_text())
    table = params_table(params)
    assert table["parameter"].tolist() == list(PARAM_NAMES)
    assert table["fallback"].tolist() == ["no"] * 5
    del params["tau2"]
    with pytest.raises(ValueError, match="'tau2'"):
        params_table(params)
    params["tau2"] = {"value": 1.0}
    with pytest.raises(
        ValueError, match=r"params\['tau2'\] lacks \['lo', 'hi', 'unit', 'method'\]"
    ):
        params_table(params)


def test_embed_png_is_a_data_uri_of_the_file(fake_results, tmp_path):
    png = fake_results.pngs[0]
    uri = embed_png(png)
    assert base64.b64decode(uri.removeprefix("data:image/png;base64,")) == png.read_bytes()
    assert png_size(png.read_bytes()) == (48, 24)  # 1.2 x 0.6 in at 40 dpi
    fake = tmp_path / "fake.png"
    fake.write_text("not a png")
    with pytest.raises(ValueError, match="not a PNG"):
        embed_png(fake)


def test_datasets_must_be_a_list_of_distinct_names(fake_results):
    with pytest.raises(ValueError, match="not one string"):
        build_report(fake_results.root, "sim", META)
    with pytest.raises(ValueError, match="twice"):
        build_report(fake_results.root, ["sim", "sim"], META)


def test_table_without_rows_says_so():
    out = html_table(pd.DataFrame(columns=["run", "modulator", "setting"]))
    assert '<tbody>\n<tr><td class="empty" colspan="3">no rows</td></tr>\n</tbody>' in out


def test_report_opens_with_a_summary_per_dataset(fake_results, report):
    summary = sections(report)["summary"]
    assert report.index('<section id="summary">') < report.index('<section id="analytic">')
    rows = re.findall(r"<tr>(.*?)</tr>", summary, flags=re.S)
    assert len(rows) == 1 + len(fake_results.datasets)  # header, one row per dataset
    sim = rows[1]
    assert '<a href="#dataset-sim">sim</a>' in sim
    # c1 = 0.533 * 1.0012345 with its interval [0.98, 1.02] * 0.533; t_on in ms
    assert "0.5337<br><small>[0.5223, 0.5437]</small>" in sim
    assert "3.004<br><small>[2.94, 3.06]</small>" in sim
    assert "median 54.73 %, lowest 12 %" in sim  # validation FIT of the two runs
    assert "IIPFM, t_l = 19.5 ms, G = 1.154 (J = 3.61 bar)" in sim
    assert "(nominal)" in rows[2] and "not tuned" in rows[2]  # t_off from the fallback
    assert "<figcaption>Per dataset: each identified valve parameter" in summary


def test_summary_names_a_failed_dataset_and_its_first_errors(fake_results, tmp_path):
    from spa.pipeline.status import write_status

    root = tmp_path / "results"
    shutil.copytree(fake_results.root, root)
    write_status(
        root / "a<b&c" / "status" / "identify.json", "identify", "a<b&c", ["no <charge> run"]
    )
    summary = sections(build_report(root, fake_results.datasets, META))["summary"]
    failed = re.search(r'<tr class="failed">(.*?)</tr>', summary, flags=re.S)[1]
    assert "a&lt;b&amp;c" in failed and "<code>identify</code>" in failed
    assert "<li><code>no &lt;charge&gt; run</code></li>" in failed
