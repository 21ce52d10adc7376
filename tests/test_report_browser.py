"""The HTML report in a real browser: headless Chromium shows every figure and table, and
logs nothing to the console.

Needs Debian's ``chromium`` and ``chromium-driver`` (``/usr/bin/chromium``,
``/usr/bin/chromedriver``; ``.ci/run`` installs them) and selenium. Without them the tests
skip, except under CI (``CI=true``), where they fail.
"""

from __future__ import annotations

import os
from pathlib import Path

import pytest
import yaml

import spa
from spa.report import build_report

ROOT = Path(__file__).resolve().parents[1]
CHROMIUM = Path("/usr/bin/chromium")
CHROMEDRIVER = Path("/usr/bin/chromedriver")
FLAGS = [
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--disable-quic",
]

# What the page shows, measured by the browser (the report itself has no script).
PAGE_STATS = """
const shown = e => { const r = e.getBoundingClientRect(); return r.width > 0 && r.height > 0; };
const imgs = Array.from(document.images);
const tables = Array.from(document.querySelectorAll('table'));
const links = Array.from(document.querySelectorAll('a[href^="#"]'));
return {
  images: imgs.length,
  images_shown: imgs.filter(i => i.complete && i.naturalWidth > 0 && shown(i)).length,
  tables: tables.length,
  tables_shown: tables.filter(t => t.rows.length > 1 && shown(t)).length,
  scripts: document.scripts.length,
  resources: performance.getEntriesByType('resource').map(e => e.name),
  dangling_links: links.filter(a => !document.getElementById(a.hash.slice(1))).length,
  title: document.title,
  window_width: window.innerWidth,
  page_width: document.documentElement.scrollWidth,
  // Table 3 and the summary: [table's scrollWidth, its container's width]
  table3: Array.from(document.querySelectorAll('table.t3'))
    .map(t => [t.scrollWidth, t.parentElement.clientWidth]),
  summary: Array.from(document.querySelectorAll('#summary table'))
    .map(t => [t.scrollWidth, t.parentElement.clientWidth, t.rows.length]),
  figures: document.querySelectorAll('figure').length,
  uncaptioned: Array.from(document.querySelectorAll('figure'))
    .filter(f => { const c = f.querySelector('figcaption');
                   return !c || !shown(c) || c.textContent.trim().length < 20; })
    .map(f => f.id),
  images_outside_figures: imgs.filter(i => !i.closest('figure')).length,
};
"""


def _in_ci() -> bool:
    return os.environ.get("CI", "").lower() not in ("", "0", "false", "no")


def _unavailable() -> str | None:
    """Why the browser tests cannot run here, or None."""
    missing = [str(p) for p in (CHROMIUM, CHROMEDRIVER) if not p.is_file()]
    if missing:
        return (
            f"{' and '.join(missing)} not found: install Debian's chromium and chromium-driver "
            "(apt-get install chromium chromium-driver; .ci/run does)"
        )
    try:
        import selenium  # noqa: F401
    except ImportError:
        return "selenium is not installed (pip install -e '.[test]')"
    return None


@pytest.fixture(scope="module")
def browser(tmp_path_factory):
    reason = _unavailable()
    if reason:
        if _in_ci():
            pytest.fail(f"CI=true but the browser test cannot run: {reason}")
        pytest.skip(reason)
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    options = webdriver.ChromeOptions()
    options.binary_location = str(CHROMIUM)
    for flag in FLAGS:
        options.add_argument(flag)
    options.add_argument(f"--user-data-dir={tmp_path_factory.mktemp('chromium-profile')}")
    options.set_capability("goog:loggingPrefs", {"browser": "ALL"})
    # The driver's path is given, so selenium never looks for (or downloads) one.
    driver = webdriver.Chrome(service=Service(str(CHROMEDRIVER)), options=options)
    driver.set_page_load_timeout(60)
    driver.set_window_size(1280, 900)  # a laptop's window: Table 3 must fit its width
    yield driver
    driver.quit()


def open_report(driver, path: Path) -> tuple[dict, list[dict]]:
    """Load ``path``; return the page's statistics and the console messages it logged."""
    from selenium.webdriver.support.ui import WebDriverWait

    driver.get_log("browser")  # drop anything logged before this page
    driver.get(path.as_uri())
    # a page of several MB of inline figures: parsed and every image decoded before counting
    WebDriverWait(driver, 60).until(
        lambda d: d.execute_script(
            "return document.readyState === 'complete'"
            " && Array.from(document.images).every(i => i.complete);"
        )
    )
    return driver.execute_script(PAGE_STATS), driver.get_log("browser")


