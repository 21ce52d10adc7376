"""The command line (spa.cli): --version, --help, `spa identify`; the guard against a clone
folder named `spa` (spa._guard); progress bars only on a terminal (spa._progress)."""

from __future__ import annotations

import io
import json
import shutil
import subprocess
import sys
from importlib.metadata import version
from pathlib import Path

import pytest

from spa.cli import _parser, main

ROOT = Path(__file__).resolve().parents[1]


def run_cli(*args: str, cwd: Path = ROOT) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "spa", *args], capture_output=True, text=True, cwd=cwd, timeout=300
    )


def test_version_is_the_installed_package_version():
    res = run_cli("--version")
    assert res.returncode == 0
    assert res.stdout.strip() == f"spa {version('spa')}"


def test_help_lists_every_command_on_one_line():
    commands = list(_parser()._subparsers._group_actions[0].choices)
    assert {"validate", "ingest", "example", "identify", "tune"} <= set(commands)
    res = subprocess.run(
        [sys.executable, "-m", "spa", "--help"],
        capture_output=True,
        text=True,
        cwd=ROOT,
        env={"COLUMNS": "80", "PATH": ""},
    )
    assert res.returncode == 0
    lines = res.stdout.splitlines()
    for name in commands:
        (i,) = [k for k, line in enumerate(lines) if line.split()[:1] == [name]]
        assert len(lines[i].split()) > 3, lines[i]  # a description on the same line
        assert not lines[i + 1].startswith(" " * 10), f"{name}'s help wraps: {lines[i + 1]!r}"
    assert "--version" in res.stdout


@pytest.fixture(scope="module")
def example_copy(tmp_path_factory) -> Path:
    """A copy of raw/example (the command must not write next to it)."""
    dst = tmp_path_factory.mktemp("raw") / "example"
    shutil.copytree(ROOT / "raw" / "example", dst)
    return dst


def _listing(folder: Path) -> dict[str, int]:
    return {str(p.relative_to(folder)): p.stat().st_mtime_ns for p in folder.rglob("*")}


def test_identify_a_bench_dataset_prints_the_parameters_with_intervals(example_copy, capsys):
    from spa.synthetic import EXAMPLE_PARAMS

    before = _listing(example_copy)
    assert main(["identify", str(example_copy)]) == 0
    text = capsys.readouterr().out
    assert _listing(example_copy) == before  # nothing written in the dataset's folder
    lines = text.splitlines()
    assert lines[0] == f"{example_copy}: 5 run(s); 95 % intervals"
    assert lines[1].split() == ["parameter", "value", "95", "%", "lo", "95", "%", "hi", "unit",
                                "fallback"]  # fmt: skip
    truth = EXAMPLE_PARAMS.as_dict()
    for line, name in zip(lines[2:7], ("c1", "k2", "tau2", "t_on", "t_off"), strict=True):
        cells = line.split()
        assert cells[0] == name and cells[-1] == "no"
        value, lo, hi = map(float, cells[1:4])
        assert lo <= value <= hi and lo <= truth[name] <= hi, (name, cells, truth[name])
    assert lines[7].startswith("R² of the fits: charge")


def test_identify_json_is_what_params_yaml_holds(example_copy, tmp_path, capsys):
    from spa.datasets import ingest_dataset

    ingest_dataset(example_copy, tmp_path / "results" / "example" / "runs")
    assert main(["identify", str(tmp_path / "results" / "example"), "--json", "--seed", "3"]) == 0
    params = json.loads(capsys.readouterr().out)
    assert params["k2"]["unit"] == "bar" and params["k2"]["lo"] < params["k2"]["hi"]
    # the same runs folder given directly and the same seed: the same numbers
    assert main(["identify", str(tmp_path / "results" / "example" / "runs"), "--json",
                 "--seed", "3"]) == 0  # fmt: skip
    assert json.loads(capsys.readouterr().out) == params


def test_identify_names_what_is_wrong(tmp_path, capsys):
    assert main(["identify", str(tmp_path)]) == 1
    assert "expected a bench dataset folder (with dataset.yaml" in capsys.readouterr().out
    broken = tmp_path / "broken"
    shutil.copytree(ROOT / "raw" / "example", broken)
    spec = broken / "dataset.yaml"
    spec.write_text(spec.read_text().replace("name: example", "name: broken"))
    (broken / "charge.csv").unlink()
    assert main(["identify", str(broken)]) == 1
    out = capsys.readouterr().out
    assert "charge.csv" in out and "not identified: the dataset has errors" in out


