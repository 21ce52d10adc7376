"""The report as a static site (spa.report.site) and the overview across datasets
(spa.report.overview, Fig. O1) on fabricated results and a simulated series of sessions."""

from __future__ import annotations

import html
import re
import shutil
from datetime import date, timedelta
from pathlib import Path

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
ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def site(fake_results, tmp_path_factory):
    """The fabricated results with each dataset's overview row and the overview written."""
    from spa.io import write_csv
    from spa.plots.save import save_figure
    from spa.report.overview_figure import plot_overview

    root = tmp_path_factory.mktemp("site") / "results"
    shutil.copytree(fake_results.root, root)
    rows = []
    for i, name in enumerate(fake_results.datasets):
        row = overview_row(root / name, name, f"2025-0{i + 1}-01", "bench", valve="bench / V1")
        rows.append(row)
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
    assert "Fig. 2a" not in page and "no &lt;charge&gt;" in page


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
    from spa.report.overview_figure import plot_overview

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


def test_a_change_is_flagged_only_between_estimates_of_the_same_kind_of_runs(tmp_path):
    """A pilot's delay (its pulse runs) and a full session's (refined on modulated runs) are
    different effective delays of one valve: their intervals may disagree on an unchanged
    valve, and the overview does not call that a change; two sessions on the same kind of
    runs that disagree are."""
    from spa.identification.results import with_basis

    kinds = {"p": "pulse", "s": "staircase", "w": "sine"}
    sessions = [  # name, t_on interval (ms), its runs
        ("pilot", (14.9, 32.8), ["p"]),
        ("full", (1.6, 5.7), ["s", "w"]),
        ("verify", (1.8, 5.0), ["s"]),
        ("later", (9.0, 12.0), ["s", "w"]),
    ]
    rows = []
    for i, (name, (lo, hi), runs) in enumerate(sessions):
        doc = {"t_on": {"value": (lo + hi) / 2e3, "lo": lo / 1e3, "hi": hi / 1e3, "runs": runs}}
        folder = tmp_path / name / "identification"
        folder.mkdir(parents=True)
        (folder / "params.yaml").write_text(yaml.safe_dump(with_basis(doc, kinds)))
        rows.append(overview_row(tmp_path / name, name, f"2025-03-0{i + 1}", "bench"))
    table = overview_table(rows)
    assert table["t_on_basis"].tolist() == ["pulse", "modulated", "modulated", "modulated"]
    assert table["changed_t_on"].tolist() == [False, False, False, True]


# --- A failed stage hides nothing ----------------------------------------------------------


def _run_dataset_stages(root, dataset: str, failing: str, error: Exception) -> None:
    """Every stage of ``dataset`` as a run goes through them (spa.pipeline.status.run_stage),
    its outputs already on disk: ``failing`` raises ``error``; the others do nothing, or are
    skipped (placeholders) when they read the failed one."""
    import logging
    from types import SimpleNamespace

    from spa.pipeline.jobs import Names
    from spa.pipeline.outputs import STAGES, stage_outputs
    from spa.pipeline.status import run_stage

    def work(stage: str) -> None:
        if stage == failing:
            raise error

    for stage in STAGES:
        if not stage.per_dataset or stage.name in ("raw_manifest", "page"):
            continue
        job = SimpleNamespace(
            output=Names(stage_outputs(stage.name, root, dataset)),
            wildcards=Names({"dataset": dataset}),
        )
        run_stage(job, stage.name, lambda s=stage.name: work(s), logging.getLogger("test_site"))


@pytest.fixture
def broken_closed_loop(site, tmp_path):
    """The results with the closed-loop stage of ``sim`` crashed by a bug (issue 29's bare
    IndexError in the PI design) on data that the earlier stages accepted."""
    root = tmp_path / "results"
    shutil.copytree(site, root)
    crash = IndexError("index 0 is out of bounds for axis 0 with size 0")
    _run_dataset_stages(root, "sim", "closed_loop", crash)
    return root


def test_a_failed_stage_leaves_every_other_result_on_the_page(fake_results, broken_closed_loop):
    import base64

    from spa.pipeline.status import _EMPTY_PNG

    page = build_dataset_page(broken_closed_loop, "sim", META)
    # every figure of the stages that worked, none of the failed stage's (placeholders)
    own = [p for p in fake_results.pngs if p.relative_to(fake_results.root).parts[0] == "sim"]
    made = [p for p in own if p.parent.name != "closed_loop"]
    assert page.count("<img ") == len(made) == len(own) - 2
    assert base64.b64encode(_EMPTY_PNG).decode() not in page
    for title in ("Identified valve parameters", "Table 3: static linearity", "Fig. 2a"):
        assert title in page
    # the failed stage's own section is gone (the recommendation's caption still names it)
    assert "Recommended modulator for this valve" in page
    assert "<h3>Closed loop: the PI" not in page
    # the failed stage named with its one-line message, in its outputs' place
    note = (
        "Stage <code>closed_loop</code> (Closed loop) failed: <code>IndexError: index 0 is "
        "out of bounds for axis 0 with size 0</code>"
    )
    assert page.count(note) == 1
    assert page.index("Fig. 9: bicoherence") < page.index(note)
    assert "Dataset sim (failed)" in page


