import os
import sys
from pathlib import Path

import pytest
from hypothesis import settings

# Make tests/reference.py importable as `reference`.
sys.path.insert(0, str(Path(__file__).parent))

# CI explores the same examples on every run (a red CI must be reproducible); locally,
# hypothesis keeps exploring new ones.
settings.register_profile("ci", derandomize=True, print_blob=True)
if os.environ.get("CI"):
    settings.load_profile("ci")


# --- The HTML report (tests/test_report.py, tests/test_report_browser.py) -------------------

ROOT = Path(__file__).resolve().parents[1]

# A tiny results folder laid out like reproduce-all's: dataset "sim" has every optional output
# (Table 3, Figs. 6-9, sine and chirp tables), dataset "a<b&c" only the required ones, and
# HTML special characters in its name, a validation figure's name and a table cell.
FAKE_DATASETS = ["sim", "a<b&c"]
FAKE_NASTY = "<script>alert(\"x\")</script> & 'y'"


def _fake_params(fallback: str | None) -> dict:
    units = {"c1": "s*bar^-0.5", "k2": "bar", "tau2": "s", "t_on": "s", "t_off": "s"}
    nominal = {"c1": 0.533, "k2": 0.837, "tau2": 0.826, "t_on": 0.003, "t_off": 0.010}
    params = {
        name: {
            "value": value * 1.0012345,
            "lo": value * 0.98,
            "hi": value * 1.02,
            "unit": units[name],
            "runs": ["pulse"],
            "method": f"fit of {name} & friends",
            "fallback": fallback if name == "t_off" else None,
        }
        for name, value in nominal.items()
    }
    params["fits"] = {"charge": {"r2": 0.96247}, "discharge": {"r2": 0.98534}}
    return params


@pytest.fixture(scope="session")
def fake_results(tmp_path_factory):
    """A fabricated run: ``.root`` (results folder), ``.datasets``, ``.pngs`` and ``.tables``
    (the files the report must show), ``.nasty`` (the table cell full of HTML specials)."""
    from types import SimpleNamespace

    import pandas as pd
    import yaml
    from matplotlib.figure import Figure

    from spa.io import write_csv
    from spa.plots.save import save_figure

    root = tmp_path_factory.mktemp("fake_results")
    pngs: list[Path] = []
    tables: list[Path] = []

    def png(path: Path) -> None:
        fig = Figure(figsize=(1.2, 0.6))
        fig.set_facecolor((len(pngs) / 40, 0.5, 0.5))  # a different image in every file
        save_figure(fig, path, dpi=40, min_width=0)
        pngs.append(path)

    def csv(path: Path, df: pd.DataFrame) -> None:
        write_csv(df, path)
        tables.append(path)

    an = root / "analytic"
    csv(an / "table1.csv", pd.DataFrame({"modulator": ["pwm"], "dead_zone": [0.06913708487]}))
    csv(
        an / "table2.csv",
        pd.DataFrame(
            {
                "modulator": ["pwm", "iipfm"],
                "J_min": [5.405415736, 1.8253],
                "unit": ["Hz", "ms"],
                "paper_J_min": [10.5, 4.8],
                "analytic_optimum": [None, 19.3153286],
            }
        ),
    )
    for name in ("fig4", "fig5"):
        png(an / f"{name}.png")
        write_csv(pd.DataFrame({"x": [1.0]}), an / f"{name}.csv")  # beside the figure: not shown

    for dataset, full in zip(FAKE_DATASETS, (True, False), strict=True):
        d = root / dataset
        (d / "identification").mkdir(parents=True)
        params = _fake_params(None if full else "no pulse run <none>")
        (d / "identification" / "params.yaml").write_text(yaml.safe_dump(params, sort_keys=False))
        tables.append(d / "identification" / "params.yaml")
        for name in ("fig2a", "fig2b", "fig2c", "laws"):
            png(d / "identification" / f"{name}.png")
        if full:  # the tuning stage's outputs (optional in the report)
            tune = d / "tuning"
            tune.mkdir()
            (tune / "recommendation.yaml").write_text(
                yaml.safe_dump(
                    {
                        "sentence": "Use IIPFM with t_l = 19.5 ms and G = 1.154 <best>.",
                        "recommended": {  # as spa.tuning.valve writes it
                            "modulator": "iipfm",
                            "description": "IIPFM, t_l = 19.5 ms, G = 1.154",
                            "setting": {"type": "iipfm", "t_l": 0.0195, "gain": 1.154},
                            "J": 3.61,
                            "J_exact": 3.58,
                        },
                    }
                )
            )
            csv(tune / "table2.csv", pd.DataFrame({"modulator": ["iipfm"], "J_min": [3.61]}))
            csv(tune / "table1.csv", pd.DataFrame({"modulator": ["iipfm"], "dead_zone": [0.1]}))
            for name in ("fig4", "fig5"):
                png(tune / f"{name}.png")
        fit = pd.DataFrame(
            {
                "run": ["charge", FAKE_NASTY],
                "kind": ["charge", "pulse"],
                "fit_percent": [97.45077085, 12.0],
                "n": [5000, 20000],
            }
        )
        csv(d / "validation" / "fit.csv", fit)
        kinds = ["charge", "pulse"] if full else ["odd<kind>"]
        for kind in kinds:
            png(d / "validation" / "figures" / f"{kind}.png")
        if not full:
            continue
        csv(
            d / "staircase" / "table3.csv",
            pd.DataFrame(
                {
                    "run": ["staircase_pwm-20Hz"],
                    "mse": [0.007952038316],
                    "fit": [73.56569481],
                    "paper_mse": [0.0073],
                    "paper_fit": [75.23],
                }
            ),
        )
        for name in ("levels", "time_constants"):  # long: mentioned, not shown
            write_csv(pd.DataFrame({"xi": [0.1, 0.2]}), d / "staircase" / f"{name}.csv")
        for name in ("fig6", "fig7a", "fig7b"):
            png(d / "staircase" / f"{name}.png")
        csv(d / "sine" / "linearity.csv", pd.DataFrame({"run": ["sine_pwm"], "rms": [0.0804]}))
        png(d / "sine" / "fig8.png")
        csv(d / "chirp" / "bicoherence.csv", pd.DataFrame({"run": ["chirp_pwm"], "mean": [0.05]}))
        png(d / "chirp" / "fig9.png")
        cl = d / "closed_loop"  # the closed_loop stage's outputs (optional)
        cl.mkdir()
        (cl / "controllers.yaml").write_text(
            yaml.safe_dump({"sentence": "Closed loop: use IIPFM with Kp = 4.1.", "setting": None})
        )
        csv(cl / "table.csv", pd.DataFrame({"modulator": ["iipfm-20ms"], "max": [0.75]}))
        csv(cl / "runs.csv", pd.DataFrame({"run": ["closed_loop_pwm"], "fit": [96.9]}))
        csv(cl / "robust.csv", pd.DataFrame({"modulator": ["iipfm-20ms"], "dip": [0.009]}))
        for name in ("fig10", "fig11"):
            png(cl / f"{name}.png")
    return SimpleNamespace(
        root=root, datasets=list(FAKE_DATASETS), pngs=pngs, tables=tables, nasty=FAKE_NASTY
    )


