"""Getting started copies into a terminal: every block a reader sees on the getting-started
pages runs, page by page in the order of the part's table of contents, in one fresh folder
laid out like the source folder (its workflow files, docs and benchmarks linked,
``raw/example`` copied).

- A shell block (```` ```bash ````, or a code cell of ``!`` lines) runs with bash, stopping at
  the first failing command.
- A Python block (a code cell, or ```` ```python ````) runs in a fresh interpreter started in
  the folder, after the page's earlier Python blocks (as one session would have run them);
  consecutive Python blocks share that interpreter, and a failure names its block.
- Cells hidden from the reader (``remove-input``/``remove-cell``) are the page's own
  machinery and are left out.
- The small configuration's results come from the session's run of the same command in the
  same layout (``small_source`` of ``tests/conftest.py``, shared with
  ``tests/test_doc_commands.py``): the pages' runs of it find nothing to redo.
- A block that cannot run here as shown (the full configuration runs for hours, ``make test``
  is this suite) carries, on the line above it, a comment the site does not render:
  ``% planned, not run: <why>``. Its commands are planned as ``tests/test_doc_commands.py``
  plans a shown command (a dry run, ``make -n``, pip's ``--dry-run``; ``source`` and
  ``git`` are not run, for the reasons of its ``NOT_RUN``). A block with such a command
  and without the comment fails the test, and so does a comment without a reason.

Any error fails the test, naming the page and the block.
"""

from __future__ import annotations

import json
import os
import re
import shlex
import shutil
import subprocess
import sys
import textwrap
from dataclasses import dataclass
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PART = ROOT / "docs" / "getting-started"
TUTORIAL = PART / "your-lab.md"
sys.path.insert(0, str(Path(__file__).resolve().parent))
import test_doc_commands as shown  # noqa: E402  (how a shown command is planned)


def pages() -> list[Path]:
    """The getting-started pages, in the order of the part's table of contents."""
    toc = (PART / "index.md").read_text(encoding="utf-8").split("```{toctree}")[1]
    names = re.findall(r"^([\w-]+)\s*$", toc.split("```")[0], flags=re.M)
    return [PART / f"{name}.md" for name in names]


@dataclass(frozen=True)
class Block:
    """One block a reader copies: ``lang`` is "bash" or "python"; ``planned`` the reason it
    is planned rather than run ("" for a block run as shown)."""

    number: int
    lang: str
    code: str
    planned: str = ""


_FENCE = re.compile(
    r"^(?P<indent>[ \t]*)```(?P<info>\S[^\n]*)\n"
    r"(?P<options>(?:[ \t]*:[\w-]+:[^\n]*\n)*)(?P<code>.*?)^(?P=indent)```[ \t]*$",
    flags=re.S | re.M,
)
_PLANNED = re.compile(r"^\s*%\s*planned, not run:\s*(?P<why>.*?)\s*$")
#: Fences that show rather than run: a directive's body, an output or a file's contents.
SHOWN = ("text", "yaml", "c", "console-output")


def reader_blocks(text: str) -> list[Block]:
    """Every block a reader sees and copies on a page, in order.

    >>> [(b.lang, b.code, b.planned) for b in reader_blocks(
    ...     "x\\n```bash\\nls\\n```\\n% planned, not run: slow\\n```bash\\nmake a\\n```\\n"
    ...     "```{code-cell} ipython3\\n:tags: [remove-cell]\\nx = 1\\n```\\n"
    ...     "```{code-cell} ipython3\\n!spa a\\n!spa b\\n```\\n"
    ...     "```{code-cell} ipython3\\nprint(2)\\n```\\n")]
    [('bash', 'ls\\n', ''), ('bash', 'make a\\n', 'slow'), ('bash', 'spa a\\nspa b\\n', ''), \
('python', 'print(2)\\n', '')]
    """
    blocks: list[Block] = []
    for match in _FENCE.finditer(text):
        info, options = match["info"].strip(), match["options"]
        code = textwrap.dedent(match["code"])
        before = text[: match.start()].rstrip("\n").rpartition("\n")[2]  # the line above
        planned = _PLANNED.match(before)
        why = planned["why"] if planned else ""
        if planned and not why:
            raise ValueError(f"block {len(blocks)}: `% planned, not run:` without a reason")
        if info == "bash":
            blocks.append(Block(len(blocks), "bash", code, why))
        elif info == "python":
            blocks.append(Block(len(blocks), "python", code, why))
        elif info == "{code-cell} ipython3":
            if re.search(r"remove-(?:input|cell)", options):
                continue
            lines = [line for line in code.splitlines() if line.strip()]
            bang = [line.lstrip().startswith("!") for line in lines]
            if any(bang) and not all(bang):
                raise ValueError(f"block {len(blocks)} mixes shell (!) and Python lines:\n{code}")
            if all(bang) and lines:
                shell = "".join(re.sub(r"^\s*!", "", line) + "\n" for line in lines)
                blocks.append(Block(len(blocks), "bash", shell, why))
            else:
                blocks.append(Block(len(blocks), "python", code, why))
        elif not (info.startswith("{") or info in SHOWN):
            raise ValueError(f"a ```{info} block: neither run nor shown; name its kind")
    return blocks