def test_fix_the_data_only_when_the_data_is_at_fault(broken_closed_loop, site, tmp_path):

    page = build_dataset_page(broken_closed_loop, "sim", META)
    assert "fix it" not in page.lower() and "spa validate" not in page
    assert "The data is not known to be at fault" in page
    index = build_index(broken_closed_loop, ["sim", "a<b&c"], META)
    failed = index[index.index('<section id="failed">') : index.index('<section id="summary">')]
    assert "fix it" not in failed.lower() and "not known to be at fault" in failed

    root = tmp_path / "bad_data"
    shutil.copytree(site, root)
    _run_dataset_stages(root, "sim", "runs", _dataset_error())
    page = build_dataset_page(root, "sim", META)
    assert "The data is at fault: fix it" in page and "spa validate raw/sim" in page


def test_data_that_pass_validation_are_not_at_fault(site, tmp_path):
    """An IdentificationError on data that validation accepted: what the data lack, in the
    error's words, and that validation passed; never "the data is at fault"."""
    from spa.identification import IdentificationError
    from spa.pipeline.status import dataset_failures, failure_summary

    root = tmp_path / "lacking"
    shutil.copytree(site, root)
    lack = "discharge run 'd1': only 5 samples between the response start and the tail"
    _run_dataset_stages(root, "sim", "identify", IdentificationError(lack))
    page = build_dataset_page(root, "sim", META)
    assert "at fault: fix it" not in page and "The data is at fault" not in page
    assert "<code>spa validate raw/sim</code> accepts this dataset" in page
    assert f"lack what the stage needs: <code>IdentificationError: {html.escape(lack)}" in page
    text = failure_summary(dataset_failures(root, ["sim"]))
    assert "fix it" not in text and "validation passed" in text


def _run_with_notes(root, dataset: str, notes: dict) -> None:
    """Every stage of ``dataset`` run through spa.pipeline.status.run_stage, its outputs on
    disk; the stages in ``notes`` return those warnings."""
    import logging
    from types import SimpleNamespace

    from spa.pipeline.jobs import Names
    from spa.pipeline.outputs import STAGES, stage_outputs
    from spa.pipeline.status import run_stage

    for stage in STAGES:
        if not stage.per_dataset or stage.name in ("raw_manifest", "page"):
            continue
        job = SimpleNamespace(
            output=Names(stage_outputs(stage.name, root, dataset)),
            wildcards=Names({"dataset": dataset}),
        )
        said = notes.get(stage.name)
        run_stage(job, stage.name, lambda s=said: s, logging.getLogger("test_site"))


def test_a_stage_without_runs_of_its_kind_says_no_runs_not_ok(site, tmp_path):
    """Issue 46: staircase, sine and chirp stages without runs, and the closed loop's
    comparison of recorded runs without closed_loop runs, say "no runs" on the page and in
    the status, in place of empty tables and figures."""
    from spa.pipeline.status import NoRuns, read_status

    root = tmp_path / "results"
    shutil.copytree(site, root)
    notes = {k: [NoRuns(k)] for k in ("staircase", "sine", "chirp")}
    notes["closed_loop"] = [NoRuns("closed_loop", ("closed_loop/runs.csv",))]
    _run_with_notes(root, "sim", notes)
    status = read_status(root / "sim" / "status" / "staircase.json")
    assert status["ok"] and status["no_runs"][0]["message"] == "no staircase runs in this dataset"
    page = build_dataset_page(root, "sim", META)
    for kind in ("staircase", "sine", "chirp", "closed_loop"):
        line = f"no {kind} runs in this dataset; nothing to show."
        assert page.count(line) == 1, kind
    for title in ("Table 3: static linearity", "Fig. 6", "Fig. 7a", "Fig. 8", "Fig. 9",
                  "Closed loop: recorded runs against the model"):  # fmt: skip
        assert title not in page, title
    assert "Fig. 10" in page and "Fig. 2a" in page  # the stages' other outputs are shown
    before = build_dataset_page(site, "sim", META)
    assert before.count("<img ") - page.count("<img ") == 5  # Figs. 6, 7a, 7b, 8, 9
    row = overview_row(root / "sim", "sim", "2025-01-01", "bench")
    assert row["status"] == "ok; no runs: staircase, sine, chirp, closed_loop"
    assert overview_row(site / "sim", "sim", "2025-01-01", "bench")["status"] == "ok"


