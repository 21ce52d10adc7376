"""The pipeline as a user runs it: small config end to end, bad config, bad dataset."""

from __future__ import annotations

import json
import re
import shutil
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SNAKEMAKE = [sys.executable, "-m", "snakemake"]


def run(*args: str, cwd: Path = ROOT) -> subprocess.CompletedProcess:
    return subprocess.run([*SNAKEMAKE, *args], cwd=cwd, capture_output=True, text=True, timeout=900)


#: The profile keeps the console to progress and the summary (`quiet: [host, rules]`); a dry
#: run that should list each job with its files says so.
LIST_JOBS = ("--quiet", "host")


# `small_run` (tests/conftest.py): the small config run once per session, shared with
# the report tests.


def test_small_config_produces_every_target(small_run):
    """Every output the registry names (spa.pipeline.outputs), for both datasets, is there
    and not empty."""
    from spa.pipeline.outputs import all_targets

    targets = [Path(p) for p in all_targets(small_run, ["sim", "example"], vectors=False)]
    assert small_run / "report.html" in targets
    for path in targets:
        assert any(path.iterdir()) if path.is_dir() else path.stat().st_size > 0, path
    for dataset in ["sim", "example"]:
        assert len(list((small_run / dataset / "runs").glob("*.parquet"))) >= 5
    assert sorted(p.name for p in (small_run / "logs").iterdir()) == [
        "analytic",
        "check.log",
        "example",
        "overview.log",
        "report.log",
        "sim",
    ]
    assert (small_run / "status.yaml").is_file()  # the check found no failed dataset


def test_every_figure_is_for_print_with_its_vector_copy_and_data(small_run):
    """Every PNG of the run (registered figures and the validation folders): at least 1000 px
    wide at 200 dpi or more, an SVG copy beside it and the plotted data as CSV."""
    import struct

    from spa.pipeline.outputs import STAGES
    from spa.pipeline.stage_types import FIGURE, VECTOR

    # the results, not the store of stages' outputs kept for reuse (results/.store)
    pngs = sorted(p for p in small_run.rglob("*.png") if ".store" not in p.parts)
    registered = {o.path for s in STAGES for o in s.outputs if o.kind == FIGURE}
    for dataset in ["sim", "example"]:  # every registered figure of each dataset is a PNG here
        per_dataset = {o.path for s in STAGES if s.per_dataset for o in s.outputs}
        assert registered & per_dataset <= {
            str(p.relative_to(small_run / dataset))
            for p in pngs
            if p.is_relative_to(small_run / dataset)
        }
    assert len(pngs) >= 30
    for png in pngs:
        data = png.read_bytes()
        width = struct.unpack(">I", data[16:20])[0]
        assert width >= 1000, (png, width)
        ppm = struct.unpack(">II", data[data.index(b"pHYs") + 4 :][:8])  # pixels per metre
        assert min(ppm) >= 200 / 0.0254 - 1, (png, ppm)
        svg = png.with_suffix(".svg")
        if any(png.is_relative_to(small_run / d) for d in ("sim", "example")):
            assert not svg.exists(), svg  # a dataset's figures: PNG alone (figure_formats)
        else:  # the analytic figures and Fig. O1 keep their SVG
            assert svg.read_text().startswith("<?xml") and "<svg" in svg.read_text()[:600], svg
        assert png.with_suffix(".csv").stat().st_size > 0, png
    vectors = [o for s in STAGES for o in s.outputs if o.kind == VECTOR]
    assert {v.path for v in vectors} == {p.replace(".png", ".svg") for p in registered}


