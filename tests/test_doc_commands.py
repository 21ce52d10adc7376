"""Every shell command the README and the documentation site show runs, so an example cannot
rot.

The fenced shell blocks (```bash) of README.md and docs/**/*.md are extracted and each
command is run in a scratch clone (the repository's Snakefile, workflow/, config/, profiles/,
docs/ and benchmarks/ linked; raw/ holding a copy of the bundled example):

- every ``spa`` command, for real;
- every run of the small configuration (``--configfile config/small.yaml``), for real: they
  share one results folder, made once, so all but the first are no-ops;
- every other ``snakemake`` run (the full configuration, the cluster profile) as a dry run;
- ``make TARGET`` as ``make -n TARGET`` in the repository (the target exists and its recipe
  expands);
- a Python one-liner for real, a benchmark script with ``--help``;
- ``python -m pip install .`` as a dry run in the repository.

Placeholders are filled in: ``<name>`` and ``<dataset>`` are the bundled example,
``PARAMS.yaml`` its identified parameters. Only a few commands cannot run here (cloning,
activating the environment, opening a browser); they are listed in ``NOT_RUN``.
"""

from __future__ import annotations

import os
import re
import shlex
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
BIN = Path(sys.executable).parent

#: The commands that are shown but not run here, by their first word, and why.
NOT_RUN = {
    "git": "clones the repository",
    "cd": "changes the shell's folder",
    "source": "activates the environment the tests run in",
    "xdg-open": "opens a browser",
}

_FENCE = re.compile(r"^([ \t]*)```(?:bash|sh|shell|console)[ \t]*\n(.*?)^\1```", re.M | re.S)
_PLACEHOLDERS = {
    "<name>": "example",
    "<dataset>": "example",
    "PARAMS.yaml": "results/example/identification/params.yaml",
    "KIND:NAME=VALUE,...": "pwm:f_w=20",
    "<partition>": "main",
    "<account>": "lab",
}


def documents() -> list[Path]:
    """README.md and every Markdown page of the site, but the pages executed at build (their
    shell blocks run there, in order) and the getting-started pages (every block of theirs
    runs, in order, in tests/test_getting_started.py)."""
    pages = sorted((ROOT / "docs").rglob("*.md"))
    started = ROOT / "docs" / "getting-started"
    return [
        ROOT / "README.md",
        *(p for p in pages if not _executed(p) and started not in p.parents),
    ]


def _executed(page: Path) -> bool:
    """Whether the page runs at build (a myst-nb notebook: ``file_format: mystnb``)."""
    return "file_format: mystnb" in page.read_text(encoding="utf-8")[:300]


def commands(text: str) -> list[str]:
    """The shell commands of the fenced shell blocks of ``text``, one string each.

    Continuation lines are joined; a command spanning lines inside quotes is one command;
    ``&&`` separates commands; comments are dropped.

    Examples
    --------
    >>> commands("```bash\\nspa a \\\\\\n  --b 1  # c\\nmake x && make y\\n```\\n")
    ['spa a --b 1', 'make x', 'make y']
    """
    found: list[str] = []
    for match in _FENCE.finditer(text):
        block = re.sub(r"\\\n\s*", " ", match.group(2))
        pending = ""
        for line in block.splitlines():
            pending = f"{pending}\n{line}" if pending else line
            try:
                words = shlex.split(pending, comments=True)
            except ValueError:  # an open quote: the command goes on
                continue
            pending = ""
            if not words:
                continue
            command = shlex.join(words)
            found += [part.strip() for part in command.split(" '&&' ")]
    return found


def shown_commands() -> list[tuple[str, str]]:
    """``(document, command)`` for every command shown, in order, without repeats."""
    seen: dict[str, str] = {}
    for doc in documents():
        for command in commands(doc.read_text(encoding="utf-8")):
            seen.setdefault(command, str(doc.relative_to(ROOT)))
    return [(doc, command) for command, doc in seen.items()]