def test_stages_skipped_for_a_failed_one_say_so_in_one_line(site, tmp_path):
    from spa.identification import IdentificationError

    root = tmp_path / "results"
    shutil.copytree(site, root)
    _run_dataset_stages(root, "sim", "identify", IdentificationError("no charge run"))
    page = build_dataset_page(root, "sim", META)
    assert "<img " not in page  # every stage after identification read its result
    skipped = ["tune", "validate_model", "staircase", "sine", "chirp", "closed_loop"]
    for stage in skipped:
        line = f"Stage <code>{stage}</code> ("
        assert page.count(line) == 1, stage
        at = page.index(line)
        assert page[at : page.index("</p>", at)].endswith(
            "not run: stage <code>identify</code> failed."
        )
    assert page.count('class="note stage-skipped"') == len(skipped)
    assert "Stage <code>identify</code> (Identification) failed: <code>IdentificationError: " in (
        page
    )


def test_the_index_row_keeps_the_parameters_and_names_the_failed_stage(broken_closed_loop):
    index = build_index(broken_closed_loop, ["sim", "a<b&c"], META)
    summary = index[index.index('<section id="summary">') : index.index('<section id="overview">')]
    row = re.search(r'<tr class="failed"><th scope="row"><a href="sim.html">.*?</tr>', summary)[0]
    assert "0.5337<br><small>[0.5223, 0.5437]</small>" in row  # c1 with its interval
    assert "median 54.73 %, lowest 12 %" in row  # the validation FIT
    assert "IIPFM, t_l = 19.5 ms, G = 1.154 (J = 3.61 bar)" in row  # the recommendation
    assert "FAILED at stage <code>closed_loop</code>" in row and "IndexError" in row
    # the overview's row keeps them too
    over = overview_row(broken_closed_loop / "sim", "sim", None, "r", failed="closed_loop")
    assert over["status"] == "failed: closed_loop"
    assert over["c1"] == pytest.approx(0.533 * 1.0012345) and over["fit_median"] > 50
    assert over["recommended"].startswith("IIPFM")


def test_a_failed_identification_leaves_the_row_without_parameters(site, tmp_path):
    from spa.identification import IdentificationError

    root = tmp_path / "results"
    shutil.copytree(site, root)
    _run_dataset_stages(root, "sim", "identify", IdentificationError("no charge run"))
    summary = build_index(root, ["sim"], META)
    row = re.search(r'<tr class="failed">.*?</tr>', summary)[0]
    assert "<br><small>" not in row and "FAILED at stage <code>identify</code>" in row
    over = overview_row(root / "sim", "sim", None, "r", failed="identify")
    assert np.isnan(over["c1"]) and not over["recommended"]


def _config_error() -> Exception:
    from spa.pipeline.config import ConfigError

    return ConfigError("closed_loop.tau_c: expected a positive number")


def _tuning_error() -> Exception:
    from spa.identification.identified import TuningError

    return TuningError("t_on: the 95 % interval [0.0, 0.00068] leaves the physical domain")


def _identification_error() -> Exception:
    from spa.identification import IdentificationError

    return IdentificationError("discharge run 'd1' has only 80 samples")


def _wrapped(error: Exception) -> Exception:
    from spa.pipeline.status import naming_run

    try:
        with naming_run("s1", "staircase"):
            raise error
    except Exception as exc:  # the RunError naming the run
        return exc
    raise AssertionError("naming_run raised nothing")


def _dataset_error() -> Exception:
    from spa.datasets import DatasetError

    return DatasetError("raw/d", [])


@pytest.mark.parametrize(
    ("make", "fault"),
    [
        (_identification_error, "lacking"),
        (_dataset_error, "data"),
        (lambda: _wrapped(ValueError("u goes down")), "stage"),  # a bare ValueError: not spa's
        (lambda: _wrapped(_identification_error()), "lacking"),
        (lambda: IndexError("index 0 is out of bounds"), "stage"),
        (_tuning_error, "stage"),
        (_config_error, "stage"),
    ],
)
def test_whose_fault_a_failure_is_follows_the_error_class(make, fault, tmp_path):
    """The rule of spa.pipeline.status.data_fault, recorded by run_stage in the status."""
    from spa.errors import RunError
    from spa.pipeline.status import (
        data_fault,
        dataset_failures,
        failure_summary,
        fault_of,
        read_status,
    )

    error = make()
    assert data_fault(error) is (fault == "data") and fault_of(error) == fault
    _run_dataset_stages(tmp_path, "d1", "sine", error)
    status = read_status(tmp_path / "d1" / "status" / "sine.json")
    assert status["ok"] is False and status["fault"] == fault
    assert "fault" not in read_status(tmp_path / "d1" / "status" / "identify.json")
    text = failure_summary(dataset_failures(tmp_path, ["d1"]))
    assert ("(the data: fix it)" in text) is (fault == "data")
    if isinstance(error, RunError):
        assert "run 's1' (staircase)" in status["errors"][0]