def _shown(results: Path, dataset: str, path: Path) -> bool:
    """Whether the page shows an output: not one its stage's status marks ``no_runs`` (the
    page puts one line "no runs" in its place, spa.report.failure.no_runs_for)."""
    import json

    from spa.report.failure import no_runs_for

    rel = path.relative_to(results / dataset).as_posix()
    status = results / dataset / "status" / f"{rel.split('/')[0]}.json"
    if rel.startswith("validation/") or not status.is_file():
        return True
    return no_runs_for(json.loads(status.read_text()), rel) is None


def expected_counts(results: Path) -> tuple[list[str], int, int]:
    """(datasets, figures, tables) that the report of ``results`` must show, from its files."""
    datasets = sorted(p.parent.parent.name for p in results.glob("*/identification/params.yaml"))
    figures = list(results.glob("analytic/*.png"))
    tables = list(results.glob("analytic/table*.csv"))
    for d in datasets:
        for pattern in (
            "identification/*.png",
            "validation/figures/*.png",
            "staircase/fig*.png",
            "sine/fig*.png",
            "chirp/fig*.png",
            "tuning/fig*.png",
            "closed_loop/fig*.png",
        ):
            figures += [p for p in (results / d).glob(pattern) if _shown(results, d, p)]
        for name in (
            "identification/params.yaml",
            "validation/fit.csv",
            "staircase/table3.csv",
            "sine/linearity.csv",
            "chirp/bicoherence.csv",
            "tuning/table2.csv",
            "tuning/table1.csv",
            "closed_loop/table.csv",
            "closed_loop/runs.csv",
            "closed_loop/robust.csv",
        ):
            path = results / d / name
            tables += [path] if path.is_file() and _shown(results, d, path) else []
    return datasets, len(figures), len(tables)


def check_page(
    stats: dict, console: list[dict], n_figures: int, n_tables: int, n_datasets: int
) -> None:
    assert [m for m in console if m["level"] in ("SEVERE", "WARNING")] == [], console
    assert stats["scripts"] == 0
    assert stats["resources"] == []  # nothing fetched: images are data: URIs
    assert stats["images"] == stats["images_shown"] == n_figures
    # every table of the results, and the summary table
    assert stats["tables"] == stats["tables_shown"] == n_tables + 1
    assert stats["dangling_links"] == 0
    # the summary opens the page: a header row and one row per dataset
    ((width, room, rows),) = stats["summary"]
    assert rows == 1 + n_datasets and width <= room
    # every figure (and table) has a visible caption; every image is in a captioned figure
    assert stats["figures"] >= n_figures and stats["uncaptioned"] == []
    assert stats["images_outside_figures"] == 0
    # Table 3 fits a 1280 px window: no horizontal scrolling, in its box or on the page
    assert stats["window_width"] == 1280
    assert stats["table3"], "no Table 3 shown"
    for width, room in stats["table3"]:
        assert width <= room <= stats["window_width"], stats["table3"]
    assert stats["page_width"] <= stats["window_width"]


def test_fabricated_report_shows_every_figure_and_table(browser, fake_results, tmp_path):
    path = tmp_path / "report.html"
    meta = {"seed": 1, "spa version": spa.__version__}
    path.write_text(build_report(fake_results.root, fake_results.datasets, meta), encoding="utf-8")
    stats, console = open_report(browser, path)
    check_page(
        stats, console, len(fake_results.pngs), len(fake_results.tables), len(fake_results.datasets)
    )
    assert stats["title"] == "spa: reproduction report"


def check_site_page(stats: dict, console: list[dict], n_figures: int, n_tables: int) -> None:
    """A page of the site: no script, nothing fetched, every figure and table shown and
    captioned, and nothing wider than a 1280 px window (Table 3 included)."""
    assert [m for m in console if m["level"] in ("SEVERE", "WARNING")] == [], console
    assert stats["scripts"] == 0 and stats["resources"] == []
    assert stats["images"] == stats["images_shown"] == n_figures
    assert stats["tables"] == stats["tables_shown"] == n_tables
    assert stats["dangling_links"] == 0
    assert stats["uncaptioned"] == [] and stats["images_outside_figures"] == 0
    assert stats["window_width"] == 1280
    for width, room in stats["table3"]:
        assert width <= room <= stats["window_width"], stats["table3"]
    assert stats["page_width"] <= stats["window_width"]


