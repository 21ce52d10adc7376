"""The player: a C99 header that plays a planned session tick by tick through spa's own
modulator step (the ``C_STEP`` text of :mod:`spa.model.modulators.kernels`, the exported
controller's), a host harness (reads ADC counts from stdin, prints the stream) and an
Arduino-style sketch.

Each tick, in this order (:data:`TICK_ORDER`): read the pressure, vent if it is above the
rated maximum, compute the command, issue it, print ``tick,adc,valve,q`` (hex tick counter
mod 65536, hex ADC counts, the valve, the Q15 input fraction in hex). A run starts with a
line ``R <index>`` and ends with ``E <index> done`` or ``E <index> vent``; after each run
the valve exhausts for the rest between runs (the watchdog), and a line the link cannot
take vents and stops the session. A tick that starts a whole step late prints ``O <steps>``
(an overrun) before its line.
"""

from __future__ import annotations

from string import Template

from spa.closedloop.export import c_double
from spa.model.modulators.kernels import KERNELS
from spa.model.modulators.kernels._common import EPS
from spa.plan.session import MODES, Q15, PlannedRun

__all__ = ["TICK_ORDER", "harness_source", "player_header", "player_sketch"]

#: What the player does within each tick, in order (``plan.yaml`` declares it).
TICK_ORDER = ("read pressure", "vent check", "command", "write valve", "print sample")

_BODY = r"""
typedef struct {
    long ticks;
    unsigned char mode, log;
    spa_real a, b, c, d;
} spa_plan_segment;

typedef struct {
    int first, count, mod;
} spa_plan_run;

static const spa_plan_segment spa_plan_segments[SPA_PLAN_N_SEGMENTS] SPA_PLAN_ROM = {
${segments}
};

static const spa_plan_run spa_plan_runs[SPA_PLAN_N_RUNS] SPA_PLAN_ROM = {
${runs}
};

/* The input fraction of a segment at its tick k, in Q15 (the player's arithmetic: float). */
static long spa_plan_q(const spa_plan_segment *g, long k)
{
    spa_real kk = (spa_real)k, x;
    switch (g->mode) {
    case ${level}: x = g->a; break;
    case ${sine}: x = g->a + g->b * (spa_real)sin(kk * g->c); break;
    case ${chirp}: x = g->a + g->b * (spa_real)sin(kk * g->c + (kk * kk) * g->d); break;
    default: x = g->a + (spa_real)(k / (long)g->c) * g->b; break;
    }
    x = (spa_real)floor(x * (spa_real)${Q} + (spa_real)0.5);
    return x < 0 ? 0L : (x > (spa_real)${Q} ? ${Q}L : (long)x);
}

static int spa_plan_mod_step(int mod, long long k, double xi, double *st)
{
    (void)k;
    (void)xi;
    (void)st;
    switch (mod) {
${dispatch}
    default: return 0;
    }
}

static void spa_plan_mod_init(int mod, double *st)
{
    int i;
    for (i = 0; i < SPA_PLAN_N_STATE; ++i) st[i] = 0.0;
    switch (mod) {
${inits}
    default: break;
    }
}

/* The player's state within a session. */
typedef struct {
    int run;          /* the run playing */
    int seg;          /* its segment */
    long k;           /* tick within the run */
    long k_seg;       /* tick within the segment */
    int vented;       /* 1 once the pressure passed the rated maximum in this run */
    double st[SPA_PLAN_N_STATE];
#ifdef SPA_PLAN_LOOP
    SPA_PLAN_CTRL(state) ctrl; /* the exported controller's, restarted with each run */
#endif
} spa_plan_state;

static void spa_plan_start(spa_plan_state *s, int run)
{
    spa_plan_run r;
    SPA_PLAN_LOAD(r, spa_plan_runs[run]);
    s->run = run;
    s->seg = r.first;
    s->k = 0;
    s->k_seg = 0;
    s->vented = 0;
    spa_plan_mod_init(r.mod, s->st);
#ifdef SPA_PLAN_LOOP
    SPA_PLAN_CTRL(init)(&s->ctrl, 0.0); /* from rest: the integrator at 0 */
#endif
}

/* One tick: adc is the pressure read at this tick (counts). Fills the valve command to
 * issue at once, the Q15 input fraction and whether to print; returns 0 while the run
 * goes on, 1 when this was its last tick. */
static int spa_plan_tick(spa_plan_state *s, long adc, int *valve, long *q, int *log)
{
    spa_plan_run r;
    spa_plan_segment g;
    SPA_PLAN_LOAD(r, spa_plan_runs[s->run]);
    SPA_PLAN_LOAD(g, spa_plan_segments[s->seg]);
    if (adc > SPA_PLAN_ADC_MAX) s->vented = 1; /* read, then check ... */
    if (g.mode == ${valve_mode}) {
        *q = 0;
        *valve = g.a > (spa_real)0.5 ? 1 : 0;
#ifdef SPA_PLAN_LOOP
    } else if (g.mode == ${loop_mode}) { /* the exported controller holds the set-point a */
        SPA_PLAN_CTRL(output) o;
        double p = (double)(adc - SPA_PLAN_ZERO_COUNTS) * SPA_PLAN_BAR_PER_COUNT;
        double x;
        o = SPA_PLAN_CTRL(step)(&s->ctrl, (double)g.a, p);
        *valve = o.valve;
        x = floor((double)o.xi * ${Q}.0 + 0.5);
        *q = x < 0.0 ? 0L : (x > ${Q}.0 ? ${Q}L : (long)x);
#endif
    } else {
        *q = spa_plan_q(&g, s->k_seg);
        *valve = spa_plan_mod_step(r.mod, (long long)s->k, (double)*q / ${Q}.0, s->st);
    }
    if (s->vented) *valve = 0; /* ... then command */
    *log = g.log;
    s->k += 1;
    s->k_seg += 1;
    if (s->k_seg >= g.ticks) {
        s->k_seg = 0;
        s->seg += 1;
        if (s->seg >= r.first + r.count) return 1;
    }
    return 0;
}
"""