def isolated_raw(base: Path) -> Path:
    """A config file pointing datasets.raw_dir at a copy of raw/example under ``base``.

    Workflow tests never read the repository's own raw/: a user's datasets there must not
    change what the tests see (or make them slow).
    """
    import shutil

    raw = base / "raw"
    if not (raw / "example").exists():
        shutil.copytree(ROOT / "raw" / "example", raw / "example")
    cfg = base / "isolated.yaml"
    cfg.write_text(f"datasets:\n  raw_dir: {raw}\n  include: []\n  exclude: []\n")
    return cfg


@pytest.fixture(scope="session")
def isolated_config(tmp_path_factory) -> Path:
    """:func:`isolated_raw` once a session."""
    return isolated_raw(tmp_path_factory.mktemp("isolated"))


@pytest.fixture(scope="session")
def small_run(tmp_path_factory, isolated_config):
    """Results folder of `snakemake reproduce-all` with config/small.yaml, run once a session."""
    import subprocess

    out = tmp_path_factory.mktemp("small_run")
    res = subprocess.run(
        [
            sys.executable,
            "-m",
            "snakemake",
            "reproduce-all",
            "--configfile",
            "config/small.yaml",
            str(isolated_config),
            "--config",
            f"results={out}",
            "-c2",
        ],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=900,
    )
    assert res.returncode == 0, res.stderr[-3000:]
    # what the console showed, for the test of the profile's quiet console (test_workflow)
    out.with_name(f"{out.name}.console.txt").write_text(res.stdout + res.stderr)
    return out


# --- The documentation's commands (tests/test_doc_commands.py, tests/test_getting_started.py)

#: What a scratch source folder links from this checkout: the workflow's files, the docs and
#: benchmarks (commands the pages show read them).
SOURCE_LINKS = ("Snakefile", "workflow", "config", "profiles", "docs", "benchmarks")


def scratch_source(folder: Path, links: tuple[str, ...] = SOURCE_LINKS) -> Path:
    """A folder laid out like the source folder: ``links`` linked from this checkout and a copy
    of ``raw/example`` (timestamps kept), nothing else."""
    import shutil

    folder.mkdir(parents=True)
    for name in links:
        (folder / name).symlink_to(ROOT / name)
    shutil.copytree(ROOT / "raw" / "example", folder / "raw" / "example")
    return folder


@pytest.fixture(scope="session")
def small_source(tmp_path_factory) -> Path:
    """A scratch source folder where ``snakemake reproduce-all --configfile config/small.yaml``
    ran, once a session, through the environment's commands."""
    import subprocess

    work = scratch_source(tmp_path_factory.mktemp("small_source") / "work")
    env = dict(os.environ, SPA_PROGRESS="0", MPLBACKEND="Agg")
    env["PATH"] = os.pathsep.join((str(Path(sys.executable).parent), env.get("PATH", "")))
    env["PYTHONPATH"] = os.pathsep.join(p for p in (str(ROOT), env.get("PYTHONPATH", "")) if p)
    res = subprocess.run(
        ["snakemake", "reproduce-all", "--configfile", "config/small.yaml"],
        cwd=work, env=env, capture_output=True, text=True, timeout=1800,
    )  # fmt: skip
    assert res.returncode == 0, res.stdout[-4000:] + res.stderr[-4000:]
    return work
