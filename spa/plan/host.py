"""The player on the host: its header and harness compiled, closed on a plant.

:func:`build_harness` compiles ``player/harness.c`` under ``-std=c99 -Wall -Wextra
-pedantic -Werror``. :func:`play_session` runs the compiled player on a plant given as a
function from the valve command to the pressure (spa's model, :func:`spa.simulate`, or the
physical plant's C twin, :func:`spa.synthetic.physical.run_plant_in_c`). The player reads a
pressure before it commands, so the loop is solved by iteration: commands → pressure → the
player's commands, until they repeat (each pass fixes at least one more tick; the player
only departs from its plan when it vents).
"""

from __future__ import annotations

import shutil
import subprocess
from collections.abc import Callable
from pathlib import Path

import numpy as np
import numpy.typing as npt

from spa.plan.design import SessionDesign
from spa.plan.session import run_commands

__all__ = ["STRICT", "build_harness", "counts", "planned_commands", "play_session"]

#: The flags the player must build under.
STRICT = ("-std=c99", "-Wall", "-Wextra", "-pedantic", "-Werror", "-O2", "-ffp-contract=off")


def build_harness(folder: str | Path, out: str | Path, cc: str = "cc") -> Path:
    """Compile a plan folder's host harness into ``out`` (an executable path).

    Raises
    ------
    FileNotFoundError
        If no compiler ``cc`` is on PATH.
    RuntimeError
        If the build fails, with the compiler's message.
    """
    compiler = shutil.which(cc)
    if compiler is None:
        raise FileNotFoundError(f"no C compiler: {cc!r} is not on PATH")
    player = Path(folder) / "player"
    cmd = [compiler, *STRICT, f"-I{player}", str(player / "harness.c"), "-o", str(out), "-lm"]
    res = subprocess.run(cmd, capture_output=True, text=True, check=False)
    if res.returncode != 0:
        raise RuntimeError(f"building the player failed ({' '.join(cmd)}):\n{res.stderr}")
    return Path(out)


def planned_commands(design: SessionDesign) -> npt.NDArray[np.int8]:
    """Every tick's command of the session as spa simulates the plan: each run's
    (:func:`spa.plan.session.run_commands`), then the exhaust between runs."""
    rest = np.zeros(round(design.rest / design.dt), dtype=np.int8)
    parts = []
    for run in design.runs:
        parts += [run_commands(run, design.dt), rest]
    return np.concatenate(parts)


def counts(p: npt.ArrayLike, cal: dict) -> npt.NDArray[np.int64]:
    """ADC counts of a pressure (bar) under the declared calibration, within the ADC."""
    c = np.floor(np.asarray(p) / cal["bar_per_count"] + cal["zero_counts"] + 0.5)
    return np.clip(c, 0, 2 ** int(cal["adc_bits"]) - 1).astype(np.int64)


def play_session(
    exe: str | Path,
    design: SessionDesign,
    plant: Callable[[npt.NDArray[np.int8]], npt.NDArray[np.float64]],
    cal: dict,
    noise: npt.ArrayLike | None = None,
    max_passes: int = 50,
) -> tuple[str, npt.NDArray[np.int8], int]:
    """Run the compiled player closed on ``plant``.

    Parameters
    ----------
    exe : path
        :func:`build_harness`'s executable.
    design : SessionDesign
        The plan it was written from.
    plant : callable
        Valve command per tick → the pressure read at each tick (bar gauge).
    cal : dict
        The declared calibration (``plan.yaml``'s).
    noise : array_like, optional
        Sensor noise added to the pressure, bar, per tick.
    max_passes : int
        Passes of the iteration before giving up.

    Returns
    -------
    stream : str
        What the player printed.
    commands : numpy.ndarray of int8
        The valve command it issued at every tick.
    passes : int
        Passes the iteration took.

    Raises
    ------
    RuntimeError
        If the player fails or the loop does not settle.
    """
    u = planned_commands(design)
    extra = np.zeros(u.size) if noise is None else np.asarray(noise, dtype=np.float64)
    trace = Path(str(exe) + ".trace")
    for n in range(1, max_passes + 1):
        adc = counts(plant(u) + extra, cal)
        res = subprocess.run(
            [str(exe), str(trace)],
            input="\n".join(map(str, adc.tolist())) + "\n",
            capture_output=True,
            text=True,
            check=False,
        )
        if res.returncode != 0:
            raise RuntimeError(f"the player failed (exit {res.returncode}): {res.stderr}")
        got = np.frombuffer(trace.read_bytes(), dtype=np.uint8) - ord("0")
        got = got.astype(np.int8)
        if got.size == u.size and np.array_equal(got, u):
            return res.stdout, got, n
        if got.size != u.size:
            raise RuntimeError(f"the player issued {got.size} commands, the plan has {u.size}")
        u = got
    raise RuntimeError(f"the loop did not settle in {max_passes} passes")