def fill(command: str) -> str:
    for placeholder, value in _PLACEHOLDERS.items():
        command = command.replace(placeholder, value)
    return command


@pytest.fixture(scope="module")
def clone(small_source, tmp_path_factory) -> dict[str, Path]:
    """A scratch clone with the small configuration's results (the session's, shared with
    tests/test_getting_started.py), and one whose example has no dataset.yaml yet (for
    ``spa init``)."""
    from conftest import scratch_source

    blank = scratch_source(tmp_path_factory.mktemp("clone") / "blank")
    (blank / "raw" / "example" / "dataset.yaml").unlink()
    return {"work": small_source, "blank": blank}


def _env() -> dict[str, str]:
    env = dict(os.environ)
    env["PATH"] = os.pathsep.join((str(BIN), env.get("PATH", "")))
    env["PYTHONPATH"] = os.pathsep.join(p for p in (str(ROOT), env.get("PYTHONPATH", "")) if p)
    env["SPA_PROGRESS"] = "0"
    env["MPLBACKEND"] = "Agg"
    return env


def run_shell(argv: list[str], cwd: Path, timeout: float = 900) -> subprocess.CompletedProcess:
    return subprocess.run(
        argv, cwd=cwd, env=_env(), capture_output=True, text=True, timeout=timeout
    )


def plan(command: str) -> tuple[list[str], str] | None:
    """How a shown command is run: ``(argv, where)`` with where in {"work", "blank",
    "root"}; None for a command in :data:`NOT_RUN`."""
    argv = shlex.split(fill(command))
    head = argv[0]
    if head in NOT_RUN:
        return None
    if head.startswith(".venv/bin/"):
        argv[0] = str(BIN / head.removeprefix(".venv/bin/"))
        head = argv[0]
    if Path(head).name.startswith("python") and len(argv) > 1 and argv[1].endswith(".py"):
        return [argv[0], argv[1], "--help"], "work"  # a benchmark: it exists and parses
    if Path(head).name.startswith("python") and argv[1:4] == ["-m", "pip", "install"]:
        # the install page's notebook route, resolved without installing anything
        # (tests/test_install_pip.py installs it into a scratch folder)
        opts = ["--dry-run", "--no-deps", "--no-build-isolation", "--no-index", "--quiet"]
        return [sys.executable, "-m", "pip", "install", *opts, *argv[4:]], "root"
    name = Path(head).name  # `.venv/bin/snakemake` is snakemake too
    if head == "make":
        return ["make", "-n", *argv[1:]], "root"
    if name == "spa":
        return argv, "blank" if argv[1:2] == ["init"] else "work"
    if name == "snakemake":
        small = "config/small.yaml" in argv
        if "--report" in argv and not small:
            argv += ["--configfile", "config/small.yaml"]  # a report of the run made here
        elif not small or "--profile" in argv:
            argv += ["--dry-run", "--quiet", "rules"]
        return argv, "work"
    return argv, "work"


def test_the_commands_are_found():
    shown = [c for _, c in shown_commands()]
    assert any(c.startswith("spa init") for c in shown)
    assert any(c.startswith("spa export-controller") for c in shown)
    assert "snakemake reproduce-all --configfile config/small.yaml" in shown
    assert "make reproduce" in shown and "make test" in shown
    assert all(plan(c) is not None or c.split()[0] in NOT_RUN for c in shown)


@pytest.mark.parametrize(("doc", "command"), shown_commands(), ids=lambda x: x[:70])
def test_every_shown_command_runs(clone, doc, command):
    how = plan(command)
    if how is None:
        pytest.skip(f"{command.split()[0]}: {NOT_RUN[command.split()[0]]}")
    argv, where = how
    cwd = ROOT if where == "root" else clone[where]
    res = run_shell(argv, cwd)
    assert res.returncode == 0, (
        f"{doc}: `{command}` (run as {shlex.join(argv)}) exited {res.returncode}\n"
        + res.stdout[-3000:]
        + res.stderr[-3000:]
    )
