"""The documentation site (docs/, `make docs`): it builds offline with warnings as errors; its
four parts are there and linked from the front page; the tutorial and the figures page ran at
build; no page names an issue number; and the API reference lists exactly the public names.

The build is the CI's: `make test` runs this file. Sphinx writes the API and CLI pages'
sources into docs/reference/ (ignored by git) and the site into a temporary folder.
"""

from __future__ import annotations

import importlib
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
API = DOCS / "reference" / "api.rst"

#: Public packages: each one's ``__all__`` is what a notebook user calls.
PACKAGES = ["spa", "spa.closedloop", "spa.datasets", "spa.identification", "spa.model.modulators",
            "spa.openloop", "spa.report", "spa.synthetic", "spa.tuning"]  # fmt: skip

#: Pages the site must have (the lead links other engineers' pages after merging).
PAGES = [
    "index",
    "getting-started/index", "getting-started/install", "getting-started/first-run",
    "getting-started/your-lab", "getting-started/notebook",
    "howto/index", "howto/add-dataset", "howto/bench-formats", "howto/relax-tuning",
    "howto/figures", "howto/cluster", "howto/many-sessions", "howto/controller-on-bench",
    "howto/cite-reproduce",
    "explanation/index", "explanation/model", "explanation/modulators", "explanation/tuning",
    "explanation/identification", "explanation/closed-loop-pi",
    "explanation/closed-loop",
    "explanation/physical-plant", "explanation/figures", "explanation/dependencies",
    "reference/index", "reference/configuration", "reference/raw-contract", "reference/cli",
    "reference/api", "reference/outputs", "reference/benchmarks",
]  # fmt: skip


def _resolve(dotted: str):
    """The object a dotted name (``spa.tuning.tune``) names."""
    module, _, name = dotted.rpartition(".")
    return getattr(importlib.import_module(module), name)


def reference_entries(text: str) -> list[str]:
    """The full names of the API reference's autosummary entries, before "Internals".

    Examples
    --------
    >>> reference_entries(".. currentmodule:: spa\\n\\n.. autosummary::\\n   :toctree: g\\n"
    ...                   "\\n   simulate\\n   modulate\\n\\nInternals\\n---------\\n")
    ['spa.simulate', 'spa.modulate']
    """
    text = text.split("\nInternals\n")[0]
    entries, module, in_summary = [], "", False
    for line in text.splitlines():
        if m := re.match(r"\.\. currentmodule:: (\S+)", line):
            module, in_summary = m.group(1), False
        elif line.startswith(".. autosummary::"):
            in_summary = True
        elif in_summary and re.match(r"   [A-Za-z_][\w.]*$", line):
            entries.append(f"{module}.{line.strip()}")
        elif line and not line.startswith(" "):
            in_summary = False
    return entries


def public_names() -> dict[str, object]:
    """``package.name -> object`` for every name of every public package's ``__all__``."""
    return {
        f"{p}.{n}": getattr(importlib.import_module(p), n)
        for p in PACKAGES
        for n in importlib.import_module(p).__all__
    }


def test_every_public_name_has_an_entry_and_every_entry_is_public():
    entries = reference_entries(API.read_text(encoding="utf-8"))
    assert len(entries) == len(set(entries)), "an entry is listed twice"
    objects = {e: _resolve(e) for e in entries}
    public = public_names()
    missing = [
        name
        for name, obj in public.items()
        if not any(o is obj and e.rsplit(".", 1)[1] == name.rsplit(".", 1)[1]
                   for e, o in objects.items())
    ]  # fmt: skip
    assert missing == [], f"public names without an entry in docs/reference/api.rst: {missing}"
    stray = [
        e
        for e, o in objects.items()
        if not any(obj is o and name.rsplit(".", 1)[1] == e.rsplit(".", 1)[1]
                   for name, obj in public.items())
    ]  # fmt: skip
    assert stray == [], f"entries of docs/reference/api.rst that are not public: {stray}"


def test_the_top_level_holds_what_a_notebook_calls():
    import spa

    calls = ("simulate", "modulate", "Modulator", "identify", "tune", "design_pi",
             "simulate_closed_loop", "export_designed", "validate_dataset",
             "read_runs")  # fmt: skip
    for name in calls:
        assert name in spa.__all__, name
    for name in ("closed_loop", "build_dataset_page", "write_manifest"):  # stage runners, pages
        assert name not in spa.__all__, name


@pytest.fixture(scope="module")
def site(tmp_path_factory) -> Path:
    pytest.importorskip("sphinx")
    pytest.importorskip("numpydoc")
    pytest.importorskip("myst_nb")
    pytest.importorskip("pydata_sphinx_theme")
    out = tmp_path_factory.mktemp("site")
    res = subprocess.run(
        [sys.executable, "-m", "sphinx", "-b", "html", "-W", "--keep-going", "-j", "auto", "-q",
         "-d", str(out / "doctrees"), str(DOCS), str(out / "html")],
        capture_output=True, text=True, cwd=ROOT, timeout=1800,
    )  # fmt: skip
    assert res.returncode == 0, (res.stdout + res.stderr)[-5000:]
    said = _KERNEL_SHUTDOWN.sub("", res.stderr)
    assert said.strip() == "", said[-5000:]  # no warning at all
    return out / "html"