def _env() -> dict[str, str]:
    env = dict(os.environ)
    env["PATH"] = os.pathsep.join((str(Path(sys.executable).parent), env.get("PATH", "")))
    env["PYTHONPATH"] = os.pathsep.join(p for p in (str(ROOT), env.get("PYTHONPATH", "")) if p)
    env["SPA_PROGRESS"] = "0"
    env["MPLBACKEND"] = "Agg"
    return env


def _transformed(command: str) -> bool:
    """Whether the shown command would be planned (changed or not run), not run as shown."""
    how = shown.plan(command)
    return how is None or how[0] != shlex.split(shown.fill(command))


#: Runs the page's Python blocks (JSON on stdin) in one namespace, naming a failing block.
_DRIVER = """
import json, sys, traceback
blocks = json.load(sys.stdin)
namespace = {"__name__": "__main__"}
for number, code in blocks:
    try:
        exec(compile(code, f"<block {number}>", "exec"), namespace)
    except BaseException:
        traceback.print_exc()
        print(f"FAILED-BLOCK {number}")
        sys.exit(1)
"""


def _fail(page: Path, block: Block, res: subprocess.CompletedProcess, how: str = "") -> str:
    return (
        f"{page.name}, block {block.number} ({block.lang}{how}) failed:\n{block.code}\n"
        + res.stdout[-3000:]
        + res.stderr[-3000:]
    )


def run_page(page: Path, work: Path) -> list[Block]:
    """Run every block of ``page`` in ``work``, in order; fail on the first error."""
    blocks = reader_blocks(page.read_text(encoding="utf-8"))
    session: list[tuple[int, str]] = []
    for block, after in zip(blocks, [*blocks[1:], None], strict=True):
        needs_cc = re.search(r"^cc |build_harness", block.code, flags=re.M)
        if needs_cc and not shutil.which("cc"):
            pytest.skip(f"{page.name}: block {block.number} compiles C; no `cc` here "
                        "(`make test` installs gcc)")  # fmt: skip
        if block.lang == "python":
            assert not block.planned, f"{page.name}, block {block.number}: Python is run"
            session.append((block.number, block.code))
            if after is not None and after.lang == "python":
                continue  # consecutive Python blocks run in one interpreter
            res = subprocess.run([sys.executable, "-c", _DRIVER], input=json.dumps(session),
                                 cwd=work, env=_env(), capture_output=True, text=True,
                                 timeout=900)  # fmt: skip
            failed = re.search(r"FAILED-BLOCK (\d+)", res.stdout)
            culprit = blocks[int(failed[1])] if failed else block
            assert res.returncode == 0, _fail(page, culprit, res)
        elif block.planned:
            for command in shown.commands(f"```bash\n{block.code}```\n"):
                how = shown.plan(command)
                if how is None:  # source, git, cd: NOT_RUN says why
                    continue
                argv, where = how
                res = subprocess.run(argv, cwd=ROOT if where == "root" else work, env=_env(),
                                     capture_output=True, text=True, timeout=900)  # fmt: skip
                assert res.returncode == 0, _fail(page, block, res, f", planned as {argv}")
        else:
            cmds = shown.commands(f"```bash\n{block.code}```\n")
            transformed = [c for c in cmds if _transformed(c) and not c.startswith("cc ")]
            assert not transformed, (
                f"{page.name}, block {block.number} holds {transformed}, which cannot run as "
                "shown here: mark the block `% planned, not run: <why>` on the line above it"
            )
            res = subprocess.run(["bash", "-e", "-c", block.code], cwd=work, env=_env(),
                                 capture_output=True, text=True, timeout=1800)  # fmt: skip
            assert res.returncode == 0, _fail(page, block, res)
    return blocks