_HEADER = """/* spa plan player for session '${name}': ${n_runs} runs, tick ${dt_ms} ms.
 * Generated by spa (spa plan); plays each run through spa's own modulator step (the code of
 * the exported controller). Each tick: read the pressure, vent above the rated maximum,
 * command, write the valve, print. C99, <math.h> only; on AVR the tables live in flash.
 */
#ifndef SPA_PLAN_H
#define SPA_PLAN_H

#include <math.h>
#include <string.h>
#ifdef __AVR__
#include <avr/pgmspace.h>
#define SPA_PLAN_ROM PROGMEM
#define SPA_PLAN_LOAD(dst, src) memcpy_P(&(dst), &(src), sizeof(dst))
#else
#define SPA_PLAN_ROM
#define SPA_PLAN_LOAD(dst, src) memcpy(&(dst), &(src), sizeof(dst))
#endif

/* The board's arithmetic for the waveforms: float (on AVR double is 32-bit too). */
typedef float spa_real;

#define SPA_PLAN_DT ${dt} /* tick, s */
#define SPA_PLAN_TICK_US ${tick_us}UL
#define SPA_PLAN_N_RUNS ${n_runs}
#define SPA_PLAN_N_SEGMENTS ${n_segments}
#define SPA_PLAN_N_STATE ${n_state}
#define SPA_PLAN_ADC_MAX ${adc_max}L /* counts at the rated maximum ${p_max} bar: vent above */
#define SPA_PLAN_REST_TICKS ${rest_ticks}L /* exhaust between runs (the watchdog's vent) */
${loop}"""

#: What the header adds when a run closes the loop with the exported controller.
_LOOP = """
/* Closed-loop runs play the exported controller (spa export-controller's header, beside
 * this one), its step every tick on the pressure read: ADC counts to bar as declared. */
#define SPA_PLAN_LOOP 1
#define SPA_PLAN_ZERO_COUNTS ${zero}L
#define SPA_PLAN_BAR_PER_COUNT ${bar_per_count}
#define SPA_PLAN_CTRL(name) ${prefix}_##name
#include "${controller}"
"""


def _literal(x: float) -> str:
    return c_double(float(x)) + "f"