def test_small_config_produces_the_open_loop_analyses(small_run):
    import pandas as pd

    for dataset in ["sim", "example"]:
        d = small_run / dataset
        for name in ["staircase/fig6.png", "staircase/fig7a.png", "staircase/fig7b.png",
                     "sine/fig8.png", "chirp/fig9.png"]:  # fmt: skip
            assert (d / name).stat().st_size > 0, (dataset, name)
    sim = pd.read_csv(small_run / "sim" / "staircase" / "table3.csv")
    assert len(sim) == 5 and sim["paper_fit"].notna().all()
    # five settings and the linear reference (the same input through a linear plant)
    sine = pd.read_csv(small_run / "sim" / "sine" / "linearity.csv")
    chirp = pd.read_csv(small_run / "sim" / "chirp" / "bicoherence.csv")
    assert len(sine) == len(chirp) == 6 and sine["modulator"].iloc[-1] == "linear"
    # the linear reference logged by the first run's sensor: its false-alarm rate without the
    # ringing after the valve edges, which the bicoherence reads as coupling
    linear = chirp.iloc[-1]
    assert linear["significant_fraction_no_ringing"] <= 0.03 < linear["significant_fraction"]
    runs = chirp.iloc[:-1]
    assert (runs["significant_fraction_no_ringing"] < runs["significant_fraction"]).all()
    assert chirp[["significant_fraction", "max_bicoherence"]].le(1.0).all().all()
    # raw/example holds two staircases and no sine or chirp run: empty tables, not errors
    assert len(pd.read_csv(small_run / "example" / "staircase" / "table3.csv")) == 2
    assert pd.read_csv(small_run / "example" / "sine" / "linearity.csv").empty


def test_simulated_table3_ranks_the_modulators_as_the_paper(small_run):
    """Issue 5, section 4: IIPFM G=1.15, IIPFM G=1, ΔΣM, PWM, IPFM (here by FIT %)."""
    import pandas as pd

    table = pd.read_csv(small_run / "sim" / "staircase" / "table3.csv")
    ours = table.sort_values("fit", ascending=False)["paper_case"].tolist()
    paper = table.sort_values("paper_fit", ascending=False)["paper_case"].tolist()
    assert ours == paper == ["IIPFM (G = 1.15)", "IIPFM (G = 1.00)", "ΔΣM", "PWM", "IPFM"]


def test_identified_example_valve_is_its_hidden_truth(small_run):
    import yaml

    from spa.synthetic import EXAMPLE_PARAMS

    found = yaml.safe_load((small_run / "example" / "identification" / "params.yaml").read_text())
    for name, true in EXAMPLE_PARAMS.as_dict().items():
        assert found[name]["lo"] <= true <= found[name]["hi"], (name, found[name], true)


def test_second_run_has_nothing_to_do(small_run, isolated_config):
    res = run(
        "reproduce-all",
        "--configfile",
        "config/small.yaml",
        str(isolated_config),
        "--config",
        f"results={small_run}",
        "-n",
    )
    assert res.returncode == 0
    assert "Nothing to be done" in res.stdout + res.stderr


def test_lint_finds_nothing_but_the_explained_conda_advice(isolated_config):
    res = run("--lint", "--configfile", "config/small.yaml", str(isolated_config))
    findings = {
        line.strip() for line in (res.stdout + res.stderr).splitlines() if line.startswith("    * ")
    }
    assert findings == {"* Specify a conda environment or container for each rule.:"}, findings


def test_the_console_shows_progress_and_the_summary_not_file_lists(small_run):
    """profiles/default: a run prints its plan, one progress line per job and the summary
    (332 lines before, mostly each job's input and output files; 84 after)."""
    text = small_run.with_name(f"{small_run.name}.console.txt").read_text()
    lines = text.splitlines()
    jobs = int(re.search(r"^total +(\d+)$", text, flags=re.M).group(1))
    assert len(lines) <= 30 + 6 * jobs, text[-3000:]
    assert max(map(len, lines)) < 200, "a line lists files"
    assert not any(line.lstrip().startswith(("input:", "output:", "reason:")) for line in lines)
    assert f"{jobs} of {jobs} steps (100%) done" in text
    assert "all 2 datasets complete" in text  # the summary


