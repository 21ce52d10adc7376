"""The registry of outputs (spa.pipeline.outputs) and the choice of datasets
(spa.pipeline.config)."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest

from spa.pipeline.config import ConfigError, discover_datasets, figure_datasets
from spa.pipeline.outputs import (
    STAGES,
    all_targets,
    dataset_folder,
    figure_paths,
    get_stage,
    log_path,
    section_outputs,
    stage_outputs,
    wildcard_choice,
)
from spa.pipeline.stage_types import FIGURE, FIGURES, RUNS, VECTOR, Output

ROOT = Path(__file__).resolve().parents[1]


def test_every_output_and_log_has_one_path():
    paths = all_targets("res", ["d1", "d2"])
    assert len(paths) == len(set(paths))
    logs = [log_path(rule, "res", "d1") for s in STAGES for rule in s.logs]
    assert len(logs) == len(set(logs))
    assert all(p.startswith("res/logs/") for p in logs)
    keys = [(s.name, o.key) for s in STAGES for o in s.outputs]
    assert len(keys) == len(set(keys))


def test_paths_are_relative_and_inside_their_folder():
    for stage in STAGES:
        for out in stage.outputs:
            assert not Path(out.path).is_absolute() and ".." not in Path(out.path).parts, out
            if stage.section == "analytic":
                assert out.path.startswith("analytic/"), out


def test_stage_outputs_for_a_rule_and_for_one_dataset():
    assert stage_outputs("identify", "results")["params"] == (
        "results/{dataset}/identification/params.yaml"
    )
    assert stage_outputs("validate_model", "r", "sim") == {
        "fit": "r/sim/validation/fit.csv",
        "figures": "r/sim/validation/figures",
        "status": "r/sim/status/validate_model.json",
    }
    marked = stage_outputs("runs", "r", mark_directory=lambda p: ("dir", p))
    assert marked == {"runs": ("dir", "r/{dataset}/runs"), "status": "r/{dataset}/status/runs.json"}
    assert stage_outputs("analytic_fig4", "r", "ignored") == {
        "figure": "r/analytic/fig4.png",
        "figure_svg": "r/analytic/fig4.svg",
        "data": "r/analytic/fig4.csv",
    }
    with pytest.raises(KeyError, match=r"'tables'.*'analytic_table1'"):
        stage_outputs("tables", "r")


def test_without_figures_a_stage_keeps_its_tables_and_the_figures_data():
    for stage in STAGES:
        every = stage_outputs(stage.name, "res", "d1")
        kept = stage_outputs(stage.name, "res", "d1", figures=False)
        kinds = {o.key: o.kind for o in stage.outputs}
        assert kept == {k: p for k, p in every.items() if kinds[k] not in (FIGURE, VECTOR, FIGURES)}
    assert "fig2a_csv" in stage_outputs("identify", "res", "d1", figures=False)
    # the targets: figures of the named datasets only; figure_paths lists what is left out
    both = all_targets("res", ["a", "b"])
    some = all_targets("res", ["a", "b"], figures=["b"])
    stages = [s.name for s in STAGES if s.per_dataset]
    assert sorted(set(both) - set(some)) == sorted(figure_paths(stages, "res", "a"))
    assert "res/a/identification/fig2a.png" in figure_paths(["identify"], "res", "a")
    assert "res/a/validation/figures" in figure_paths(["validate_model"], "res", "a")


def test_the_dataset_folder_of_a_job_is_found_from_its_outputs():
    outputs = stage_outputs("tune", "/x/res", "d1")
    assert dataset_folder("tune", outputs) == Path("/x/res/d1")
    assert dataset_folder("runs", {"runs": "r/d 2/runs"}) == Path("r/d 2")
    with pytest.raises(ValueError, match="no output"):
        dataset_folder("tune", {"table2": "elsewhere.csv"})
    with pytest.raises(ValueError, match="table1"):
        dataset_folder("analytic_table1", {"table": "res/analytic/table1.csv"})


def test_figure_datasets_all_none_or_a_list_of_the_runs_datasets():
    names = ["sim", "a", "b"]
    assert figure_datasets({}, names) == names == figure_datasets({"figures": "all"}, names)
    assert figure_datasets({"figures": "none"}, names) == []
    assert figure_datasets({"figures": ["b", "sim"]}, names) == ["sim", "b"]
    with pytest.raises(ConfigError, match=r"names \['c'\].*'sim', 'a', 'b'"):
        figure_datasets({"figures": ["a", "c"]}, names)


def test_folders_are_the_runs_and_figure_folders():
    folders = {o.path for s in STAGES for o in s.outputs if o.directory}
    assert folders == {"runs", "validation/figures"}
    assert {o.kind for s in STAGES for o in s.outputs if o.directory} == {RUNS, FIGURES}


def test_logs_as_the_workflow_writes_them():
    assert log_path("ingest_dataset", "r", "broken") == "r/logs/broken/ingest.log"
    assert log_path("simulate_dataset", "r") == "r/logs/{dataset}/simulate.log"
    assert log_path("analytic_fig5", "r") == "r/logs/analytic/fig5.log"
    assert log_path("report", "r") == "r/logs/report.log"
    assert log_path("tune", "r", "sim") == "r/logs/sim/tune.log"
    with pytest.raises(KeyError, match="'frobnicate'"):
        log_path("frobnicate", "r")


def test_report_sections_in_pipeline_order_key_item_first():
    titles = [o.title for o in section_outputs("dataset") if o.shown]
    assert titles[0].startswith("Table 3")
    assert titles.index("Identified valve parameters") < titles.index("Fig. 2a: charging")
    assert titles.index("Model validation: FIT per run") < titles.index(
        "Fig. 6: staircase responses"
    )
    assert titles.index("Fig. 9: bicoherence") < titles.index("Fig. 10: closed-loop staircase")
    assert titles[-1] == "Closed loop: recorded runs against the model"
    assert [o.path for o in section_outputs("dataset") if o.mention] == [
        "staircase/levels.csv",
        "staircase/time_constants.csv",
    ]
    assert get_stage("report").section is None


def test_an_output_shown_in_the_report_needs_a_caption_and_a_known_kind():
    with pytest.raises(ValueError, match="'fig' is shown in the report but has no caption"):
        Output("fig", "x/fig.png", "figure", "Fig. X")
    with pytest.raises(ValueError, match="kind 'png' is not one of"):
        Output("fig", "x/fig.png", "png")


def test_wildcard_choice_matches_exactly_the_names():
    pattern = wildcard_choice(["sim", "a.b"])
    assert [n for n in ["sim", "a.b", "axb", "sim2"] if re.fullmatch(pattern, n)] == ["sim", "a.b"]
    assert re.fullmatch(wildcard_choice([]), "") is None


def test_the_registry_imports_without_pandas_or_matplotlib():
    code = (
        "import sys, spa.pipeline.outputs, spa.pipeline.config\n"
        "print(sorted({'pandas', 'matplotlib'} & set(sys.modules)))"
    )
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert res.stdout.strip() == "[]"


# --- spa.pipeline.config.discover_datasets ------------------------------------------------


def _raw(tmp_path: Path, *names: str) -> Path:
    raw = tmp_path / "raw"
    for name in names:
        (raw / name).mkdir(parents=True)
        (raw / name / "dataset.yaml").write_text(f"name: {name}\n")
    (raw / "no_spec").mkdir(parents=True)
    return raw


def _config(raw: Path, include=(), exclude=(), simulated=("sim",)) -> dict:
    return {
        "datasets": {"raw_dir": str(raw), "include": list(include), "exclude": list(exclude)},
        "simulated": {name: {} for name in simulated},
    }


def test_discovery_skips_hidden_folders_and_folders_without_a_spec(tmp_path):
    raw = _raw(tmp_path, "b", "a", ".hidden", ".git")
    assert discover_datasets(_config(raw)) == (["sim"], ["a", "b"])
    assert discover_datasets(_config(tmp_path / "missing")) == (["sim"], [])


def test_include_and_exclude_choose_the_bench_datasets(tmp_path):
    raw = _raw(tmp_path, "a", "b", "c")
    assert discover_datasets(_config(raw, include=["c", "a"])) == (["sim"], ["c", "a"])
    assert discover_datasets(_config(raw, exclude=["b"])) == (["sim"], ["a", "c"])
    with pytest.raises(ConfigError, match=r"include names \['x'\].*found: \['a', 'b', 'c'\]"):
        discover_datasets(_config(raw, include=["a", "x"]))


def test_a_name_both_simulated_and_bench_is_refused(tmp_path):
    raw = _raw(tmp_path, "sim", "a")
    with pytest.raises(ConfigError, match=r"\['sim'\] are both simulated.*datasets.exclude"):
        discover_datasets(_config(raw))
    assert discover_datasets(_config(raw, exclude=["sim"])) == (["sim"], ["a"])


def _schema():
    import yaml

    return yaml.safe_load((ROOT / "workflow" / "schemas" / "config.schema.yaml").read_text())


def _full_config():
    import yaml

    return yaml.safe_load((ROOT / "config" / "config.yaml").read_text())


def test_config_relations_the_schema_cannot_state_are_checked():
    from spa.pipeline.config import config_errors

    cfg = _full_config()
    assert config_errors(cfg, _schema()) == []
    cfg["analytic"]["sweeps"]["pwm"].update(start=80.0, stop=1.0)
    cfg["simulated"]["sim"]["controller_dt"] = 0.003
    cfg["simulated"]["sim"]["modulators"][0] = {"type": "pwm", "f_w": 900.0}
    errors = "\n".join(config_errors(cfg, _schema()))
    assert "analytic.sweeps.pwm: start 80.0 must be below stop 1.0" in errors
    assert "simulated.sim.sensor.fs: the logging period 1/fs = 0.001 s is not a whole" in errors
    assert "simulated.sim.modulators[0]: pwm: f_w = 900 Hz is above half" in errors


def test_runaway_grids_and_empty_ranges_are_one_config_error_each():
    """A sweep step of 1e-7 (790 M points), n_xi of 1e9, a gain sweep too large for the
    IIPFM grid, a simulated run of 1e9 samples and a range [50, 5] are refused by key."""
    from spa.pipeline.config import config_errors, grid_errors

    cfg = _full_config()
    assert grid_errors(cfg) == []
    cfg["analytic"]["n_xi"] = 10**9
    assert config_errors(cfg, _schema()) == [
        "analytic.n_xi: 1000000000 is greater than the maximum of 100000"
    ]
    cfg = _full_config()
    cfg["analytic"]["sweeps"]["pwm"]["step"] = 1e-7
    cfg["analytic"]["n_xi"] = 30_000
    cfg["tuning"]["ranges"] = {"pwm": [50.0, 5.0], "dsm": [0.01, 0.05]}
    cfg["tuning"]["gain_sweep"] = {"start": 1.0, "stop": 1.3, "step": 0.001}
    cfg["experiments"]["chirp"]["duration"] = 1e6
    errors = config_errors(cfg, _schema())
    assert len(errors) == 8, errors  # n_xi x grid: ipfm, iipfm, dsm and lpwm
    assert errors[0].startswith("analytic.sweeps.pwm.step: 1e-07 gives 790,000,001 points")
    assert errors[1].startswith("analytic.n_xi: 30,000 x the 988 points of analytic.sweeps.ipfm")
    assert "tuning.gain_sweep: 301 gains x 988 t_l x n_xi 30,000" in errors[5]
    assert errors[6] == (
        "tuning.ranges.pwm: [50.0, 5.0]: the lower bound 50.0 is above the upper bound 5.0"
    )
    assert "experiments.chirp: a run of 1,000,000 s is 1,000,000,000 samples" in errors[7]


def test_numbers_given_as_strings_on_the_command_line_are_numbers():
    """`--config 'analytic={n_xi: 30}'` hands Snakemake's config '30', a string."""
    from spa.pipeline.config import coerce_numbers, config_errors

    cfg = _full_config()
    cfg["analytic"]["n_xi"] = "30"
    cfg["simulated"]["sim"]["modulators"][0] = {"type": "pwm", "f_w": "50"}
    cfg["seed"] = "abc"
    coerce_numbers(cfg, _schema())
    assert cfg["analytic"]["n_xi"] == 30
    assert cfg["simulated"]["sim"]["modulators"][0]["f_w"] == 50
    assert config_errors(cfg, _schema()) == ["seed: 'abc' is not of type 'integer'"]