def _shadowing_clone(tmp_path: Path) -> Path:
    """A parent folder holding a folder `spa` without __init__.py (a clone named spa)."""
    (tmp_path / "spa" / "spa").mkdir(parents=True)
    (tmp_path / "spa" / "README.md").write_text("a clone\n")
    return tmp_path


def test_cli_refuses_a_clone_folder_named_spa(tmp_path):
    res = run_cli("--version", cwd=_shadowing_clone(tmp_path))
    assert res.returncode == 2
    assert f"'import spa' found the folder {tmp_path / 'spa'}" in res.stderr
    assert "git clone <url> spa-pipeline" in res.stderr
    assert "Traceback" not in res.stderr


def test_workflow_from_the_parent_of_a_folder_named_spa_uses_the_package(tmp_path):
    """Snakemake puts the top-level Snakefile's folder first on sys.path, so the workflow
    imports the repository's spa package even from the parent of a folder named spa (the
    guard in common.smk stays for a setup where it would not)."""
    res = subprocess.run(
        [sys.executable, "-m", "snakemake", "-s", str(ROOT / "Snakefile"),
         "-d", str(ROOT), "-n", "--configfile", str(ROOT / "config" / "small.yaml"),
         "--config", f"results={tmp_path / 'results'}"],
        capture_output=True, text=True, cwd=_shadowing_clone(tmp_path), timeout=300,
    )  # fmt: skip
    assert res.returncode == 0, res.stderr[-2000:]
    assert "namespace package" not in res.stdout + res.stderr


def test_guard_passes_the_real_package_and_names_a_namespace():
    from types import ModuleType

    from spa._guard import ShadowedPackageError, check_package, shadowing_folders

    check_package()
    fake = ModuleType("spa")
    fake.__path__ = ["/somewhere/spa"]  # a namespace package has a path and no file
    assert shadowing_folders(fake) == ["/somewhere/spa"]
    with pytest.raises(ShadowedPackageError, match="/somewhere/spa"):
        check_package(fake)


class _Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_progress_bar_only_on_a_terminal(monkeypatch):
    from spa._progress import progress

    items = [1, 2, 3]
    monkeypatch.delenv("SPA_PROGRESS", raising=False)
    monkeypatch.setattr(sys, "stderr", io.StringIO())  # a log file or a pipe: nothing
    assert progress(items, "runs") is items
    term = _Terminal()
    monkeypatch.setattr(sys, "stderr", term)
    assert list(progress(items, "simulating sim")) == items
    assert "simulating sim:" in term.getvalue() and "/3 " in term.getvalue()  # a tqdm bar
    monkeypatch.setenv("SPA_PROGRESS", "0")  # turned off
    assert progress(items, "runs") is items


def test_no_progress_bar_in_a_workflow_job(monkeypatch):
    from snakemake.iocontainers import Snakemake

    from spa._progress import progress

    monkeypatch.delenv("SPA_PROGRESS", raising=False)
    monkeypatch.setattr(sys, "stderr", _Terminal())
    job = object.__new__(Snakemake)  # what a job's script finds as `snakemake`
    monkeypatch.setattr(sys.modules["__main__"], "snakemake", job, raising=False)
    items = [1, 2]
    assert progress(items, "runs") is items


def test_simulating_a_dataset_shows_a_bar_and_still_calls_back(tmp_path, monkeypatch):
    """The bar of spa.synthetic.generate_dataset does not replace its progress callback."""
    from spa.model.params import ValveParams
    from spa.synthetic import generate_dataset

    monkeypatch.delenv("SPA_PROGRESS", raising=False)
    term = _Terminal()
    monkeypatch.setattr(sys, "stderr", term)
    cfg = {"params": ValveParams().as_dict(), "controller_dt": 1e-3, "sensor": {"fs": 1000.0},
           "modulators": [{"type": "pwm", "f_w": 20.0}]}  # fmt: skip
    experiments = {"staircase": {"step": 0.5, "hold": 0.5}}
    lines: list[str] = []
    paths = generate_dataset("mini", cfg, experiments, 1, tmp_path / "runs", progress=lines.append)
    assert len(paths) == len(lines) >= 1
    assert "simulating mini:" in term.getvalue()


# ---- help texts and `spa tune`'s brief answer ---------------------------------------------


def _subparsers():
    return _parser()._subparsers._group_actions[0].choices