def test_a_failing_job_still_says_why(tmp_path):
    bad = tmp_path / "bad.yaml"
    bad.write_text("analytic:\n  selected:\n    - {type: pwm, f_w: 1.0e-300}\n")
    out = tmp_path / "results"
    res = run(f"{out}/analytic/table1.csv", "--configfile", "config/small.yaml", str(bad),
              "--config", f"results={out}")  # fmt: skip
    assert res.returncode != 0
    text = res.stdout + res.stderr
    assert "selected[0]: pwm: setting 'f_w' = 1e-300 is outside the range" in text
    assert "analytic.smk" in text and "Exiting because a job execution failed" in text
    assert len(text.splitlines()) < 60


def test_typo_in_config_names_the_key(tmp_path):
    bad = tmp_path / "bad.yaml"
    bad.write_text("analytic:\n  n_xy: 3\n")
    res = run("-n", "--configfile", str(bad))
    assert res.returncode != 0
    text = res.stdout + res.stderr
    assert "analytic: Additional properties are not allowed ('n_xy' was unexpected)" in text


def test_bad_raw_dataset_fails_alone_and_the_report_names_it(tmp_path):
    """A broken bench dataset costs only itself: the others and the report are built, the
    report lists it with its first error, and the run's exit status is non-zero."""
    raw = tmp_path / "raw"
    shutil.copytree(ROOT / "raw" / "example", raw / "example")
    shutil.copytree(ROOT / "raw" / "example", raw / "broken")
    spec = raw / "broken" / "dataset.yaml"
    spec.write_text(
        spec.read_text()
        .replace("name: example", "name: broken")
        .replace("kind: pulse", "kind: pulsed")
    )
    out = tmp_path / "results"
    res = run(
        "reproduce-all",
        "--configfile",
        "config/small.yaml",
        "--config",
        f"results={out}",
        f"datasets={{'raw_dir': '{raw}'}}",
        "-c2",
    )
    assert res.returncode != 0
    assert "dataset broken: stage runs failed" in res.stderr
    log = (out / "logs" / "broken" / "ingest.log").read_text()
    assert "pulsed" in log and "dataset.yaml" in log
    # the good datasets are complete, the report is written and names the failure
    assert (out / "example" / "staircase" / "table3.csv").stat().st_size > 100
    assert (out / "sim" / "chirp" / "bicoherence.csv").stat().st_size > 100
    page = (out / "report.html").read_text()
    assert "Failed datasets" in page and "pulsed" in page
    assert "Dataset broken (failed)" in page
    # the failed datasets come first; the summary names it too, with the stage that failed
    assert page.index('<section id="failed">') < page.index('<section id="summary">')
    summary = page[page.index('<section id="summary">') : page.index('<section id="overview">')]
    assert '<tr class="failed"><th scope="row"><a href="report/broken.html">broken</a></th>' in (
        summary
    )
    assert "FAILED at stage <code>runs</code>" in summary and "pulsed" in summary
    assert not (out / "status.yaml").exists()
    # a second run does nothing new and still fails, naming the dataset
    again = run(
        "reproduce-all",
        "--configfile",
        "config/small.yaml",
        "--config",
        f"results={out}",
        f"datasets={{'raw_dir': '{raw}'}}",
        "-c2",
    )
    assert again.returncode != 0 and "dataset broken" in again.stderr
    assert "rule ingest_dataset" not in again.stdout + again.stderr


def test_hidden_and_spec_less_folders_of_raw_are_not_datasets(tmp_path):
    raw = tmp_path / "raw"
    for name in ["example", ".hidden"]:
        shutil.copytree(ROOT / "raw" / "example", raw / name)
    (raw / "notes").mkdir()
    out = tmp_path / "results"
    res = run(
        "reproduce-all",
        "-n",
        *LIST_JOBS,
        "--configfile",
        "config/small.yaml",
        "--config",
        f"results={out}",
        f"datasets={{'raw_dir': '{raw}'}}",
    )
    assert res.returncode == 0, res.stderr[-3000:]
    text = res.stdout + res.stderr
    assert f"{out}/example/runs" in text
    assert ".hidden" not in text and "notes" not in text


