"""The documentation's pages, checked from their sources without building the site.

Each check keeps one kind of defect out: an API summary cut at an abbreviation's full stop or
showing raw markup, a doubled word, ``%%`` on the CLI page, a caption that counts the
modulators differently from its legend, a page with two titles, a definition list that does
not render, an equation written as code, and developer vocabulary on the pages for users.
"""

from __future__ import annotations

import importlib
import inspect
import itertools
import re
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
if str(DOCS) not in sys.path:
    sys.path.append(str(DOCS))  # docs/_cli.py and docs/_summaries.py, as conf.py imports them

#: Pages for users: they name commands, files in results/ and raw/, configuration keys.
USER_PARTS = ("getting-started", "howto", "explanation")
#: The contributor's pages of the explanation part: they may name modules and test files.
CONTRIBUTOR_PAGES = ("explanation/architecture.md", "explanation/dependencies.md")


def _resolve(dotted: str):
    """The object or module a dotted name names."""
    try:
        return importlib.import_module(dotted)
    except ImportError:
        module, _, name = dotted.rpartition(".")
        return getattr(importlib.import_module(module), name)


def _api_entries() -> list[str]:
    """Every name the API reference summarises: the public entries and the internal modules."""
    from test_docs_site import API, reference_entries

    text = API.read_text(encoding="utf-8")
    internals = re.findall(r"^   (spa(?:\.\w+)*)$", text.split("\nInternals\n")[1], flags=re.M)
    return reference_entries(text) + internals


def summary(obj) -> str:
    """The one-line summary Sphinx's autosummary shows for ``obj``'s docstring."""
    from _summaries import extend_abbreviations
    from docutils.frontend import get_default_settings
    from docutils.parsers.rst import Parser
    from sphinx.ext.autosummary import extract_summary
    from sphinx.util.docutils import docutils_namespace

    extend_abbreviations()  # as docs/conf.py does

    lines = inspect.cleandoc(obj.__doc__ or "").splitlines()
    if not lines:
        return ""
    with docutils_namespace():
        settings = get_default_settings(Parser)
        settings.pep_references = settings.rfc_references = False
        settings.tab_width = 8
        settings.language_code = "en"
        return extract_summary(lines, settings)


#: An abbreviation whose full stop ends a summary: the sentence was cut at it.
_ABBREVIATION = re.compile(r"\b(?:Eqs?|Apps?|Figs?|Secs?|Refs?|e\.g|i\.e|cf|vs|etc|approx)\.$")


def _rendered_words(text: str) -> list[str]:
    """The words a reader sees, a literal (````snakemake --report r.zip````) being one word."""
    tokens = re.findall(r"``[^`]+``|:\w+:`[^`]+`|[\w'-]+", text)
    return [re.sub(r"^:\w+:`~?|`", "", t).lower() for t in tokens]


def summary_problems(text: str) -> list[str]:
    """What is wrong with one summary line.

    Examples
    --------
    >>> summary_problems("The equilibrium (Eq.")
    ['ends at an abbreviation']
    >>> summary_problems("Staircase: 0, ``step``, 2*``step``, ...")
    ['shows raw markup']
    >>> summary_problems("Worst case of the controller ``controller``.")
    ["doubles 'controller'"]
    >>> summary_problems("What ``snakemake --report report.zip`` shows.")
    []
    >>> summary_problems("The equilibrium pressure (Eq. 5).")
    []
    """
    problems = []
    if _ABBREVIATION.search(text.strip()):
        problems.append("ends at an abbreviation")
    if re.search(r"\w\*``|[^\s(`]``\w", text):  # 2*``step``: markup glued to a word
        problems.append("shows raw markup")
    words = _rendered_words(text)
    problems += [f"doubles {a!r}" for a, b in itertools.pairwise(words) if a == b and a.isalpha()]
    return problems


def test_the_summary_check_finds_each_defect():
    assert summary_problems("Fit the valve (App. B) to the runs (Table 3, Figs.") == [
        "ends at an abbreviation"
    ]
    assert summary_problems("Sweep ``f_w`` and ``t_l``.") == []
    assert summary_problems("Inputs 2*``step``.") == ["shows raw markup"]


def test_no_api_summary_is_cut_at_an_abbreviation_shows_markup_or_doubles_a_word():
    pytest.importorskip("sphinx")
    bad = {}
    for entry in _api_entries():
        text = summary(_resolve(entry))
        if problems := summary_problems(text):
            bad[entry] = (text, problems)
    assert bad == {}, "\n".join(f"{e}: {t!r}: {p}" for e, (t, p) in bad.items())


