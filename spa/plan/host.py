"""The player on the host: its header and harness compiled, closed on a plant.

:func:`build_harness` compiles ``player/harness.c`` under ``-std=c99 -Wall -Wextra
-pedantic -Werror``. :func:`play_session` runs the compiled player on a plant given as a
function from the valve command to the pressure (spa's model, :func:`spa.simulate`, or the
physical plant's C twin, :func:`spa.synthetic.physical.run_plant_in_c`). The player reads a
pressure before it commands, so the loop is solved by iteration: commands → pressure → the
player's commands, until they repeat (each pass fixes at least one more tick; the player
only departs from its plan when it vents). :func:`play_on_physical` compiles the player with
the physical plant's C twin into one program instead, closed tick by tick: the way to play a
session with closed-loop runs, whose commands follow the pressure. :func:`play_on_model` does
the same on spa's model plant in C (``model_plant.c``, :func:`spa.simulate` stepped tick by
tick), and :func:`play_on_plant` picks one of the two by the plant given.
"""

from __future__ import annotations

import subprocess
from collections.abc import Callable
from pathlib import Path

import numpy as np
import numpy.typing as npt

from spa._cc import build_c, find_cc
from spa.model.params import ValveParams
from spa.plan.design import SessionDesign
from spa.plan.session import run_commands

__all__ = [
    "STRICT",
    "build_harness",
    "counts",
    "planned_commands",
    "play_on_model",
    "play_on_physical",
    "play_on_plant",
    "play_session",
    "session_ticks",
]

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
    player = Path(folder) / "player"
    build_c(
        [player / "harness.c"],
        out,
        flags=STRICT,
        includes=[player],
        cc=cc,
        what="building the player",
    )
    return Path(out).resolve()  # absolute: a bare name would be looked up on PATH


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
    exe = Path(exe).resolve()  # a bare name such as "player" would be looked up on PATH
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


_HARNESS = r"""/* The spa plan player closed on @WHAT@, tick by tick: the
 * sensor (@SENSOR@ + noise, ADC counts as declared) read, the player's tick, the plant
 * advanced over the tick with its command. Prints the board's stream; the valve commands
 * into argv[1]. stdin: the plant's constants, then one noise value (bar) per tick. */
#include <math.h>
#include <stdio.h>
#include "player.h"
#include "@HEADER@"
static @STATE@ plant;
static spa_plan_state s;
static double next_noise(void) { double v; return scanf("%lf", &v) == 1 ? v : 0.0; }
static long read_adc(double zero, double bpc, long top)
{
    double c = floor((@PRESSURE@ + next_noise()) / bpc + zero + 0.5);
    return c < 0.0 ? 0L : (c > (double)top ? top : (long)c);
}
int main(int argc, char **argv)
{
    FILE *trace = fopen(argc > 1 ? argv[1] : "trace.txt", "w");
    double c[@N_CONST@], zero, bpc;
    long top, adc, q, r, tick;
    int i, @INTS@run, valve, log, last;
    if (trace == NULL) return 2;
    for (i = 0; i < @N_CONST@; ++i) {
        if (scanf("%lf", &c[i]) != 1) return 2;
    }
    @READ@
    @INIT@
    for (run = 0; run < SPA_PLAN_N_RUNS; ++run) {
        spa_plan_start(&s, run);
        printf("R %d\n", run);
        do {
            tick = s.k;
            adc = read_adc(zero, bpc, top);
            last = spa_plan_tick(&s, adc, &valve, &q, &log);
            fputc(valve ? '1' : '0', trace);
            if (log) printf("%lx,%lx,%d,%lx\n", tick & 0xFFFFL, adc, valve, q);
            if (@STEP@(&plant, valve) != 0) return 3;
        } while (!last);
        printf("E %d %s\n", run, s.vented ? "vent" : "done");
        for (r = 0; r < SPA_PLAN_REST_TICKS; ++r) {
            adc = read_adc(zero, bpc, top);
            fputc('0', trace);
            if (@STEP@(&plant, 0) != 0) return 3;
        }
    }
    fclose(trace);
    return 0;
}
"""