def test_fallback_identification_and_a_run_that_is_not_its_kind(tmp_path):
    """use_fallback: a dataset without pulse runs is identified with nominal delays and gets
    its figures; a 'staircase' run whose input is not a staircase fails its stage with the run
    named (one line in the log and on the console, no traceback), not the workflow."""
    import json

    raw = tmp_path / "raw"
    shutil.copytree(ROOT / "raw" / "example", raw / "nopulse")
    spec = raw / "nopulse" / "dataset.yaml"
    text = spec.read_text().replace("name: example", "name: nopulse")
    start = text.index("- id: pulse")
    text = text[:start] + text[text.index("- id: staircase_iipfm", start) :]
    spec.write_text(text)
    (raw / "nopulse" / "pulse.csv").unlink()
    # a sine where the dataset says staircase
    import numpy as np
    import pyarrow as pa
    import pyarrow.parquet as pq

    path = raw / "nopulse" / "staircase_pwm-20Hz.parquet"
    table = pq.read_table(path).to_pandas()
    table[table.columns[-1]] = 0.5 + 0.4 * np.sin(np.arange(len(table)) / 500.0)
    pq.write_table(pa.Table.from_pandas(table, preserve_index=False), path)
    cfg = tmp_path / "cfg.yaml"
    cfg.write_text(f"identification: {{use_fallback: true}}\ndatasets: {{raw_dir: {raw}}}\n")
    out = tmp_path / "results"
    res = run(
        f"{out}/nopulse/staircase/table3.csv",
        f"{out}/nopulse/validation/fit.csv",
        "--configfile",
        "config/small.yaml",
        str(cfg),
        "--config",
        f"results={out}",
        "-c2",
    )
    assert res.returncode == 0, res.stderr[-3000:]
    status = json.loads((out / "nopulse" / "status" / "identify.json").read_text())
    assert status["ok"], status
    params = (out / "nopulse" / "identification" / "params.yaml").read_text()
    assert "fallback" in params
    assert (out / "nopulse" / "identification" / "fig2c.png").stat().st_size > 1000
    stair = json.loads((out / "nopulse" / "status" / "staircase.json").read_text())
    assert not stair["ok"]
    said = "run 'staircase_pwm-20Hz' is labelled staircase but u goes both up and down"
    assert said in stair["errors"][0]
    log = (out / "logs" / "nopulse" / "staircase.log").read_text()
    assert "labelled staircase but u goes both up and down" in log  # one line, no traceback:
    assert "Traceback" not in log and "Traceback" not in res.stderr  # an input error, no bug


def test_staleness_follows_content_not_modification_times(tmp_path):
    """Touching a raw file reruns nothing; new content with an older modification time (a
    restored backup, rsync -t) reruns the ingest; a deleted run table is rebuilt."""
    import os

    raw = tmp_path / "raw"
    shutil.copytree(ROOT / "raw" / "example", raw / "example")
    out = tmp_path / "results"
    # the run tables are a target, as in reproduce-all (a deleted member is rebuilt then)
    targets = [f"{out}/example/runs", f"{out}/example/identification/params.yaml"]
    args = [*targets, "--configfile", "config/small.yaml", "--config", f"results={out}",
            f"datasets={{'raw_dir': '{raw}'}}", "-c2"]  # fmt: skip
    assert run(*args).returncode == 0

    def planned() -> set[str]:
        res = run(*args, "-n", *LIST_JOBS)
        assert res.returncode == 0, res.stderr[-2000:]
        return set(re.findall(r"^rule (\w+):", res.stdout, flags=re.M))

    csv = raw / "example" / "charge.csv"
    old = csv.stat().st_mtime
    os.utime(csv, (old + 3600, old + 3600))  # a touch: newer, same content
    assert planned() == set()
    lines = csv.read_text().splitlines(keepends=True)
    fields = lines[10].split(",")
    fields[1] = f"{float(fields[1]) + 0.5:g}"
    lines[10] = ",".join(fields)
    csv.write_text("".join(lines))
    os.utime(csv, (old - 3600, old - 3600))  # new content, an older time
    assert planned() == {"ingest_dataset", "analyse"}
    assert run(*args).returncode == 0
    assert planned() == set()
    (out / "example" / "runs" / "pulse.parquet").unlink()
    assert planned() == {"ingest_dataset", "analyse"}