def expected_counts_of(results: Path, dataset: str) -> tuple[int, int]:
    """(figures, tables) of one dataset's folder, as :func:`expected_counts` counts them."""
    import shutil
    import tempfile

    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        (root / "analytic").mkdir()
        shutil.copytree(results / dataset, root / dataset, ignore=_only_counted)
        _, figures, tables = expected_counts(root)
    return figures, tables


def _only_counted(folder: str, names: list[str]) -> list[str]:
    return [n for n in names if n.endswith((".parquet", ".svg"))]


def test_small_config_site_in_the_browser(browser, request):
    """The index (results/report.html, also report/index.html) and a dataset's page."""
    # the browser first, so that a missing Chromium skips before the ~1 min pipeline run
    small_run = request.getfixturevalue("small_run")  # session-scoped, in conftest.py
    datasets, _, _ = expected_counts(small_run)
    assert datasets == ["example", "sim"]
    seed = yaml.safe_load((ROOT / "config" / "config.yaml").read_text())["seed"]
    for path in (small_run / "report.html", small_run / "report" / "index.html"):
        text = path.read_text(encoding="utf-8")
        assert f"<dt>seed</dt><dd>{seed}</dd>" in text
        assert f"<dt>spa version</dt><dd>{spa.__version__}</dd>" in text
        stats, console = open_report(browser, path)
        # Fig. O1 alone; the summary and the overview table
        check_site_page(stats, console, 1, 2)
        ((width, room, rows),) = stats["summary"]
        assert rows == 1 + len(datasets) and width <= room
        assert stats["title"] == "spa: reproduction report"
    for dataset in datasets:
        stats, console = open_report(browser, small_run / "report" / f"{dataset}.html")
        figures, tables = expected_counts_of(small_run, dataset)
        check_site_page(stats, console, figures, tables)
        assert stats["table3"], "no Table 3 shown"
    stats, console = open_report(browser, small_run / "report" / "analytic.html")
    check_site_page(stats, console, 2, 2)


def test_a_dataset_with_a_failed_stage_in_the_browser(browser, fake_results, tmp_path):
    """The closed-loop stage of ``sim`` crashed: its page still shows every other figure and
    table, the stage named in their place (its contents entry resolves), and the index's
    row, parameters kept and the failure named, fits the window."""
    import shutil

    from test_site import _run_dataset_stages

    from spa.io import write_csv
    from spa.plots.save import save_figure
    from spa.report.overview import overview_row, overview_table
    from spa.report.overview_figure import plot_overview
    from spa.report.site import build_dataset_page, build_index

    root = tmp_path / "results"
    shutil.copytree(fake_results.root, root)
    _run_dataset_stages(root, "sim", "closed_loop", IndexError("index 0 is out of bounds"))
    failed = {"sim": "closed_loop"}
    rows = [overview_row(root / n, n, None, "r", failed.get(n)) for n in fake_results.datasets]
    write_csv(overview_table(rows), root / "overview.csv")
    save_figure(plot_overview(overview_table(rows)), root / "overview.png")
    meta = {"seed": 1, "spa version": spa.__version__}
    page, index = tmp_path / "sim.html", tmp_path / "index.html"
    page.write_text(build_dataset_page(root, "sim", meta), encoding="utf-8")
    index.write_text(build_index(root, fake_results.datasets, meta), encoding="utf-8")
    figures, tables = expected_counts_of(fake_results.root, "sim")
    stats, console = open_report(browser, page)
    # closed_loop: Figs. 10-11, its metrics, recorded-runs and robust tables are not shown
    check_site_page(stats, console, figures - 2, tables - 3)
    assert stats["table3"], "no Table 3 shown"
    stats, console = open_report(browser, index)
    check_site_page(stats, console, 1, 2)  # Fig. O1; the summary and the overview table
    ((width, room, rows),) = stats["summary"]
    assert rows == 1 + len(fake_results.datasets) and width <= room