def test_the_cli_page_shows_no_escaped_percent():
    from _cli import cli_page

    text = cli_page()
    assert "%%" not in text
    assert "95 % intervals" in text  # spa identify's summary, as the reader sees it


_NUMBER_WORDS = {"two": 2, "three": 3, "four": 4, "five": 5, "six": 6, "seven": 7}


def modulator_counts(text: str) -> list[int]:
    """The counts a caption gives for "all/every N modulators" (the series of a legend).

    >>> modulator_counts("J for all four modulators on one axis, and the five modulators.")
    [4, 5]
    """
    pattern = r"\b(?:all|the|of) (two|three|four|five|six|seven|\d+) modulators\b"
    return [
        int(w) if w.isdigit() else _NUMBER_WORDS[w]
        for w in re.findall(pattern, text, flags=re.IGNORECASE)
    ]


def test_each_caption_counts_the_modulators_its_legend_shows():
    """Figures that draw every kind (Fig. 4 and 5) have one legend entry per registered kind."""
    from spa.model.modulators import kinds
    from spa.pipeline.stage_table import STAGES

    legend = len(kinds())
    captions = {
        f"{s.name}: {o.path}": o.caption
        for s in STAGES
        for o in s.outputs
        if getattr(o, "caption", None)
    }
    captions |= {
        str(p.relative_to(ROOT)): p.read_text(encoding="utf-8")
        for p in (ROOT / "workflow" / "report").glob("*.rst")
    }
    captions["docs/reference/outputs.md"] = (DOCS / "reference" / "outputs.md").read_text()
    wrong = {k: c for k, text in captions.items() if (c := modulator_counts(text)) and
             any(n != legend for n in c)}  # fmt: skip
    assert captions, "no caption found"
    assert wrong == {}, f"captions counting other than the legend's {legend} modulators: {wrong}"


def _markdown_pages() -> list[Path]:
    return sorted(
        p
        for p in DOCS.rglob("*.md")
        if "_build" not in p.parts and p.name != "cli.md" and not p.name.startswith("_")
    )


def _without_code(text: str) -> str:
    """The text with its fenced code blocks removed."""
    return re.sub(r"^(```|~~~).*?^\1", "", text, flags=re.S | re.M)


def _expanded(page: Path) -> str:
    """The page's text with its ``{include}`` directives replaced by the included file."""
    text = page.read_text(encoding="utf-8")

    def include(m: re.Match) -> str:
        target = page.parent / m.group(1).strip()
        if target.name == "_source.md" and not target.exists():
            # written by docs/conf.py at build time, from pyproject.toml: write it the same way
            import sys

            sys.path.insert(0, str(DOCS))
            from _source import write_source_section

            write_source_section(ROOT / "pyproject.toml", target)
        return target.read_text(encoding="utf-8")

    return re.sub(r"```\{include\} ([^\n]+)\n(?::[^\n]*\n)*```", include, text)


@pytest.mark.parametrize(
    "page",
    [p for p in _markdown_pages() if p != DOCS / "model.md"],
    ids=lambda p: str(p.relative_to(DOCS)),
)
def test_every_page_has_one_title(page):
    text = _without_code(_expanded(page))
    titles = re.findall(r"^# .+", text, flags=re.M)
    assert len(titles) == 1, f"{page.relative_to(ROOT)} has {len(titles)} H1 headings: {titles}"


def test_the_front_pages_definition_list_renders():
    """MyST renders ``term`` / ``: definition`` as <dl> only with its deflist extension."""
    from markdown_it.renderer import RendererHTML
    from myst_parser.config.main import MdParserConfig
    from myst_parser.parsers.mdit import create_md_parser

    conf: dict = {}
    exec(
        compile(
            re.search(r"^myst_enable_extensions = .*$", (DOCS / "conf.py").read_text(), re.M)[0],
            "conf.py",
            "exec",
        ),
        conf,
    )
    config = MdParserConfig(enable_extensions=set(conf["myst_enable_extensions"]))
    html = create_md_parser(config, RendererHTML).render((DOCS / "index.md").read_text())
    assert html.count("<dt>") >= 4, "the front page's definition list is not rendered"


# --- equations are math, and user pages speak plainly ---------------------------------------

#: A code span that holds an equation or a formula: a relation, a Greek letter or a math sign.
_FORMULA = re.compile(r"[ξαβτθρΣσΔφπΩΓ√²³⁻¹∞≤≥≈‖⟨⟩·]| [=<>] |\S [+*/] \S|\S - \S|/dt\b")