def _files(folder: Path) -> dict[str, bytes]:
    """Every file of a results folder but logs, the report's pages, the store of stage
    results, the execution records (where and when each job ran: spa.pipeline.execution) and
    the recommendation's `source:` line (it names the results folder), by relative path; a
    status file without its `reuse` field (how it came: reused or computed,
    spa.pipeline.reuse)."""
    found = {}
    for path in sorted(folder.rglob("*")):
        rel = str(path.relative_to(folder))
        if rel.endswith("provenance/execution.json"):
            continue
        if path.is_file() and not rel.startswith(("logs/", "report", ".store/")):
            data = path.read_bytes()
            if path.name == "recommendation.yaml":
                data = data.split(b"\n", 1)[1]
            if path.parent.name == "status" and path.suffix == ".json":
                record = json.loads(data)
                record.pop("reuse", None)
                data = json.dumps(record).encode()
            if rel == "status.yaml":
                data = data.split(b"stages:", 1)[0]
            found[rel] = data
    return found


def test_figures_setting_draws_for_the_named_datasets_only(small_run, isolated_config, tmp_path):
    """`figures: none` writes every table and every figure's data, byte for byte those of a
    run with figures, and no figure; naming one dataset then draws its figures alone (the
    other dataset's analysis does not rerun); a rerun without figures removes them."""
    from spa.pipeline.outputs import figure_paths, stage_outputs

    out = tmp_path / "results"
    base = ["reproduce-all", "--configfile", "config/small.yaml", str(isolated_config)]
    args = [*base, "-c2", "--config", f"results={out}"]
    res = run(*args, "figures=none")
    assert res.returncode == 0, res.stderr[-3000:]
    stages = ["identify", "tune", "validate_model", "staircase", "sine", "chirp", "closed_loop"]
    assert all("figures" not in stage_outputs(s, out, figures=False) for s in stages)
    figures = {
        str(Path(p).relative_to(small_run))
        for d in ["sim", "example"]
        for p in figure_paths(stages, small_run, d)
    }
    with_figures, without = _files(small_run), _files(out)
    expected = {
        rel: data
        for rel, data in with_figures.items()
        if rel not in figures and not any(rel.startswith(f"{f}/") for f in figures)
    }
    assert without == expected  # the same tables and figure data, and no figure
    for dataset in ["sim", "example"]:
        page = (out / "report" / f"{dataset}.html").read_text()
        assert page.count("No figures for this dataset") == 1 and "<img " not in page
    assert (out / "report.html").read_text().count("<img ") == 1  # Fig. O1 only
    assert (out / "report" / "analytic.html").read_text().count("<img ") == 2  # Figs. 4, 5

    plan = run(*args, "figures=[example]", "-n", *LIST_JOBS)
    assert plan.returncode == 0, plan.stderr[-3000:]
    pattern = r"^rule (\w+):\n(?:    .*\n)*?    wildcards: dataset=(\w+)"
    assert re.findall(pattern, plan.stdout, re.M) == [("analyse", "example")], plan.stdout
    assert run(*args, "figures=[example]").returncode == 0
    drawn = [rel for rel in with_figures if rel.startswith("example/") and rel.endswith(".png")]
    assert drawn, "the full run drew example's figures"
    for rel, data in with_figures.items():
        if rel.startswith("example/") and rel.endswith((".png", ".svg")):
            assert (out / rel).read_bytes() == data, rel  # the same figures as a full run
    assert not list((out / "sim").rglob("*.png"))

    # new tuning settings without figures: example's analysis reruns and takes its figures
    res = run(*args, "figures=none", "tuning={score: J_exact}")
    assert res.returncode == 0, res.stderr[-3000:]
    assert not list((out / "example").rglob("*.png")), "a figure outlived its tables"
    assert not list((out / "example").rglob("*.svg"))
    assert not (out / "example" / "validation" / "figures").exists()


