/* spa's model plant in C: spa/model/plant.py's simulate, one controller tick at a time.
 * Compile as C99 with -ffp-contract=off (no fused multiply-add), as numpy evaluates. */
#include <math.h>

#include "model_plant.h"

/* segment_pressure: after e s of charging (on) or exhausting from p0, bar. */
static double segment(const double *c, int on, double p0, double e)
{
    double r;
    if (e < 0.0) {
        e = 0.0;
    }
    if (on) {
        return exp(-e / c[2]) * (p0 - c[1]) + c[1];
    }
    r = sqrt(p0) - e / (2.0 * c[0]);
    if (r < 0.0) {
        r = 0.0;
    }
    return r * r;
}

/* run_start_pressures' step: the pressure after a run active for `active` s from p0. */
static double run_end(const double *c, int on, double p0, double active)
{
    double r;
    if (on) {
        return c[1] + (p0 - c[1]) * exp(-active / c[2]);
    }
    r = sqrt(p0) - active / (2.0 * c[0]);
    return r > 0.0 ? r * r : 0.0;
}

void spa_model_init(spa_model_state *s, const double *c, double dt, double p0, int u0)
{
    int i;
    for (i = 0; i < SPA_MODEL_N_CONST; ++i) {
        s->c[i] = c[i];
    }
    s->dt = dt;
    s->k = 0;
    s->cmd = u0 != 0;
    s->level = s->cmd;
    s->ks = 0;
    s->hold = 0.0; /* settled at t = 0 */
    s->ts = 0.0;
    s->ps = p0;
    s->has_prev = 0;
    s->prev_level = 0;
    s->prev_ts = 0.0;
    s->prev_ps = 0.0;
    s->qhead = 0;
    s->qcount = 0;
    s->p = p0;
}

/* The hold convention: a command run's closed form from its hold's end (simulate). */
static void step_hold(spa_model_state *s, int u)
{
    const double *c = s->c;
    double active, t;
    if (u != s->cmd) {
        active = (double)(s->k - s->ks) * s->dt - s->hold;
        if (active < 0.0) {
            active = 0.0;
        }
        s->ps = run_end(c, s->level, s->ps, active);
        s->cmd = u;
        s->level = u;
        s->ks = s->k;
        s->hold = u ? c[3] : c[4];
    }
    s->k += 1;
    t = (double)s->k * s->dt;
    s->p = segment(c, s->level, s->ps, t - ((double)s->ks * s->dt + s->hold));
}

/* The transport convention: delayed edges queued, cancelled in pairs (transport_runs). */
static int step_transport(spa_model_state *s, int u)
{
    const double *c = s->c;
    double arrive, t, active;
    long j, last;
    if (u != s->cmd) {
        arrive = (double)s->k * s->dt + (u ? c[3] : c[4]);
        s->cmd = u;
        last = (s->qhead + s->qcount - 1) % SPA_MODEL_QUEUE;
        if (s->qcount > 0 && s->qt[last] >= arrive) {
            s->qcount -= 1; /* the pending edge and this one cancel */
        } else if (s->qcount == 0 && s->has_prev && s->ts >= arrive) {
            s->level = s->prev_level; /* a zero delay: the edge applied at t cancels */
            s->ts = s->prev_ts;
            s->ps = s->prev_ps;
            s->has_prev = 0;
        } else {
            if (s->qcount == SPA_MODEL_QUEUE) {
                return -1;
            }
            j = (s->qhead + s->qcount) % SPA_MODEL_QUEUE;
            s->qt[j] = arrive;
            s->qv[j] = u;
            s->qcount += 1;
        }
    }
    s->k += 1;
    t = (double)s->k * s->dt;
    while (s->qcount > 0 && s->qt[s->qhead] <= t) {
        active = s->qt[s->qhead] - s->ts;
        if (active < 0.0) {
            active = 0.0;
        }
        s->has_prev = 1;
        s->prev_level = s->level;
        s->prev_ts = s->ts;
        s->prev_ps = s->ps;
        s->ps = run_end(c, s->level, s->ps, active);
        s->ts = s->qt[s->qhead];
        s->level = s->qv[s->qhead];
        s->qhead = (s->qhead + 1) % SPA_MODEL_QUEUE;
        s->qcount -= 1;
    }
    s->p = segment(c, s->level, s->ps, t - s->ts);
    return 0;
}

int spa_model_step(spa_model_state *s, int u)
{
    u = u != 0;
    if (s->c[5] > 0.5) {
        return step_transport(s, u);
    }
    step_hold(s, u);
    return 0;
}

double spa_model_pressure(const spa_model_state *s)
{
    return s->p;
}