def _prose(text: str) -> str:
    """The page's text without fenced blocks (code, directives' bodies are kept) and math."""
    text = re.sub(r"^(```+|~~~+)(?!\{).*?^\1", "", text, flags=re.S | re.M)
    text = re.sub(r"\$\$.*?\$\$", "", text, flags=re.S)
    return re.sub(r"(?<![\\$])\$[^$\n]+\$", "", text)


def code_spans(text: str) -> list[str]:
    """The inline code spans of a page's prose (not those of a role such as {term}`x`).

    >>> code_spans("Run `spa tune` for {term}`FIT`, with ``a `b` c`` too.\\n```\\n`no`\\n```")
    ['spa tune', 'a `b` c']
    """
    text = re.sub(r"^(```+|~~~+).*?^\1", "", text, flags=re.S | re.M)
    text = re.sub(r"\{[\w:-]+\}`[^`]*`", "", text)  # roles: {term}`FIT`, {doc}`model`
    spans = re.findall(r"(?<!`)(`+)(?!`)(.+?)(?<!`)\1(?!`)", text)
    return [s.strip() for _, s in spans]


def formulas_in_code(text: str) -> list[str]:
    """The code spans that hold a formula.

    >>> formulas_in_code("`dP/dt = -P/τ1(P)` and `k2·ξ` beside `spa tune raw/x` and `f_w: 20`")
    ['dP/dt = -P/τ1(P)', 'k2·ξ']
    """
    commands = ("spa ", "snakemake ", "sed ", "column ", "python ", "cat ", "make ")
    return [s for s in code_spans(text) if _FORMULA.search(s) and not s.startswith(commands)]


def _site_pages(parts: tuple[str, ...]) -> list[Path]:
    return [p for p in _markdown_pages() if p.relative_to(DOCS).parts[0] in parts]


USER_PAGES = [
    p
    for p in _site_pages(USER_PARTS)
    if str(p.relative_to(DOCS)) not in CONTRIBUTOR_PAGES
]


def _id(p: Path) -> str:
    return str(p.relative_to(DOCS))


def _written_pages() -> list[Path]:
    """Every Markdown page of the site written by hand (the gallery's pages are made at build
    from its scripts, the CLI page from the parser)."""
    return [p for p in _markdown_pages() if p.parent != DOCS / "gallery"]


@pytest.mark.parametrize("page", _written_pages(), ids=_id)
def test_equations_are_math_not_code(page):
    found = formulas_in_code(page.read_text(encoding="utf-8"))
    assert found == [], f"{_id(page)}: equations written as code, not math: {found}"


#: What a user page must not name: test files, source modules, the pipeline's stage table.
_DEVELOPER = re.compile(
    r"\btests?/\S*|\btest_\w+\.py\b|\bspa/[\w/<>.]+\.py\b|`(?-i:spa\.[a-z_]+\.)\w[^`]*`|(?<!--)\bstages?\b",
    re.IGNORECASE,
)


def developer_words(text: str) -> list[str]:
    """Test files, module paths and "stage" in a page's text (its code blocks included).

    >>> developer_words("checked in tests/test_x.py by spa/model/plant.py, stage `spa.a.b`")
    ['tests/test_x.py', 'spa/model/plant.py', 'stage', '`spa.a.b`']
    >>> developer_words("run `spa tune`, see {func}`~spa.closedloop.design_pi`; staged")
    []
    """
    text = re.sub(r"\{\w+\}`~[^`]+`", "", text)  # a cross-reference shows its last name only
    hidden = r"^```\{code-cell\}[^\n]*\n:tags: \[remove-(?:cell|input)\]\n.*?^```"
    text = re.sub(hidden, "", text, flags=re.S | re.M)  # cells the reader never sees
    return [m.group(0) for m in _DEVELOPER.finditer(text)]


@pytest.mark.parametrize("page", [DOCS / "model.md", *USER_PAGES], ids=_id)
def test_user_pages_name_no_test_file_module_path_or_stage(page):
    found = developer_words(page.read_text(encoding="utf-8"))
    assert found == [], f"{_id(page)} names {found}"


def page_names(text: str) -> list[str]:
    """Pages named as plain text (``docs/model.md``, ```config/README.md```, "the README"),
    not as a link (``[the model](../model.md)``, ``{doc}`model```).

    >>> page_names("See docs/model.md and `config/README.md`, the README, [x](../a.md).")
    ['docs/model.md', 'config/README.md', 'README']
    """
    # fenced blocks are code or directives ({include} ../model.md), not prose: a command that
    # names its output file (`--page verification.md`) does not cross-reference a page
    text = re.sub(r"^(```+).*?^\1[^\n]*$", "", text, flags=re.S | re.M)
    text = re.sub(r"\]\([^)]*\)|\{\w+\}`[^`]*`", "]", _prose(text))
    return re.findall(r"(?:[\w.-]+/)*[\w.-]+\.md\b|\bREADME\b(?!\.md)", text)