# --- Pages of datasets no longer in raw/ ---------------------------------------------------


def _script(name: str, job) -> None:
    """Run ``workflow/scripts/<name>.py`` as its rule would, ``job`` as ``snakemake``."""
    import runpy

    from spa import _memo

    script = ROOT / "workflow" / "scripts" / f"{name}.py"
    try:
        runpy.run_path(str(script), init_globals={"snakemake": job}, run_name="__main__")
    finally:
        _memo.use_folder(None)  # a job's process ends here; this one goes on testing


def test_a_dataset_removed_from_the_run_loses_its_page(fake_results, site, tmp_path):
    """The overview and report jobs run with two datasets, then with one: the other's page is
    removed, the index no longer lists it, the remaining page is unchanged, and nothing else
    is touched (its results folder, a file of the user's in report/)."""
    from types import SimpleNamespace

    from spa.pipeline.jobs import Names
    from spa.pipeline.outputs import stage_outputs

    root = tmp_path / "results"
    shutil.copytree(site, root)
    report = root / "report"
    rows = {}
    for name in fake_results.datasets:  # each dataset's own job: its page and overview row
        (report / page_name(name)).parent.mkdir(exist_ok=True)
        (report / page_name(name)).write_text(build_dataset_page(root, name, META))
        rows[name] = stage_outputs("page", root, name)["row"]
        write_row(rows[name], overview_row(root / name, name, None, "bench"))
    (report / "notes.html").write_text("<title>my notes</title>")

    def run(datasets: list[str]) -> str:
        log = [str(tmp_path / "report.log")]
        inputs = Names({"rows": [rows[n] for n in datasets]})
        _script(
            "overview",
            SimpleNamespace(input=inputs, output=Names(stage_outputs("overview", root)), log=log),
        )
        params = Names({"datasets": datasets, "seed": META["seed"]})
        _script(
            "report",
            SimpleNamespace(output=Names(stage_outputs("report", root)), log=log, params=params),
        )
        return (report / "index.html").read_text()

    both = run(fake_results.datasets)
    assert 'href="a&lt;b&amp;c.html"' in both and (report / "a<b&c.html").is_file()
    kept = (report / "sim.html").read_bytes()
    index = run(["sim"])
    assert not (report / "a<b&c.html").exists()
    assert "a&lt;b&amp;c" not in index and "a<b&c" not in index
    assert (report / "sim.html").read_bytes() == kept and 'href="sim.html"' in index
    assert (report / "notes.html").is_file() and (report / "analytic.html").is_file()
    assert (root / "a<b&c" / "identification" / "params.yaml").is_file()
    assert (
        "a<b&c.html: its dataset is no longer in the run" in (tmp_path / "report.log").read_text()
    )
    from spa.report.site import remove_stale_pages

    assert remove_stale_pages(report, ["sim"]) == []  # nothing more to remove


def test_an_open_loop_stage_without_runs_records_no_runs(tmp_path, monkeypatch):
    """spa.stages.script.run_open_loop: a stage whose result is empty (no runs of its kind)
    records NoRuns in its status; one with runs does not."""
    from types import SimpleNamespace

    import spa.stages.script as script
    from spa.pipeline.jobs import Names
    from spa.pipeline.status import read_status

    monkeypatch.setattr(script, "read_runs", lambda _: ({}, {}))
    monkeypatch.setattr(script, "read_params", lambda _: None)
    for empty in (True, False):
        status = tmp_path / f"{empty}" / "status" / "sine.json"
        smk = SimpleNamespace(
            input=Names({"runs": "r", "params": "p"}),
            params=Names({"cfg": {}}),
            output=Names({"status": str(status)}),
            wildcards=Names({"dataset": "d"}),
            log=[str(tmp_path / f"{empty}.log")],
        )
        result = SimpleNamespace(empty=empty, warnings=[])
        assert script.run_open_loop(smk, "sine", lambda i, log, r=result: r, lambda *a: None)
        record = read_status(status)
        assert record["ok"]
        if empty:
            assert record["no_runs"] == [
                {"kind": "sine", "message": "no sine runs in this dataset", "paths": []}
            ]
        else:
            assert "no_runs" not in record