#: The plants the harness closes the player on: the physical plant's C twin, and spa's model
#: plant in C (``spa.simulate`` stepped tick by tick); each fills :data:`_HARNESS`'s slots.
_PLANTS: dict[str, dict[str, str]] = {
    "physical": {
        "@WHAT@": "the physical plant's C twin",
        "@SENSOR@": "lagged pressure",
        "@HEADER@": "physical_plant.h",
        "@STATE@": "spa_phys_state",
        "@PRESSURE@": "spa_phys_lagged(&plant) / 1e5",
        "@N_CONST@": "SPA_PHYS_N_CONST",
        "@INTS@": "nsub, ",
        "@READ@": 'if (scanf("%d %lf %lf %ld", &nsub, &zero, &bpc, &top) != 4) return 2;',
        "@INIT@": "spa_phys_init(&plant, c, SPA_PLAN_DT, nsub, 0.0, 0);",
        "@STEP@": "spa_phys_step",
    },
    "model": {
        "@WHAT@": "spa's model plant in C (model_plant.c)",
        "@SENSOR@": "the model's pressure",
        "@HEADER@": "model_plant.h",
        "@STATE@": "spa_model_state",
        "@PRESSURE@": "spa_model_pressure(&plant)",
        "@N_CONST@": "SPA_MODEL_N_CONST",
        "@INTS@": "",
        "@READ@": 'if (scanf("%lf %lf %ld", &zero, &bpc, &top) != 3) return 2;',
        "@INIT@": "spa_model_init(&plant, c, SPA_PLAN_DT, 0.0, 0);",
        "@STEP@": "spa_model_step",
    },
}


def _harness(plant: str) -> str:
    """The harness's C main for ``plant`` (a key of :data:`_PLANTS`)."""
    text = _HARNESS
    for slot, value in _PLANTS[plant].items():
        text = text.replace(slot, value)
    return text


def session_ticks(folder: str | Path) -> int:
    """The ticks a plan folder's session plays: its runs and the rests between them
    (``plan.yaml``)."""
    from spa.plan.record import read_plan

    plan = read_plan(folder)
    dt = float(plan["tick"])
    rest = round(float(plan["rest_between_runs"]) / dt)
    return sum(round(float(r["seconds"]) / dt) + rest for r in plan["runs"])


def _play_compiled(
    folder: str | Path,
    main_text: str,
    plant_source: tuple[Path, Path],
    head: str,
    noise: npt.ArrayLike | None,
    work: str | Path | None,
    cc: str,
) -> tuple[str, npt.NDArray[np.int8]]:
    """Compile ``main_text`` with a folder's player and a plant's C source, and run it: the
    plant's constants line ``head``, then one noise value per tick played."""
    find_cc(cc)  # before the program's source is written next to the plan
    player = Path(folder) / "player"
    out = Path(work) if work is not None else Path(folder).parent
    out.mkdir(parents=True, exist_ok=True)
    source, header = plant_source
    main = out / f"on-plant-{Path(folder).name}.c"
    main.write_text(main_text, encoding="utf-8")
    exe = build_c(
        [main, source],
        out / f"on-plant-{Path(folder).name}",
        flags=STRICT,
        includes=[player, header.parent],
        cc=cc,
        what="building the player on the plant",
    )
    n = session_ticks(folder)
    extra = np.zeros(n) if noise is None else np.asarray(noise, dtype=np.float64)
    if extra.size < n:
        raise ValueError(f"noise: {extra.size} values for the {n} ticks the session plays")
    trace = Path(str(exe) + ".trace")
    res = subprocess.run(
        [str(exe), str(trace)],
        input=head + "\n".join(map(repr, extra[:n].tolist())) + "\n",
        capture_output=True,
        text=True,
        check=False,
    )
    if res.returncode != 0:
        raise RuntimeError(f"the player on the plant failed (exit {res.returncode}): {res.stderr}")
    got = (np.frombuffer(trace.read_bytes(), dtype=np.uint8) - ord("0")).astype(np.int8)
    return res.stdout, got


def _calibration_line(cal: dict) -> str:
    top = 2 ** int(cal["adc_bits"]) - 1
    return f"{float(cal['zero_counts'])!r} {float(cal['bar_per_count'])!r} {top}\n"