def test_cross_references_between_pages_are_links():
    """A page names another page by a link, not as plain text (docs/x.md, README.md)."""
    bare = {
        _id(p): m
        for p in [DOCS / "model.md", *USER_PAGES]
        if (m := page_names(p.read_text(encoding="utf-8")))
    }  # fmt: skip
    assert bare == {}, f"pages naming other pages as text: {bare}"


# --- the glossary, linked where each term first appears -------------------------------------

#: Glossary terms a user page links where it first uses them: ``term -> pattern``.
GLOSSARY_TERMS = {
    "FIT": r"\bFIT\b",
    "promise": r"\b[Pp]romis(?:e|es|ed)\b",
    "held-out": r"\b[Hh]eld[- ]out\b",
    "unverified": r"\b[Uu]nverified\b",
    "box": r"(?<=95 % )box\b|(?<=merged )box\b",
    "ξ": r"ξ|\binput fractions?\b",
    "J": r"\blinearity cost\b|(?<![\w$\\])J(?![\w$])",
    "τ_m": r"τ_m|\bequivalent time constant\b",
    "t_l*": r"t_l\*",
}
#: The other names of a glossary entry a link may target (``input fraction`` for ``ξ``).
GLOSSARY_ALIASES = {"ξ": {"input fraction"}, "J": {"linearity cost"}, "τ_m": {"time constant"}}
#: Pages another change is editing, and the terms they do not link yet; the check fails as
#: soon as one of them is linked, so that the entry is removed.
GLOSSARY_PENDING: dict[str, list[str]] = {}

#: What is not running prose: fenced blocks, headings, math, code, roles, links, bold.
_NOT_PROSE = re.compile(
    r"^(```+|~~~+).*?^\1[^\n]*$|^#[^\n]*$|\$\$.*?\$\$|(?<![\\$])\$[^$\n]+\$|\{\w+\}`[^`]*`"
    r"|``[^`]+``|`[^`\n]+`|\[[^\]]*\]\([^)]*\)|\*\*[^*]+\*\*",
    flags=re.S | re.M,
)


def unlinked_terms(text: str) -> list[str]:
    """The glossary terms whose first use in a page's prose is not a {term} link.

    >>> unlinked_terms("A {term}`FIT` of 90 %; the FIT again. The promise holds.")
    ['promise']
    >>> unlinked_terms("# The promise\\n\\nIts {term}`promise` holds; `FIT` is code.")
    []
    >>> unlinked_terms("An {term}`input fraction <ξ>` ξ; the linearity cost J, {term}`J`.")
    ['J']
    """
    plain = text
    for m in _NOT_PROSE.finditer(text):  # keep roles, blank out everything else not prose
        if not m.group(0).startswith("{term}"):
            plain = plain[: m.start()] + " " * len(m.group(0)) + plain[m.end() :]
    missing = []
    for term, pattern in GLOSSARY_TERMS.items():
        first = re.search(pattern, plain)  # its first use (a role's text counts too)
        targets = {term, *GLOSSARY_ALIASES.get(term, ())}
        links = [m.start() for m in re.finditer(r"\{term\}`([^`]*)`", plain)
                 if re.sub(r".*<([^>]+)>$", r"\1", m[1]) in targets]  # fmt: skip
        if first and not (links and links[0] <= first.start()):
            missing.append(term)
    return missing


@pytest.mark.parametrize("page", [DOCS / "model.md", *USER_PAGES], ids=_id)
def test_each_glossary_term_is_linked_where_the_page_first_uses_it(page):
    pending = GLOSSARY_PENDING.get(_id(page), [])
    assert unlinked_terms(page.read_text(encoding="utf-8")) == pending, _id(page)


def test_the_glossary_defines_every_linked_term():
    glossary = (DOCS / "reference" / "glossary.md").read_text(encoding="utf-8")
    terms = set(re.findall(r"^(\S[^\n]*)$", glossary.split("```{glossary}")[1], flags=re.M))
    for page in [DOCS / "model.md", *USER_PAGES]:
        for link in re.findall(r"\{term\}`([^`]*)`", page.read_text(encoding="utf-8")):
            target = re.search(r"<([^>]+)>$", link)
            assert (target[1] if target else link) in terms, (_id(page), link)