@pytest.fixture(scope="module")
def folder(small_source, tmp_path_factory) -> Path:
    """A fresh folder laid out like the source folder, shared by the pages in order.

    The small configuration's results (and Snakemake's record of them) are copied in from the
    session's run of the same command in the same layout (``small_source``), so that the
    pages' own runs of the small configuration check their command and find nothing to
    redo, rather than take CI's time twice; every other output is the pages' own."""
    from conftest import scratch_source

    work = scratch_source(tmp_path_factory.mktemp("getting-started") / "spa-pipeline")
    shutil.copytree(small_source / "results", work / "results")
    shutil.copytree(small_source / ".snakemake" / "metadata", work / ".snakemake" / "metadata")
    return work


def test_the_part_lists_every_page_and_the_blocks_are_plain_shell_and_python():
    assert {p.name for p in pages()} == {
        p.name for p in PART.glob("*.md") if not p.name.startswith(("_", "index"))
    }
    blocks = reader_blocks(TUTORIAL.read_text(encoding="utf-8"))
    assert [b.lang for b in blocks].count("bash") >= 8
    assert any("snakemake reproduce-all" in b.code for b in blocks if b.lang == "bash")
    assert any("spa export-controller" in b.code for b in blocks if b.lang == "bash")
    python = "".join(b.code for b in blocks if b.lang == "python")
    assert "from pathlib import Path" in python  # imports visible, not in a hidden cell
    notebook = reader_blocks((PART / "notebook.md").read_text(encoding="utf-8"))
    assert {b.lang for b in notebook} == {"python"}
    assert "export_designed" in "".join(b.code for b in notebook)


def test_a_block_that_cannot_run_as_shown_must_say_why():
    with pytest.raises(ValueError, match="without a reason"):
        reader_blocks("text\n% planned, not run:\n```bash\nmake test\n```\n")
    with pytest.raises(ValueError, match="mixes"):
        reader_blocks("```{code-cell} ipython3\n!ls\nx = 1\n```\n")
    with pytest.raises(ValueError, match="name its kind"):
        reader_blocks("```sh\nls\n```\n")
    assert _transformed("make test") and _transformed("snakemake reproduce-all")
    assert not _transformed("snakemake reproduce-all --configfile config/small.yaml")
    assert not _transformed("spa validate raw/mylab")


def test_a_failing_block_is_named_and_a_session_keeps_its_names(tmp_path):
    page = tmp_path / "page.md"
    page.write_text(
        "```python\nx = 2\n```\n```bash\necho ok > f.txt\n```\n"
        "```{code-cell} ipython3\nassert x == 2\n```\n```python\nprint(1 / (x - 2))\n```\n"
    )
    with pytest.raises(AssertionError, match=r"page\.md, block 3 \(python\)") as failed:
        run_page(page, tmp_path)
    assert "ZeroDivisionError" in str(failed.value)
    assert (tmp_path / "f.txt").read_text() == "ok\n"


#: Pages with a block known to fail as the reader copies it, and why; strict, so the entry
#: must go as soon as the page is fixed.
KNOWN_FAILING: dict[str, str] = {}


def _marked(page: Path):
    why = KNOWN_FAILING.get(page.stem)
    marks = [pytest.mark.xfail(strict=True, raises=AssertionError, reason=why)] if why else []
    return pytest.param(page, marks=marks, id=page.stem)


@pytest.mark.parametrize("page", [_marked(p) for p in pages()])
def test_every_block_of_the_page_runs_in_order_in_the_fresh_folder(folder, page):
    blocks = run_page(page, folder)
    assert blocks, f"{page.name}: no block found"
    if page == TUTORIAL:
        assert (folder / "board" / "controller.h").is_file()
        assert "failed: []" in (folder / "results" / "status.yaml").read_text()
    if page.stem == "notebook":
        assert "spa_ctrl_step" in (folder / "board" / "controller.h").read_text()