def test_help_counts_and_names_the_registered_modulators():
    from toy_modulator import Toy

    from spa.model.modulators import REGISTRY, get_kind, kinds, register

    def texts() -> tuple[str, str]:
        return _parser().format_help(), _subparsers()["tune"].format_help()

    top, tune = texts()
    assert len(kinds()) == 5 and "tune the five modulators" in top
    assert "four" not in top + tune
    for kind in kinds():
        assert get_kind(kind).name in " ".join(tune.split())
    register(Toy)
    try:
        top, tune = texts()
        assert "tune the six modulators" in top and "Toy" in tune
    finally:
        del REGISTRY["toy"]


def test_every_option_shows_its_default():
    from spa.cli import TAU_C
    from spa.closedloop.design import DEFAULT_TAU_C

    for name, sub in _subparsers().items():
        formatter = sub._get_formatter()
        for action in sub._actions:
            if not action.option_strings or action.nargs == 0 or action.required:
                continue  # positionals, flags and required options have no default
            text = formatter._expand_help(action)
            assert "default" in text, f"spa {name} {action.option_strings[0]}: {text!r}"
    assert TAU_C == DEFAULT_TAU_C
    tau = " ".join(_subparsers()["design-pi"].format_help().split())
    assert f"--tau-c TAU_C closed-loop time constant, s (default: {DEFAULT_TAU_C:g})" in tau
    example = " ".join(_subparsers()["example"].format_help().split())
    assert "noise seed (default: 2025)" in example


VALVE = ["--c1", "0.5", "--k2", "0.8", "--tau2", "0.8", "--t-on", "0.003", "--t-off", "0.01"]


@pytest.fixture(scope="module")
def tune_config(tmp_path_factory) -> Path:
    """Coarse grids; PWM's stops at 15 Hz, below its optimum, which so sits at the grid edge."""
    import yaml

    from spa.tuning import DEFAULT_SWEEPS

    sweeps = {k: {**g, "step": g["step"] * 5} for k, g in DEFAULT_SWEEPS.items()}
    sweeps["pwm"] = {"start": 5.0, "stop": 15.0, "step": 1.0}
    path = tmp_path_factory.mktemp("tune") / "config.yaml"
    path.write_text(yaml.safe_dump({"analytic": {"sweeps": sweeps, "n_xi": 40}}))
    return path


def test_tune_answers_in_a_few_lines_with_the_grid_edge_flags(tune_config, capsys):
    from spa.model.modulators import kinds

    assert main(["tune", *VALVE, "--config", str(tune_config), "--json"]) == 0
    table2 = {r["modulator"]: r for r in json.loads(capsys.readouterr().out)["table2"]}
    assert main(["tune", *VALVE, "--config", str(tune_config)]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert len(lines) <= len(kinds()) + 7, "\n".join(lines)
    header = lines[1].split()
    assert header == ["modulator", "optimum", "J", "J_exact", "chattering", "at_grid_edge"]
    rows = {line.split()[0]: line.split() for line in lines[2 : 2 + len(kinds())]}
    assert set(rows) == set(kinds())
    assert table2["pwm"]["optimum_at_grid_edge"] and rows["pwm"][1] == "pwm-15Hz"
    for kind, row in rows.items():
        flags = [
            c.removesuffix("_at_grid_edge") for c in table2[kind] if c.endswith("_at_grid_edge")
        ]
        shown = [f for f in flags if table2[kind][f"{f}_at_grid_edge"]]
        assert row[-1] == (", ".join(shown) or "-").split()[-1], (kind, row)
        assert float(row[2]) == pytest.approx(table2[kind]["J_min"], rel=1e-3)
        assert 0.0 <= float(row[4]) < 0.8  # chattering, bar: below k2
    assert any(line.startswith("at_grid_edge:") for line in lines)
    assert lines[-2].startswith("Use ")


def test_tune_yaml_is_the_full_data(tune_config, capsys):
    import yaml

    from spa.tuning import tune_with_config
    from spa.tuning.valve import _plain

    assert main(["tune", *VALVE, "--config", str(tune_config), "--yaml"]) == 0
    text = capsys.readouterr().out
    assert main(["tune", *VALVE, "--config", str(tune_config), "--json"]) == 0
    as_json = json.loads(capsys.readouterr().out)
    data = yaml.safe_load(text)
    assert data == as_json
    given = dict(zip(("c1", "k2", "tau2", "t_on", "t_off"), map(float, VALVE[1::2]), strict=True))
    result = tune_with_config(given, yaml.safe_load(tune_config.read_text()))
    assert data["recommendation"] == _plain(result.recommendation)
    assert len(data["table2"]) == len(result.table2)
    assert set(data["table2"][0]) == set(result.table2.columns)
    assert "*id" not in text and "&id" not in text
    assert main(["tune", *VALVE, "--yaml", "--json"]) == 2  # one or the other