def player_header(
    name: str,
    runs: tuple[PlannedRun, ...] | list[PlannedRun],
    dt: float,
    adc_max: int,
    p_max: float,
    rest_ticks: int,
    calibration: dict | None = None,
    controller: str = "controller.h",
    prefix: str = "spa_ctrl",
) -> str:
    """The player's C99 header for a session's runs.

    Parameters
    ----------
    name : str
        The session (the dataset's name).
    runs : sequence of PlannedRun
        The runs, in the order played.
    dt : float
        The tick, s.
    adc_max : int
        ADC counts at the rated maximum pressure: above them the player vents.
    p_max : float
        The rated maximum, bar (for the comment).
    rest_ticks : int
        Ticks of exhaust after each run.
    calibration : dict, optional
        The declared calibration (:func:`spa.plan.folder.calibration_for`); needed when a
        run closes the loop (its ``loop`` segments), to read the pressure in bar.
    controller, prefix : str, optional
        The exported controller's header file (beside ``player.h``) and its prefix, for the
        closed-loop runs.

    Raises
    ------
    ValueError
        For closed-loop runs without a calibration, or a prefix that is not a C identifier.
    """
    loop = ""
    if any(run.closed for run in runs):
        if calibration is None:
            raise ValueError("closed-loop runs need the calibration, to read the pressure in bar")
        if not prefix.isidentifier():
            raise ValueError(f"prefix must be a C identifier, got {prefix!r}")
        loop = Template(_LOOP).substitute(
            zero=int(calibration["zero_counts"]),
            bar_per_count=c_double(float(calibration["bar_per_count"])),
            prefix=prefix,
            controller=controller,
        )
    mods: list = []
    labels: dict[str, int] = {}
    for run in runs:
        if run.modulator is not None and run.modulator.label not in labels:
            labels[run.modulator.label] = len(mods)
            mods.append(run.modulator)
    segments, table = [], []
    for run in runs:
        first = len(segments)
        for s in run.segments:
            segments.append(
                f"    {{{s.ticks}L, {MODES[s.mode]}, {int(s.log)}, {_literal(s.a)}, "
                f"{_literal(s.b)}, {_literal(s.c)}, {_literal(s.d)}}}"
            )
        mod = -1 if run.modulator is None else labels[run.modulator.label]
        table.append(f"    {{{first}, {len(run.segments)}, {mod}}} /* {run.id} */")
    kernels, dispatch, inits, n_state = [], [], [], 1
    for i, mod in enumerate(mods):
        kernel = KERNELS[mod.kind]
        prefix = f"spa_plan_m{i}"
        cfg = kernel.configure(dict(mod.settings), dt)
        n_state = max(n_state, len(kernel.INITIAL))
        kernels.append(f"/* modulator {i}: {mod.label} {mod.to_mapping()} */")
        kernels.append(
            f"static const double {prefix}_cfg[{len(cfg)}] = "
            f"{{{', '.join(c_double(v) for v in cfg)}}};"
        )
        kernels.append(Template(kernel.C_STEP).substitute(p=prefix, eps=c_double(EPS)).rstrip())
        dispatch.append(f"    case {i}: return {prefix}_mod_step(k, xi, {prefix}_cfg, st);")
        init = " ".join(f"st[{j}] = {c_double(v)};" for j, v in enumerate(kernel.INITIAL))
        inits.append(f"    case {i}: {init} break;")
    head = Template(_HEADER).substitute(
        name=name,
        n_runs=len(runs),
        dt_ms=f"{dt * 1e3:g}",
        dt=c_double(dt),
        tick_us=round(dt * 1e6),
        n_segments=max(1, len(segments)),
        n_state=n_state,
        adc_max=int(adc_max),
        p_max=f"{p_max:g}",
        rest_ticks=int(rest_ticks),
        loop=loop,
    )
    body = Template(_BODY).substitute(
        segments=",\n".join(segments) or "    {1L, 0, 0, 0.0f, 0.0f, 0.0f, 0.0f}",
        runs=",\n".join(table),
        dispatch="\n".join(dispatch),
        inits="\n".join(inits),
        Q=Q15,
        level=MODES["level"],
        sine=MODES["sine"],
        chirp=MODES["chirp"],
        valve_mode=MODES["valve"],
        loop_mode=MODES["loop"],
    )
    text = "\n".join([head, *kernels, body, "#endif /* SPA_PLAN_H */\n"])
    return text.replace("\nstatic ", "\nstatic inline ").replace(
        "static inline const", "static const"
    )


