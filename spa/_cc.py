"""One C build for the C twins and players spa compiles (the physical plant, the model
plant, a plan's player): the compiler looked up on PATH, one command, its message kept."""

from __future__ import annotations

import shutil
import subprocess
from collections.abc import Sequence
from pathlib import Path

__all__ = ["build_c", "find_cc"]


def find_cc(cc: str = "cc") -> str:
    """The compiler ``cc``'s path on PATH.

    Raises
    ------
    FileNotFoundError
        If ``cc`` is not on PATH.
    """
    compiler = shutil.which(cc)
    if compiler is None:
        raise FileNotFoundError(f"no C compiler: {cc!r} is not on PATH")
    return compiler


def build_c(
    sources: Sequence[str | Path],
    exe: str | Path,
    *,
    flags: Sequence[str],
    includes: Sequence[str | Path] = (),
    cc: str = "cc",
    what: str = "building the C program",
) -> Path:
    """Compile and link ``sources`` into ``exe`` (``cc flags -I... sources -o exe -lm``).

    Parameters
    ----------
    sources : sequence of path
        The C sources, in the command's order.
    exe : path
        The executable to write.
    flags : sequence of str
        The compiler's flags, before the include folders.
    includes : sequence of path, optional
        Folders for ``-I``, in order.
    cc : str, default "cc"
        The compiler, looked up on PATH.
    what : str, optional
        What the build is, for the error (``"<what> failed (<command>): <stderr>"``).

    Returns
    -------
    pathlib.Path
        ``exe``.

    Raises
    ------
    FileNotFoundError
        If ``cc`` is not on PATH.
    RuntimeError
        If the build fails, with the command and the compiler's message.

    Examples
    --------
    >>> build_c(["main.c"], "main", flags=(), cc="no-such-cc-here")
    Traceback (most recent call last):
    ...
    FileNotFoundError: no C compiler: 'no-such-cc-here' is not on PATH
    """
    cmd = [find_cc(cc), *flags, *(f"-I{p}" for p in includes), *map(str, sources)]
    cmd += ["-o", str(exe), "-lm"]
    res = subprocess.run(cmd, capture_output=True, text=True, check=False)
    if res.returncode != 0:
        raise RuntimeError(f"{what} failed ({' '.join(cmd)}):\n{res.stderr}")
    return Path(exe)