def play_on_physical(
    folder: str | Path,
    plant: object,
    noise: npt.ArrayLike | None = None,
    work: str | Path | None = None,
    cc: str = "cc",
) -> tuple[str, npt.NDArray[np.int8]]:
    """Compile a plan folder's player with the physical plant's C twin and play the whole
    session closed on it, tick by tick (closed-loop runs included), as the folder says:
    its tick, rests and calibration from ``plan.yaml``.

    Parameters
    ----------
    folder : path
        The plan's folder (``player/player.h``, and ``player/controller.h`` if it closes a
        loop).
    plant : spa.synthetic.physical.PhysicalPlant
        The plant; its sensor is read as its lagged pressure plus ``noise``.
    noise : array_like, optional
        Sensor noise per tick played, bar (runs and rests: :func:`session_ticks` values).
    work : path, optional
        Where the program is built (default: ``folder``'s parent).
    cc : str, default "cc"
        The C compiler.

    Returns
    -------
    stream : str
        What the player printed.
    commands : numpy.ndarray of int8
        The valve command at every tick played (the rests' 0 included).

    Raises
    ------
    FileNotFoundError
        If no compiler ``cc`` is on PATH.
    ValueError
        For too few noise values, or a tick the plant cannot step.
    RuntimeError
        If the build or the run fails.
    """
    from spa.plan.record import read_plan
    from spa.synthetic._physical_c import c_plant_source
    from spa.synthetic._physical_core import _check_dt, _constants, substeps

    plan = read_plan(folder)
    dt = _check_dt(plant, float(plan["tick"]))  # type: ignore[arg-type]
    head = " ".join(repr(float(v)) for v in _constants(plant))  # type: ignore[arg-type]
    head += f" {substeps(plant, dt)} " + _calibration_line(plan["calibration"])  # type: ignore[arg-type]
    return _play_compiled(folder, _harness("physical"), c_plant_source(), head, noise, work, cc)


def play_on_model(
    folder: str | Path,
    params: ValveParams,
    noise: npt.ArrayLike | None = None,
    work: str | Path | None = None,
    cc: str = "cc",
) -> tuple[str, npt.NDArray[np.int8]]:
    """Compile a plan folder's player with spa's model plant in C (``model_plant.c``:
    :func:`spa.simulate` of ``params``, stepped tick by tick) and play the whole session
    closed on it (closed-loop runs included), as :func:`play_on_physical` does on the
    physical plant. The model starts at 0 bar, settled with the exhaust open; its sensor
    reads the model's pressure plus ``noise``.

    Parameters
    ----------
    folder : path
        The plan's folder.
    params : ValveParams
        The valve, either delay convention; the paper's laws only.
    noise : array_like, optional
        Sensor noise per tick played, bar (:func:`session_ticks` values).
    work : path, optional
        Where the program is built (default: ``folder``'s parent).
    cc : str, default "cc"
        The C compiler.

    Returns
    -------
    stream : str
        What the player printed.
    commands : numpy.ndarray of int8
        The valve command at every tick played (the rests' 0 included).

    Raises
    ------
    FileNotFoundError
        If no compiler ``cc`` is on PATH.
    ValueError
        For a valve with its own laws (not in C:
        :func:`spa.synthetic._model_c.model_constants`), or too few noise values.
    RuntimeError
        If the build or the run fails.
    """
    from spa.plan.record import read_plan
    from spa.synthetic._model_c import model_constants, model_plant_source

    consts = model_constants(params)
    plan = read_plan(folder)
    head = " ".join(map(repr, consts)) + " " + _calibration_line(plan["calibration"])
    return _play_compiled(folder, _harness("model"), model_plant_source(), head, noise, work, cc)


def play_on_plant(
    folder: str | Path,
    plant: object,
    noise: npt.ArrayLike | None = None,
    work: str | Path | None = None,
    cc: str = "cc",
) -> tuple[str, npt.NDArray[np.int8]]:
    """:func:`play_on_model` for a :class:`~spa.model.params.ValveParams`,
    :func:`play_on_physical` for a physical plant."""
    if isinstance(plant, ValveParams):
        return play_on_model(folder, plant, noise, work, cc)
    return play_on_physical(folder, plant, noise, work, cc)