def test_missing_or_altered_outputs_are_rebuilt_and_nothing_else(tmp_path, isolated_config):
    """A deleted stage folder, a deleted run table and an altered table are rebuilt by
    reproduce-all (Snakemake alone would say "Nothing to be done", its issue 1978), only their
    jobs and those downstream rerun, and the results are byte for byte a clean run's."""
    out = tmp_path / "results"
    args = ["reproduce-all", "--configfile", "config/small.yaml", str(isolated_config),
            "--config", f"results={out}", "-c2"]  # fmt: skip
    res = run(*args)
    assert res.returncode == 0, res.stderr[-3000:]
    clean = _files(out)
    shutil.rmtree(out / "example" / "staircase")
    (out / "sim" / "runs" / "sine_dsm-20ms.parquet").unlink()
    with (out / "analytic" / "table1.csv").open("a") as fh:
        fh.write("0,0,0\n")
    plan = run(*args, "-n", *LIST_JOBS)
    assert plan.returncode == 0, plan.stderr[-3000:]
    rules = re.findall(r"^rule (\w+):", plan.stdout, flags=re.M)
    assert sorted(rules) == sorted(
        ["simulate_dataset", "analyse", "analyse", "analytic_table1", "overview", "report", "check"]
    ), plan.stdout[-3000:]
    res = run(*args)
    assert res.returncode == 0, res.stderr[-3000:]
    assert _files(out) == clean
    assert "Nothing to be done" in run(*args, "-n").stdout


def test_stray_files_in_raw_stop_nothing_and_a_bad_named_file_fails_its_dataset(tmp_path):
    """A dangling link, a pipe, a Latin-1 file name and office droppings that no run names are
    ignored (the DAG builds, the digest does not change, `spa validate` lists them); a named
    run file that is a pipe is an error of its dataset alone, never opened."""
    import os

    from spa.pipeline.provenance import dataset_digest

    raw = tmp_path / "raw"
    for name in ["example", "piped"]:
        shutil.copytree(ROOT / "raw" / "example", raw / name)
    (raw / "piped" / "dataset.yaml").write_text(
        (raw / "example" / "dataset.yaml").read_text().replace("name: example", "name: piped")
    )
    folder = raw / "example"
    before = dataset_digest(folder)
    (folder / "dangling").symlink_to(tmp_path / "nowhere")
    os.mkfifo(folder / "pipe")
    (folder / os.fsdecode(b"r\xfcn.csv")).write_text("x")
    for junk in [".DS_Store", "Thumbs.db", "~$notes.xlsx"]:
        (folder / junk).write_text("x")
    assert dataset_digest(folder) == before
    (raw / "piped" / "pulse.csv").unlink()
    os.mkfifo(raw / "piped" / "pulse.csv")
    (raw / "stray").mkdir()  # no dataset.yaml: not a dataset
    (raw / "stray" / "a.csv").write_text("x")
    shutil.copytree(ROOT / "raw" / "example", raw / os.fsdecode(b"Pr\xfcf"))  # Latin-1 name

    val = subprocess.run([sys.executable, "-m", "spa", "validate", str(folder)],
                         capture_output=True, text=True, timeout=120)  # fmt: skip
    assert val.returncode == 0, val.stdout
    assert "3 file(s) of the folder that no run names are ignored" in val.stdout
    assert "Thumbs.db" not in val.stdout and ".DS_Store" not in val.stdout
    out = tmp_path / "results"
    targets = [f"{out}/{d}/runs" for d in ["example", "piped"]]
    args = [*targets, "--configfile", "config/small.yaml", "--config", f"results={out}",
            f"datasets={{'raw_dir': '{raw}'}}", "-c1", "--keep-going"]  # fmt: skip
    res = run(*args)
    text = res.stdout + res.stderr
    assert (out / "example" / "runs" / "pulse.parquet").is_file(), text[-3000:]
    assert "Pr\\xfcf: skipped: a dataset's folder name must be UTF-8 text" in text
    status = json.loads((out / "piped" / "status" / "runs.json").read_text())
    assert "'pulse.csv' is not a regular file" in " ".join(status["errors"])
