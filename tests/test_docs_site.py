"""The documentation site (docs/, `make docs`): it builds offline with warnings as errors, and
its API reference has a page for every public name of spa.

The build is the CI's: `make test` runs this file. Sphinx writes the API pages' sources into
docs/api/ (ignored by git) and the site into a temporary folder.
"""

from __future__ import annotations

import importlib
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"

pytest.importorskip("sphinx")
pytest.importorskip("numpydoc")
pytest.importorskip("myst_parser")

#: Public packages: each one's ``__all__`` must be in the reference.
PACKAGES = ["spa", "spa.closedloop", "spa.datasets", "spa.identification", "spa.model.modulators",
            "spa.openloop", "spa.report", "spa.synthetic", "spa.tuning"]  # fmt: skip


@pytest.fixture(scope="module")
def site(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("site")
    res = subprocess.run(
        [sys.executable, "-m", "sphinx", "-b", "html", "-W", "--keep-going", "-j", "auto", "-q",
         "-d", str(out / "doctrees"), str(DOCS), str(out / "html")],
        capture_output=True, text=True, cwd=ROOT, timeout=1200,
    )  # fmt: skip
    assert res.returncode == 0, (res.stdout + res.stderr)[-5000:]
    assert res.stderr.strip() == "", res.stderr[-5000:]  # no warning at all
    return out / "html"


def test_the_site_has_the_guide_the_model_and_the_benchmarks(site):
    for page in ("index", "guide", "model", "benchmarks", "api/index"):
        assert (site / f"{page}.html").is_file(), page
    guide = (site / "guide.html").read_text(encoding="utf-8")
    assert "Dependencies, and why" in guide and "spa tune" in guide
    assert "api/index.html" in (site / "index.html").read_text(encoding="utf-8")


def test_every_public_name_has_its_page(site):
    sys.path.insert(0, str(DOCS))
    try:
        from _api import homes, public_modules
    finally:
        sys.path.remove(str(DOCS))
    modules = public_modules()
    assert {m.__name__ for m in modules} >= set(PACKAGES)
    home = homes(modules)
    for package in PACKAGES:
        names = importlib.import_module(package).__all__
        assert names, package
        page = (site / "api" / f"{package}.html").read_text(encoding="utf-8")
        for name in names:
            target = site / "api" / "generated" / f"{home[package, name]}.{name}.html"
            assert target.is_file(), (package, name, target)
            assert f"{home[package, name]}.{name}.html" in page, (package, name)
    tune = (site / "api" / "generated" / "spa.tuning.stage.tune.html").read_text(encoding="utf-8")
    assert "Parameters" in tune and "Returns" in tune and "TuningResult" in tune
    params = site / "api" / "generated" / "spa.model.params.ValveParams.html"
    assert "c1" in params.read_text(encoding="utf-8")
    assert (site / "api" / "generated" / "spa.io.dump_yaml.html").is_file()
