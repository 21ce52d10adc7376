"""How the site is built and judged, for ``make docs``, the suite and the benchmark alike.

Sphinx runs with warnings as errors (``-W --keep-going``: every warning is reported, then
the build fails) and writes its warnings and errors to a file of their own (``-w``). The
verdict is Sphinx's: its exit status and that file. What the executed pages' kernels print
on stderr as they are shut down (libzmq's ``Assertion failed: pfd.revents & POLLIN``,
tornado's ``ZMQStream`` tracebacks) is theirs, says nothing of the pages, and is not read.
"""

from __future__ import annotations

import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path


@dataclass(frozen=True)
class Verdict:
    """One build: ``ok`` when Sphinx exited 0 and wrote no warning; ``warnings`` is the
    warnings file's text, ``output`` what Sphinx and the pages' kernels printed, ``seconds``
    the wall time."""

    ok: bool
    returncode: int
    warnings: str
    output: str
    seconds: float


def command(src: Path, out: Path, warnings: Path, *extra: str) -> list[str]:
    """The ``sphinx-build`` command of the site: HTML from ``src`` into ``out/html``,
    doctrees in ``out/doctrees``, warnings into ``warnings``; ``extra`` are more options
    (``-D name=value``)."""
    return [sys.executable, "-m", "sphinx", "-b", "html", "-W", "--keep-going", "-j", "auto",
            "-q", "-w", str(warnings), "-d", str(out / "doctrees"), *extra, str(src),
            str(out / "html")]  # fmt: skip


def build(src: Path, out: Path, *extra: str, cwd: Path | None = None) -> Verdict:
    """Build the site of ``src`` into ``out`` (see :func:`command`) and judge it."""
    out.mkdir(parents=True, exist_ok=True)
    warnings = out / "warnings.txt"
    warnings.unlink(missing_ok=True)
    start = time.perf_counter()
    res = subprocess.run(
        command(src, out, warnings, *extra), capture_output=True, text=True, cwd=cwd,
        timeout=3600,
    )  # fmt: skip
    said = warnings.read_text(encoding="utf-8") if warnings.exists() else ""
    return Verdict(
        ok=res.returncode == 0 and said.strip() == "",
        returncode=res.returncode,
        warnings=said,
        output=res.stdout + res.stderr,
        seconds=time.perf_counter() - start,
    )
