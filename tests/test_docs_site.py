"""The documentation site (docs/, `make docs`): it builds offline with warnings as errors; its
four parts are there and linked from the front page; the tutorial and the figures page ran at
build; no page names an issue number; and the API reference lists exactly the public names.

The build is the CI's: `make test` runs this file. Sphinx writes the API and CLI pages'
sources into docs/reference/ (ignored by git) and the site into a temporary folder.
"""

from __future__ import annotations

import importlib
import re
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


sys.path.insert(0, str(DOCS))
import _site  # noqa: E402  (how the site is built and judged: docs/_site.py)


@pytest.fixture(scope="module")
def site(tmp_path_factory) -> Path:
    """The site, built as ``make docs`` builds it. Its verdict is Sphinx's own: exit status 0
    and an empty warnings file (``-w``); the executed pages' kernels may print what they like
    on stderr as they shut down."""
    pytest.importorskip("sphinx")
    pytest.importorskip("numpydoc")
    pytest.importorskip("myst_nb")
    pytest.importorskip("pydata_sphinx_theme")
    out = tmp_path_factory.mktemp("site")
    verdict = _site.build(DOCS, out, cwd=ROOT)
    assert verdict.returncode == 0, verdict.output[-5000:]
    assert verdict.warnings == "", verdict.warnings  # no warning at all
    return out / "html"


def _tiny_site(tmp_path: Path, page: str) -> Path:
    src = tmp_path / "src"
    src.mkdir()
    (src / "conf.py").write_text('extensions = ["myst_parser"]\nproject = "t"\n')
    (src / "index.md").write_text("# Front\n\n```{toctree}\npage\n```\n")
    (src / "page.md").write_text(page)
    return src


def test_a_broken_reference_fails_the_build_and_is_named(tmp_path) -> None:
    pytest.importorskip("myst_parser")
    src = _tiny_site(tmp_path, "# Page\n\nSee {doc}`no-such-page`.\n")
    verdict = _site.build(src, tmp_path / "out")
    assert not verdict.ok
    assert "page.md:3" in verdict.warnings and "no-such-page" in verdict.warnings


def test_a_clean_page_passes_whatever_is_printed_on_stderr(tmp_path) -> None:
    """A page whose build prints libzmq's shutdown abort on stderr (as a kernel's teardown
    does) and warns of nothing is a good build."""
    pytest.importorskip("myst_parser")
    src = _tiny_site(tmp_path, "# Page\n\nSee {doc}`index`.\n")
    (src / "conf.py").write_text(
        (src / "conf.py").read_text()
        + "import sys\nsys.stderr.write('Assertion failed: pfd.revents & POLLIN "
        "(src/signaler.cpp:238)\\n')\n"
    )
    verdict = _site.build(src, tmp_path / "out")
    assert "pfd.revents" in verdict.output  # the noise was there
    assert verdict.ok, verdict.warnings


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


def test_an_executed_page_runs_once_per_state_of_its_code(tmp_path) -> None:
    """docs/_execute.py: a page runs when its outputs are not cached, not when they are, and
    again when one of its cells changes; its cached outputs are the ones it computed."""
    pytest.importorskip("jupyter_cache")
    import _execute

    page = tmp_path / "page.md"
    head = "---\nfile_format: mystnb\nkernelspec:\n  name: python3\n  display_name: Python 3\n---\n"
    page.write_text(head + "# A\n\n```{code-cell} ipython3\nprint(6 * 7)\n```\n")
    assert _execute.executed_pages(tmp_path) == [page]
    cache = _execute.cache_folder(tmp_path / "_build", "k1")
    options = {"extensions": ["colon_fence"], "heading_anchors": 3, "timeout": 120}
    assert _execute.prime([page], cache, **options) == [page]
    assert _execute.prime([page], cache, **options) == []  # cached: no kernel started
    from jupyter_cache import get_cache

    notebook = _execute.read_page(page, ["colon_fence"], 3)
    _, merged = get_cache(str(cache)).merge_match_into_notebook(notebook)
    code = [c for c in merged.cells if c.cell_type == "code"]
    assert "42" in str(code[0].outputs)
    page.write_text(page.read_text().replace("6 * 7", "6 * 8"))
    assert _execute.prime([page], cache, **options) == [page]
    # a new key (a change to what the pages use) starts from an empty cache, the old one gone
    fresh = _execute.cache_folder(tmp_path / "_build", "k2")
    assert not cache.exists() and _execute.prime([page], fresh, **options) == [page]


def test_the_execution_key_follows_what_the_pages_use(tmp_path) -> None:
    import _execute

    (tmp_path / "spa").mkdir()
    (tmp_path / "spa" / "a.py").write_text("x = 1\n")
    key = _execute.sources_key(tmp_path, ("spa",))
    (tmp_path / "spa" / "__pycache__").mkdir()
    (tmp_path / "spa" / "__pycache__" / "a.pyc").write_bytes(b"\0")
    assert _execute.sources_key(tmp_path, ("spa",)) == key  # compiled files are not sources
    (tmp_path / "spa" / "a.py").write_text("x = 2\n")
    assert _execute.sources_key(tmp_path, ("spa",)) != key
