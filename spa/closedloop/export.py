"""The designed controller as portable code: a dependency-free C99 header and a sketch.

:func:`controller_header` writes one controller (a :class:`~spa.closedloop.PIController`,
fixed, scheduled or with feed-forward) and one modulator setting as a single C99 header: the
step ``dt`` as a constant, the gain schedule and feed-forward as tables, one state struct,
``<prefix>_init`` and ``<prefix>_step(state, r, p)`` returning the valve command and ``xi``.
The PI law is docs/model.md section 8 with the operations of
:func:`spa.closedloop.loop.simulate_closed_loop` in the same order; the modulator's per-step
law is the ``C_STEP`` text of its kernel module (:mod:`spa.model.modulators.kernels`), so
nothing here names a kind. Every constant is written as the shortest decimal that reads back
as the same double, so a compiler that keeps IEEE double and does not contract
``a*b + c`` into a fused multiply-add (ISO C mode, ``-std=c99``, or ``-ffp-contract=off``)
gives the simulation's commands and ``xi`` (tests/test_export.py).
:func:`arduino_sketch` shows where the sensor read and the valve write go.
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping, Sequence
from pathlib import Path
from string import Template
from typing import Any

import numpy as np

from spa import _checks as checks
from spa.closedloop.controller import PIController
from spa.model.modulators import Modulator, check_settings
from spa.model.modulators.kernels import KERNELS
from spa.model.modulators.kernels._common import EPS
from spa.model.params import ValveParams

__all__ = [
    "FLASH_BUDGET",
    "PRECISIONS",
    "arduino_sketch",
    "c_double",
    "c_float",
    "controller_header",
    "export_designed",
    "write_controller",
]

_PREFIX = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")

#: The flash a header's constant tables may take, bytes: the gain schedule, the feed-forward,
#: the modulator's constants and, for a valve with its own laws, the tables the modulator
#: reads of them (LPWM's inverse: 257 doubles, 2056 bytes). The header's comment states
#: what it takes; :func:`controller_header` refuses a header beyond it.
FLASH_BUDGET = 4096

_PI = """
static ${real} ${p}_interp(${real} x, const ${real} *xp, const ${real} *fp, int n)
{
    int lo, hi, mid;
    if (n == 1 || x <= xp[0]) {
        return fp[0];
    }
    if (x >= xp[n - 1]) {
        return fp[n - 1];
    }
    lo = 0;
    hi = n - 1;
    while (hi - lo > 1) {
        mid = (lo + hi) / 2;
        if (xp[mid] <= x) {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    return fp[lo] + (x - xp[lo]) * (fp[lo + 1] - fp[lo]) / (xp[lo + 1] - xp[lo]);
}

/* Start (or restart) the controller: step 0, integrator at integral0 (input fraction),
 * the modulator at its initial state. */
static void ${p}_init(${p}_state *s, ${real} integral0)
{
    int i;
    s->k = 0;
    s->integral = integral0;
    s->r_prev = ${zero};
    s->kp = ${zero};
    s->ki = ${zero};
    s->ff = ${zero};
    for (i = 0; i < ${P}_N_STATE; ++i) {
        s->mod[i] = ${p}_initial[i];
    }
}

/* One controller step at t_k = k*${P}_DT: r the set-point and p the measured pressure at
 * t_k (bar). Returns the valve command to apply at once and hold until the next step
 * (1 = charge, 0 = exhaust) and xi, the PI's output (the input fraction). */
static ${p}_output ${p}_step(${p}_state *s, ${real} r, ${real} p)
{
    ${p}_output out;
    ${real} e, v;
    if (s->k == 0 || r != s->r_prev) {
        s->kp = ${p}_interp(r, ${p}_grid, ${p}_kp, ${P}_N_GRID);
        s->ki = ${p}_interp(r, ${p}_grid, ${p}_ki, ${P}_N_GRID);
        s->ff = ${p}_interp(r, ${p}_ff_r, ${p}_ff_xi, ${P}_N_FF);
        s->r_prev = r;
    }
    e = r - p;
    v = s->kp * e + s->integral + s->ff;
    out.xi = v < ${zero} ? ${zero} : (v > ${one} ? ${one} : v);
    if (!((v > ${one} && e > ${zero}) || (v < ${zero} && e < ${zero}))) {
        s->integral += s->ki * ${dt} * e;
    }
    out.valve = ${p}_mod_step(s->k, out.xi, ${p}_cfg, s->mod);
    s->k += 1;
    return out;
}
"""

_SKETCH = """// Arduino-style sketch for ${header} (spa export-controller): the PI and the modulator
// run every ${P}_DT s; fill in the two TODOs. It needs an IEEE double (a 32-bit ARM board
// such as a Teensy or a Due: on 8-bit AVR boards double is a 32-bit float).
#include "${header}"

const int VALVE_PIN = 8;  // TODO: the pin that drives the valve (HIGH = charge)
const unsigned long STEP_US = (unsigned long)(${P}_DT * 1e6 + 0.5);

${p}_state state;
unsigned long next_us;

double read_pressure_bar() {
  // TODO: the pressure sensor, in bar (the unit and zero the valve was identified in)
  return 0.0;
}

double setpoint_bar() {
  return ${r};  // TODO: the set-point, bar (inside the range the loop holds)
}

void setup() {
  pinMode(VALVE_PIN, OUTPUT);
  digitalWrite(VALVE_PIN, LOW);
  ${p}_init(&state, 0.0);  // from rest: integrator at 0
  next_us = micros();
}

void loop() {
  if ((long)(micros() - next_us) < 0) {
    return;  // wait for the next step: the law assumes a fixed step of ${P}_DT s
  }
  next_us += STEP_US;
  double p = read_pressure_bar();  // read first ...
  ${p}_output out = ${p}_step(&state, setpoint_bar(), p);
  digitalWrite(VALVE_PIN, out.valve ? HIGH : LOW);  // ... then write at once
}
"""


def c_double(x: float) -> str:
    """A C double literal that reads back as exactly ``x``: Python's shortest round-trip
    decimal (``repr``), which a correctly rounding C compiler reads as the same double.

    Raises
    ------
    ValueError
        For a non-finite value.

    Examples
    --------
    >>> c_double(0.1), c_double(20.0), c_double(1e-9)
    ('0.1', '20.0', '1e-09')
    """
    v = float(x)
    if not math.isfinite(v):
        raise ValueError(f"c_double: {v} has no C literal")
    return repr(v)


def c_float(x: float) -> str:
    """A C float literal (``f`` suffix) that reads back as the float nearest ``x``: numpy's
    shortest decimal that round-trips in single precision.

    Raises
    ------
    ValueError
        For a value that is not finite in single precision.

    Examples
    --------
    >>> c_float(0.1), c_float(20.0), c_float(1e-9)
    ('0.1f', '20.0f', '1e-09f')
    """
    with np.errstate(over="ignore"):
        v = np.float32(x)
    if not np.isfinite(v):
        raise ValueError(f"c_float: {float(x)} has no finite single-precision C literal")
    return c_double(float(str(v))) + "f"


#: The header's floating-point precision for the PI: C type and literal writer.
PRECISIONS = {"double": ("double", c_double), "single": ("float", c_float)}

#: A function definition of the generated text: ``static`` at the start of a line, not a table.
_STATIC_FUNCTION = re.compile(r"^static (?!const )", re.MULTILINE)


def _array(name: str, values: Sequence[float] | np.ndarray, precision: str = "double") -> str:
    ctype, literal = PRECISIONS[precision]
    items = ", ".join(literal(v) for v in np.asarray(values, dtype=np.float64))
    return f"static const {ctype} {name}[{len(values)}] = {{{items}}};"


def controller_header(
    modulator: Modulator | dict[str, Any],
    controller: PIController,
    dt: float,
    *,
    prefix: str = "spa_ctrl",
    note: str = "",
    precision: str = "double",
    params: ValveParams | None = None,
) -> str:
    """The C99 header of one controller and modulator setting.

    Parameters
    ----------
    modulator : Modulator or mapping
        The setting, e.g. ``{"type": "iipfm", "t_l": 0.02, "gain": 1.15}``.
    controller : PIController
        Fixed, scheduled or with feed-forward.
    dt : float
        The controller step, s (the modulator's clock too).
    prefix : str, optional
        Prefix of every name the header defines (a C identifier); the macros use it in
        upper case. Two headers with different prefixes can share a program.
    note : str, optional
        A line for the header's comment (e.g. where the design came from).
    precision : {"double", "single"}, optional
        ``"double"`` (default): every operation in IEEE double, the simulation's to the bit.
        ``"single"``: the PI (its tables, integrator, error, ``xi``, the arguments ``r`` and
        ``p``) in ``float`` with ``f`` literals, for boards whose FPU is single precision
        (Cortex-M4F); the modulator keeps its constants and state in double (it computes
        only at its events, and its step clock must not drift), so the header is the same
        law rounded differently: docs/howto/controller-on-bench.md states the agreement.
    params : ValveParams, optional
        The valve the controller was designed for, as :func:`spa.closedloop.loop.
        closed_loop_arrays` takes it: a modulator that reads the valve's laws (LPWM's
        inverse) gets their table from it; None or a valve without laws writes the paper's
        closed forms. The tables stay within :data:`FLASH_BUDGET` bytes.

    Returns
    -------
    str
        The header (every function ``static inline``, so a translation unit that includes it
        and calls nothing compiles warning-free): ``<prefix>_state``, ``<prefix>_output``
        (``valve``, ``xi``),
        ``<prefix>_init(&state, integral0)``, ``<prefix>_step(&state, r, p)`` and the
        macro ``<PREFIX>_DT``; only ``<math.h>`` is included.

    Raises
    ------
    ValueError
        For a bad prefix, step, controller, or a setting that does not fit the step, or
        tables beyond :data:`FLASH_BUDGET`.

    Examples
    --------
    >>> h = controller_header({"type": "pwm", "f_w": 20.0}, PIController(1.0, 2.0), 1e-3)
    >>> "spa_ctrl_step(spa_ctrl_state *s, double r, double p)" in h
    True
    """
    if not isinstance(prefix, str) or not _PREFIX.fullmatch(prefix):
        raise ValueError(f"prefix must be a C identifier, got {prefix!r}")
    if precision not in PRECISIONS:
        raise ValueError(f"precision must be one of {list(PRECISIONS)}, got {precision!r}")
    if not isinstance(controller, PIController):
        raise ValueError(f"controller must be a PIController, got {controller!r}")
    dt = checks.positive("dt", dt, "s")
    mod = Modulator.from_mapping(modulator)
    if mod.kind not in KERNELS:
        raise ValueError(f"no per-step law for modulator kind {mod.kind!r}")
    settings = dict(mod.settings)
    check_settings(mod.kind, dt, **settings)
    kernel = KERNELS[mod.kind]
    cfg = kernel.configure(settings, dt, params)
    grid, kp, ki, ff_r, ff_xi = controller.arrays()
    up = prefix.upper()
    # Flash: the PI's tables in the header's precision, the modulator's in double; of these,
    # the bytes the valve's laws add (the constants with and without them).
    width = 8 if precision == "double" else 4
    flash = width * sum(a.size for a in (grid, kp, ki, ff_r, ff_xi))
    flash += 8 * (cfg.size + len(kernel.INITIAL))
    law_bytes = 8 * (cfg.size - kernel.configure(settings, dt).size)  # without a valve
    if flash > FLASH_BUDGET:
        raise ValueError(
            f"the header's tables take {flash} bytes, beyond the flash budget of "
            f"{FLASH_BUDGET} bytes (fewer schedule or feed-forward nodes)"
        )
    subs = {"p": prefix, "P": up, "eps": c_double(EPS)}
    real, literal = PRECISIONS[precision]
    pi_subs = {
        **subs,
        "real": real,
        "zero": literal(0.0),
        "one": literal(1.0),
        "dt": f"{up}_DT" if precision == "double" else f"(({real}){up}_DT)",
    }
    kind = "gain-scheduled" if controller.scheduled else "fixed"
    ff = " with feed-forward" if controller.feedforward is not None else ""
    lines = [
        f"/* {up}: {kind} PI{ff} -> {mod.description} ({mod.label}), step {dt:g} s.",
        " * Generated by spa (spa export-controller); the law of docs/model.md section 8,",
        " * checked against spa.simulate_closed_loop to the bit (tests/test_export.py)."
        if precision == "double"
        else " * in double precision the simulation's to the bit (tests/test_export.py).",
        " * Compile as ISO C (-std=c99) or with -ffp-contract=off, IEEE double."
        if precision == "double"
        else " * Single precision: the PI in float (the modulator in double); its commands can"
        " differ\n * from the double-precision loop's (by how much:"
        " docs/howto/controller-on-bench.md).",
        f" * Setting: {mod.to_mapping()}",
        f" * Controller: {controller.to_mapping()}",
    ]
    inverted = [k for k in mod.spec.optional if k in settings]
    if inverted:
        lines.append(
            " * Inverted valve (the identified one): "
            + ", ".join(f"{k} = {settings[k]:.6g}" for k in inverted)
        )
    lines.append(
        f" * Flash: {flash} bytes of constant tables (budget {FLASH_BUDGET} bytes)"
        + (f", of which {law_bytes} the table of the valve's own laws." if law_bytes else ".")
    )
    if note:
        lines.append(f" * {note}")
    lines.append(" */")
    body = [
        "\n".join(lines),
        f"#ifndef {up}_H\n#define {up}_H\n\n#include <math.h>\n",
        f"#define {up}_DT {c_double(dt)} /* controller step, s */",
        f"#define {up}_N_GRID {grid.size}",
        f"#define {up}_N_FF {ff_r.size}",
        f"#define {up}_N_STATE {len(kernel.INITIAL)}\n",
        "/* Gains (1/bar, 1/(bar*s)) at the set-points of the grid (bar), the feed-forward",
        " * input fraction at its set-points: linear in the set-point, held outside. */",
        _array(f"{prefix}_grid", grid, precision),
        _array(f"{prefix}_kp", kp, precision),
        _array(f"{prefix}_ki", ki, precision),
        _array(f"{prefix}_ff_r", ff_r, precision),
        _array(f"{prefix}_ff_xi", ff_xi, precision),
        "/* The modulator's constants and initial state. */",
        _array(f"{prefix}_cfg", cfg),
        _array(f"{prefix}_initial", kernel.INITIAL) + "\n",
        "typedef struct {\n    long long k; /* steps since init */\n"
        f"    {real} integral; /* the PI's integrator, input fraction */\n"
        f"    {real} r_prev, kp, ki, ff; /* gains at the last set-point */\n"
        f"    double mod[{up}_N_STATE]; /* the modulator's state */\n}} {prefix}_state;\n",
        "typedef struct {\n    int valve; /* 1: charge, 0: exhaust, over the coming step */\n"
        f"    {real} xi; /* the PI's output, input fraction */\n}} {prefix}_output;",
        Template(kernel.C_STEP).substitute(subs).rstrip(),
        Template(_PI).substitute(pi_subs).rstrip(),
        f"\n#endif /* {up}_H */\n",
    ]
    return _STATIC_FUNCTION.sub("static inline ", "\n".join(body))


def arduino_sketch(
    header: str = "controller.h", prefix: str = "spa_ctrl", setpoint: float = 0.4
) -> str:
    """A minimal Arduino-style sketch that includes the file named ``header``;
    ``setpoint`` (bar) is its default set-point (choose one the loop holds).

    Examples
    --------
    >>> "spa_ctrl_step(&state, setpoint_bar(), p)" in arduino_sketch()
    True
    """
    if not _PREFIX.fullmatch(prefix):
        raise ValueError(f"prefix must be a C identifier, got {prefix!r}")
    return Template(_SKETCH).substitute(
        header=header, p=prefix, P=prefix.upper(), r=c_double(setpoint)
    )


def write_controller(
    folder: str | Path,
    modulator: Modulator | dict[str, Any],
    controller: PIController,
    dt: float,
    *,
    name: str = "controller",
    prefix: str = "spa_ctrl",
    note: str = "",
    precision: str = "double",
    setpoint: float = 0.4,
    params: ValveParams | None = None,
) -> tuple[Path, Path]:
    """Write ``<name>.h`` (:func:`controller_header`, in ``precision``, for the valve
    ``params``) and ``<name>.ino`` (:func:`arduino_sketch`, whose default set-point is
    ``setpoint`` bar) into ``folder``.

    Returns
    -------
    header, sketch : pathlib.Path
        The two files written (``folder`` is created if needed).
    """
    text = controller_header(
        modulator, controller, dt, prefix=prefix, note=note, precision=precision, params=params
    )
    out = Path(folder)
    out.mkdir(parents=True, exist_ok=True)
    header, sketch = out / f"{name}.h", out / f"{name}.ino"
    header.write_text(text, encoding="utf-8")
    sketch.write_text(arduino_sketch(header.name, prefix, setpoint), encoding="utf-8")
    return header, sketch


def export_designed(
    folder: str | Path,
    params: Any,
    modulator: Modulator | dict[str, Any],
    *,
    controller: str = "scheduled_ff",
    tau_c: float | None = None,
    levels: Sequence[float] | None = None,
    dt: float = 0.001,
    note: str = "",
    precision: str = "double",
    unresolved: Mapping[str, tuple[float, float]] | None = None,
) -> tuple[Path, Path]:
    """Design the PIs for a valve and a setting (as the ``closed_loop`` stage does) and write
    the header and sketch of one of them (``spa export-controller``).

    Parameters
    ----------
    folder : str or pathlib.Path
        Where ``controller.h`` and ``controller.ino`` go.
    params : ValveParams
        The identified valve.
    modulator : Modulator or mapping
        The setting.
    controller : {"fixed", "scheduled", "scheduled_ff"}
        Which of :func:`spa.closedloop.design.design_pi`'s controllers.
    tau_c, levels, dt : optional
        SIMC's closed-loop time constant (s), the schedule's set-points (bar) and the step
        (s); the ``closed_loop`` stage's defaults (levels below 0.95*k2) when omitted.
    note : str, optional
        A line for the header's comment.
    precision : {"double", "single"}, optional
        The header's PI arithmetic (:func:`controller_header`).
    unresolved : mapping, optional
        The delays the data do not resolve, ``name -> (lo, hi)`` s
        (:func:`spa.closedloop.delays.unresolved_delays`): the header's comment says the
        controller was designed at a value they do not fix, and what to record.

    Returns
    -------
    header, sketch : pathlib.Path

    Raises
    ------
    ValueError
        For an unknown controller name, fewer than two levels, or a design that fails.
    """
    from spa.closedloop.choice import CONTROLLERS
    from spa.closedloop.comparison import DEFAULTS
    from spa.closedloop.design import design_pi

    if controller not in CONTROLLERS:
        raise ValueError(f"controller must be one of {list(CONTROLLERS)}, got {controller!r}")
    tau = float(DEFAULTS["tau_c"] if tau_c is None else tau_c)
    # An LPWM that omits its valve inverts the identified one, not the nominal valve.
    modulator = Modulator.from_mapping(modulator).bind(params)
    if levels is None:
        from spa.closedloop.comparison import setting_levels

        found, skipped, _ = setting_levels([modulator], params, DEFAULTS)
        if modulator.label not in found:
            raise ValueError(skipped.get(modulator.label, f"{modulator.label}: no levels"))
        levels = found[modulator.label]
    if len(levels) < 2:
        raise ValueError(f"levels: need at least two set-points, got {list(levels)}")
    designs = design_pi(modulator, params, levels=levels, tau_c=tau)
    text = note or f"SIMC, tau_c = {tau:g} s, schedule over {list(levels)} bar."
    if unresolved:
        from spa.closedloop.delays import unresolved_sentence

        text += " " + unresolved_sentence(unresolved, checked=False)
    mid = float(f"{float(np.median(levels)):.3g}")
    return write_controller(
        folder, modulator, designs[controller], dt, note=text, precision=precision,
        setpoint=mid, params=params,
    )  # fmt: skip
