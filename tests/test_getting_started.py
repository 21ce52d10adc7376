"""The tutorial copies into a terminal: every block a reader sees on the getting-started
tutorial (docs/getting-started/your-lab.md) runs, in the page's order, the shell blocks with
bash in a fresh folder laid out like the source folder, the Python blocks in a fresh
interpreter started there (each with the page's Python blocks before it, as one session
would have run them). Hidden cells (the page's own machinery) are not the reader's and are
left out. Any error fails the test, naming the block."""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
TUTORIAL = ROOT / "docs" / "getting-started" / "your-lab.md"

_BLOCK = re.compile(
    r"^```(bash|\{code-cell\} ipython3)\n((?::[^\n]*\n)*)(.*?)^```", flags=re.S | re.M
)


def reader_blocks(text: str) -> list[tuple[str, str]]:
    """``(language, code)`` of every block a reader sees and copies, in order: shell blocks
    and code cells that are not hidden (``remove-input``/``remove-cell``).

    >>> reader_blocks("```bash\\nls\\n```\\n```{code-cell} ipython3\\n:tags: [remove-cell]\\n"
    ...               "x = 1\\n```\\n```{code-cell} ipython3\\nprint(2)\\n```\\n")
    [('bash', 'ls\\n'), ('python', 'print(2)\\n')]
    """
    blocks = []
    for lang, options, code in _BLOCK.findall(text):
        if re.search(r"remove-(?:input|cell)", options):
            continue
        blocks.append(("bash" if lang == "bash" else "python", code))
    return blocks


def test_the_blocks_are_plain_shell_and_python():
    blocks = reader_blocks(TUTORIAL.read_text(encoding="utf-8"))
    assert [lang for lang, _ in blocks].count("bash") >= 8
    assert any("snakemake reproduce-all" in code for lang, code in blocks if lang == "bash")
    assert any("spa export-controller" in code for lang, code in blocks if lang == "bash")
    for lang, code in blocks:
        if lang == "python":  # IPython syntax does not paste into a Python session
            assert not re.search(r"^\s*[!%]", code, flags=re.M), code
    python = "".join(code for lang, code in blocks if lang == "python")
    assert "from pathlib import Path" in python  # imports visible, not in a hidden cell


def _env() -> dict[str, str]:
    env = dict(os.environ)
    env["PATH"] = os.pathsep.join((str(Path(sys.executable).parent), env.get("PATH", "")))
    env["PYTHONPATH"] = os.pathsep.join(p for p in (str(ROOT), env.get("PYTHONPATH", "")) if p)
    env["SPA_PROGRESS"] = "0"
    env["MPLBACKEND"] = "Agg"
    return env


def test_every_block_of_the_tutorial_runs_in_order_in_a_fresh_folder(tmp_path):
    work = tmp_path / "spa-pipeline"
    work.mkdir()
    for name in ("Snakefile", "workflow", "config", "profiles"):
        (work / name).symlink_to(ROOT / name)
    (work / "raw").mkdir()
    session = ""
    for i, (lang, code) in enumerate(reader_blocks(TUTORIAL.read_text(encoding="utf-8"))):
        if lang == "bash" and re.search(r"^cc ", code, flags=re.M) and not shutil.which("cc"):
            pytest.skip("no C compiler (`make test` installs gcc)")
        if lang == "bash":
            argv = ["bash", "-e", "-c", code]
        else:
            session += code + "\n"
            argv = [sys.executable, "-c", session]
        res = subprocess.run(argv, cwd=work, env=_env(), capture_output=True, text=True,
                             timeout=1800)  # fmt: skip
        assert res.returncode == 0, (
            f"block {i} ({lang}) of {TUTORIAL.name} failed:\n{code}\n"
            + res.stdout[-3000:] + res.stderr[-3000:]
        )  # fmt: skip
    assert (work / "board" / "controller.h").is_file()
    assert "failed: []" in (work / "results" / "status.yaml").read_text()