#: The one traceback a notebook page's kernel may print as it is shut down: ipykernel's
#: control channel flushing stderr after its I/O thread closed the socket. It is the
#: kernel's, not Sphinx's, and says nothing of the pages; nothing else is forgiven.
_KERNEL_SHUTDOWN = re.compile(
    r"ERROR:tornado\.general:Uncaught exception in ZMQStream callback\n"
    r"Traceback \(most recent call last\):\n(?:  .*\n)+?"
    r"zmq\.error\.ZMQError: Socket operation on non-socket\n?"
)


def test_only_the_kernels_shutdown_traceback_is_forgiven() -> None:
    noise = (
        "ERROR:tornado.general:Uncaught exception in ZMQStream callback\n"
        "Traceback (most recent call last):\n"
        '  File "zmqstream.py", line 585, in _log_error\n'
        "    f.result()\n"
        "zmq.error.ZMQError: Socket operation on non-socket\n"
    )
    warning = "docs/x.md:3: WARNING: unknown document: 'y'\n"
    assert _KERNEL_SHUTDOWN.sub("", noise + warning + noise) == warning
    assert _KERNEL_SHUTDOWN.sub("", warning.replace("WARNING", "ERROR")) != ""


def _text(site: Path, page: str) -> str:
    return (site / f"{page}.html").read_text(encoding="utf-8")


def test_the_site_has_its_four_parts_linked_from_the_front_page(site):
    for page in PAGES:
        assert (site / f"{page}.html").is_file(), page
    front = _text(site, "index")
    for part in ("getting-started/index", "howto/index", "explanation/index", "reference/index"):
        assert f"{part}.html" in front, part
    assert "Dependencies, and why" in _text(site, "explanation/dependencies")
    assert "spa tune" in _text(site, "reference/cli")
    assert "export-controller" in _text(site, "reference/cli")


def test_the_contract_the_configuration_and_the_model_are_on_the_site(site):
    assert "What <code class" in _text(
        site, "reference/raw-contract"
    )  # "What `spa validate` checks"
    assert "spa validate" in _text(site, "reference/raw-contract")
    assert "max_chattering" in _text(site, "reference/configuration")
    assert "closed_loop" in _text(site, "reference/configuration")
    assert "Eq" in _text(site, "explanation/model")


def test_the_tutorial_and_the_figures_ran_at_build(site):
    tutorial = _text(site, "getting-started/your-lab")
    assert "drafted 5 run(s)" in tutorial  # spa init
    assert "raw/mylab: OK, 5 run(s)" in tutorial  # spa validate
    assert "failed: []" in tutorial  # the run's status.yaml
    assert "Closed loop: use" in tutorial  # the chosen loop's sentence
    assert "wrote board/controller.h" in tutorial  # spa export-controller
    notebook = _text(site, "getting-started/notebook")
    assert "problems: []" in notebook  # the dataset checked
    assert "SPA_CTRL: gain-scheduled PI with feed-forward" in notebook  # the exported header
    figures = _text(site, "explanation/figures")
    assert figures.count("<img") >= 12
    for fig in ("Fig. 2a", "Fig. 6", "Fig. 9", "Fig. 10", "Fig. O1"):
        assert fig in figures, fig


def test_no_page_names_an_issue_number(site):
    pages = [
        p
        for p in site.rglob("*.html")
        if p.relative_to(site).parts[0] not in ("_modules", "_sources")
    ]
    found = [
        f"{p.relative_to(site)}: {m.group(0)}"
        for p in pages
        for m in re.finditer(
            r"\bissues? \d+", re.sub(r"<[^>]+>", "", p.read_text(encoding="utf-8"))
        )
    ]
    assert found == []


def test_every_reference_entry_has_its_page(site):
    for entry in reference_entries(API.read_text(encoding="utf-8")):
        assert (site / "reference" / "generated" / f"{entry}.html").is_file(), entry
    tune = _text(site, "reference/generated/spa.tune")
    assert "Parameters" in tune and "Returns" in tune and "TuningResult" in tune
    assert "c1" in _text(site, "reference/generated/spa.ValveParams")


def _pages(site: Path) -> list[Path]:
    return [
        p
        for p in site.rglob("*.html")
        if p.relative_to(site).parts[0] not in ("_modules", "_sources", "_static")
        and p.name not in ("genindex.html", "search.html", "py-modindex.html")
    ]


def test_no_rendered_page_shows_an_escaped_percent_or_two_titles(site):
    escaped = [str(p.relative_to(site)) for p in _pages(site) if "%%" in p.read_text()]
    assert escaped == []
    titles = {
        str(p.relative_to(site)): n
        for p in _pages(site)
        if (n := len(re.findall(r"<h1\b", p.read_text(encoding="utf-8")))) != 1
    }
    assert titles == {}, f"pages without exactly one H1: {titles}"
    assert _text(site, "index").count("<dt") >= 4  # the front page's definition list