_HARNESS = r"""/* Host harness of the spa plan player: reads one ADC count per tick from stdin (the
 * pressure at that tick), prints the board's stream on stdout and, when given a file name,
 * every tick's valve command into it. Exit 0 at the end of the session, 4 when the link
 * (stdout) is lost (the valve vented first), 2 when stdin ends early. */
#include <stdio.h>
#include "player.h"

static void valve_write(int v, FILE *trace) { if (trace) fputc(v ? '1' : '0', trace); }

int main(int argc, char **argv)
{
    spa_plan_state s;
    FILE *trace = argc > 1 ? fopen(argv[1], "w") : NULL;
    int run, valve, log, last;
    long adc, q, r;
    for (run = 0; run < SPA_PLAN_N_RUNS; ++run) {
        spa_plan_start(&s, run);
        if (printf("R %d\n", run) < 0) { valve_write(0, trace); return 4; }
        do {
            long tick = s.k;
            if (scanf("%ld", &adc) != 1) { valve_write(0, trace); return 2; }
            last = spa_plan_tick(&s, adc, &valve, &q, &log);
            valve_write(valve, trace);
            if (log && printf("%lx,%lx,%d,%lx\n", tick & 0xFFFFL, adc, valve, q) < 0) {
                valve_write(0, trace);
                return 4;
            }
        } while (!last);
        printf("E %d %s\n", run, s.vented ? "vent" : "done");
        for (r = 0; r < SPA_PLAN_REST_TICKS; ++r) {
            if (scanf("%ld", &adc) != 1) return 2;
            valve_write(0, trace);
        }
    }
    if (trace) fclose(trace);
    return 0;
}
"""


def harness_source() -> str:
    """The host harness's C source (includes ``player.h``)."""
    return _HARNESS


_SKETCH = r"""// Arduino-style player for the spa plan session '${name}' (C++ around player.h).
// Each tick (SPA_PLAN_DT s): read the pressure, vent above the rated maximum, command the
// valve, print one line. Between runs and whenever the link stalls the valve exhausts; the
// hardware watchdog restarts the board (valve closed first) if the loop hangs.
#include "player.h"
#ifdef __AVR__
#include <avr/wdt.h>
#endif

const int VALVE_PIN = 8;     // TODO: the pin that drives the valve (HIGH = charge)
const int SENSOR_PIN = A0;   // TODO: the pressure sensor's analog input
const unsigned long BAUD = ${baud}UL;

spa_plan_state state;
int run = 0;
long rest = 0;
unsigned long next_us;

void vent() { digitalWrite(VALVE_PIN, LOW); }

void setup() {
  pinMode(VALVE_PIN, OUTPUT);
  vent();
  Serial.begin(BAUD);
  while (!Serial) {}
#ifdef __AVR__
  wdt_enable(WDTO_250MS);
#endif
  spa_plan_start(&state, run);
  Serial.print("R "); Serial.println(run);
  next_us = micros();
}

void loop() {
#ifdef __AVR__
  wdt_reset();
#endif
  long late = (long)(micros() - next_us);
  if (late < 0) return;
  next_us += SPA_PLAN_TICK_US;
  if (late >= (long)SPA_PLAN_TICK_US) {  // an overrun: the tick came a whole step late
    Serial.print("O ");
    Serial.println(late / (long)SPA_PLAN_TICK_US);
    next_us = micros() + SPA_PLAN_TICK_US;
  }
  if (run >= SPA_PLAN_N_RUNS) { vent(); return; }
  if (rest > 0) {
    vent();
    if (--rest == 0 && run < SPA_PLAN_N_RUNS) {
      spa_plan_start(&state, run);
      Serial.print("R ");
      Serial.println(run);
    }
    return;
  }
  long tick = state.k;
  long adc = analogRead(SENSOR_PIN);           // read first ...
  int valve, log;
  long q;
  int last = spa_plan_tick(&state, adc, &valve, &q, &log);
  digitalWrite(VALVE_PIN, valve ? HIGH : LOW); // ... then write at once
  if (log) {
    if (Serial.availableForWrite() < 17) {      // the link stalls: vent and stop
      vent();
      run = SPA_PLAN_N_RUNS;
      return;
    }
    Serial.print(tick & 0xFFFFL, HEX); Serial.print(',');
    Serial.print(adc, HEX); Serial.print(',');
    Serial.print(valve); Serial.print(',');
    Serial.println(q, HEX);
  }
  if (last) {
    Serial.print("E "); Serial.print(run); Serial.println(state.vented ? " vent" : " done");
    vent();
    rest = SPA_PLAN_REST_TICKS;
    ++run;
  }
}
"""


def player_sketch(name: str, baud: int) -> str:
    """The Arduino-style sketch around ``player.h`` at ``baud``."""
    return Template(_SKETCH).substitute(name=name, baud=int(baud))
