"""The install page's notebook route, ``python -m pip install .``, gives the package and the
``spa`` command without the pipeline's workflow files; the install page's source section
comes from ``[project.urls]`` and never shows a placeholder address."""

from __future__ import annotations

import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
sys.path.append(str(ROOT / "docs"))

from _source import icon_links, repository_url, source_section  # noqa: E402


@pytest.fixture(scope="module")
def wheel(tmp_path_factory) -> Path:
    """The wheel ``pip install .`` builds from this source folder (offline: no build isolation,
    no dependencies fetched)."""
    out = tmp_path_factory.mktemp("wheel")
    res = subprocess.run(
        [sys.executable, "-m", "pip", "wheel", "--quiet", "--no-deps", "--no-build-isolation",
         "--disable-pip-version-check", "-w", str(out), str(ROOT)],
        capture_output=True, text=True, timeout=600,
    )  # fmt: skip
    assert res.returncode == 0, res.stderr[-3000:]
    (found,) = out.glob("spa-*.whl")
    return found


def test_the_wheel_holds_the_package_and_the_command_not_the_workflow(wheel):
    names = zipfile.ZipFile(wheel).namelist()
    assert "spa/__init__.py" in names
    assert "spa/synthetic/physical_plant.c" in names  # package data the C checks compile
    entry_points = next(n for n in names if n.endswith("entry_points.txt"))
    assert "spa = spa.cli:main" in zipfile.ZipFile(wheel).read(entry_points).decode()
    for workflow_file in ("Snakefile", "workflow/", "config/", "profiles/"):
        assert not any(n.startswith(workflow_file) for n in names), workflow_file


def test_the_installed_package_runs_in_a_fresh_interpreter_away_from_the_source(wheel, tmp_path):
    target = tmp_path / "site"
    res = subprocess.run(
        [sys.executable, "-m", "pip", "install", "--quiet", "--no-deps", "--no-index",
         "--disable-pip-version-check", "--target", str(target), str(wheel)],
        capture_output=True, text=True, timeout=600,
    )  # fmt: skip
    assert res.returncode == 0, res.stderr[-3000:]
    code = (
        "import numpy as np, spa, sys; "
        "u = spa.modulate('pwm', np.full(2000, 0.5), 1e-3, f_w=20.0); "
        "p = spa.simulate(u, 1e-3, spa.ValveParams()); "
        "print(spa.__file__); print(round(float(p[-100:].mean()), 2))"
    )
    env = {"PYTHONPATH": str(target), "PATH": "/usr/bin:/bin", "HOME": str(tmp_path)}
    work = tmp_path / "notebook"
    work.mkdir()
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=work,
                         env=env, timeout=600)  # fmt: skip
    assert res.returncode == 0, res.stderr[-3000:]
    where, pressure = res.stdout.split()
    assert Path(where).is_relative_to(target)  # the installed copy, not this checkout
    assert 0.0 < float(pressure) < spa_supply()
    res = subprocess.run([sys.executable, "-m", "spa", "--version"], capture_output=True,
                         text=True, cwd=work, env=env, timeout=600)  # fmt: skip
    assert res.returncode == 0 and res.stdout.startswith("spa "), res.stderr[-2000:]


def spa_supply() -> float:
    import spa

    return spa.ValveParams().k2


def test_the_source_section_uses_the_projects_address_or_says_how_to_get_the_source(tmp_path):
    with_url = tmp_path / "with.toml"
    with_url.write_text(
        '[project]\nname = "spa"\n[project.urls]\nRepository = "https://example.org/lab/spa"\n'
    )
    assert repository_url(with_url) == "https://example.org/lab/spa"
    text = source_section(repository_url(with_url))
    assert "git clone https://example.org/lab/spa spa-pipeline" in text
    assert icon_links("https://example.org/lab/spa")[0]["url"] == "https://example.org/lab/spa"
    without = tmp_path / "without.toml"
    without.write_text('[project]\nname = "spa"\n')
    text = source_section(repository_url(without))
    assert "<" not in text and "git clone" in text and "not** named `spa`" in text
    assert icon_links(None) == []
    # this repository: whatever pyproject.toml says is what the page shows
    ours = repository_url(ROOT / "pyproject.toml")
    assert (ours in source_section(ours)) if ours else ("[project.urls]" in source_section(ours))
