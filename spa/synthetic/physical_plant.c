/* The physical test plant in C: spa/synthetic/physical.py's kernels, step for step.
 * Compile as C99 with -ffp-contract=off (no fused multiply-add) for the closest agreement. */
#include <math.h>

#include "physical_plant.h"

static double flow(double p1, double p2, double cond, double b, double m, double rho0,
                   double blam)
{
    double up, dn, sgn, r, z, phi;
    if (p1 >= p2) {
        up = p1;
        dn = p2;
        sgn = 1.0;
    } else {
        up = p2;
        dn = p1;
        sgn = -1.0;
    }
    if (up <= 0.0 || cond <= 0.0) {
        return 0.0;
    }
    r = dn / up;
    if (r <= b) {
        phi = 1.0;
    } else if (r <= blam) {
        z = (r - b) / (1.0 - b);
        phi = pow(1.0 - z * z, m);
    } else {
        z = (blam - b) / (1.0 - b);
        phi = pow(1.0 - z * z, m) * (1.0 - r) / (1.0 - blam);
    }
    return sgn * cond * up * rho0 * phi;
}

static double spool(double t, const double *x, double transit)
{
    double direction = x[5] > 0.5 ? 1.0 : -1.0;
    double s = x[3] + (t - x[4]) * direction / transit;
    if (s < 0.0) {
        return 0.0;
    }
    if (s > 1.0) {
        return 1.0;
    }
    return s;
}

static void events(double t, spa_phys_state *s)
{
    double tau;
    while (s->qcount > 0 && s->qt[s->qhead] <= t) {
        tau = s->qt[s->qhead];
        s->x[3] = spool(tau, s->x, s->c[16]);
        s->x[4] = tau;
        s->x[5] = s->qv[s->qhead];
        s->qhead = (s->qhead + 1) % SPA_PHYS_QUEUE;
        s->qcount -= 1;
    }
}

static void rhs(double p, double ps, double y, double sp, const double *c, double *d)
{
    double q_in = flow(ps, p, c[5] * sp, c[6], c[7], c[4], c[19]);
    double q_out = flow(p, c[0], c[8] * (1.0 - sp), c[9], c[10], c[4], c[19]);
    double vol = c[11] + c[12] * (p - c[0]);
    d[0] = c[2] * c[3] * (q_in - q_out) / (vol + c[2] * p * c[12]);
    d[1] = (c[1] - c[13] * q_in / c[4] - ps) / c[14];
    if (c[15] > 0.0) {
        d[2] = (p - c[0] - y) / c[15];
    } else {
        d[2] = 0.0;
    }
}

static int command(spa_phys_state *s, double tk, int u)
{
    double v = u != 0 ? 1.0 : 0.0;
    double tau;
    long j;
    if (v == s->x[6]) {
        return 0;
    }
    tau = tk + (v > 0.5 ? s->c[17] : s->c[18]);
    while (s->qcount > 0 && s->qt[(s->qhead + s->qcount - 1) % SPA_PHYS_QUEUE] >= tau) {
        s->qcount -= 1;
    }
    if (s->qcount == SPA_PHYS_QUEUE) {
        return -1;
    }
    j = (s->qhead + s->qcount) % SPA_PHYS_QUEUE;
    s->qt[j] = tau;
    s->qv[j] = v;
    s->qcount += 1;
    s->x[6] = v;
    return 0;
}

static void advance(spa_phys_state *s, double tk)
{
    const double *c = s->c;
    double *x = s->x, *d = s->d;
    double h = s->dt / s->nsub;
    double t, p, ps, y, s2, k1p, k1s, k1y, k2p, k2s, k2y, k3p, k3s, k3y;
    int i;
    for (i = 0; i < s->nsub; ++i) {
        t = tk + i * h;
        p = x[0];
        ps = x[1];
        y = x[2];
        events(t, s);
        rhs(p, ps, y, spool(t, x, c[16]), c, d);
        k1p = d[0];
        k1s = d[1];
        k1y = d[2];
        events(t + 0.5 * h, s);
        s2 = spool(t + 0.5 * h, x, c[16]);
        rhs(p + 0.5 * h * k1p, ps + 0.5 * h * k1s, y + 0.5 * h * k1y, s2, c, d);
        k2p = d[0];
        k2s = d[1];
        k2y = d[2];
        rhs(p + 0.5 * h * k2p, ps + 0.5 * h * k2s, y + 0.5 * h * k2y, s2, c, d);
        k3p = d[0];
        k3s = d[1];
        k3y = d[2];
        events(t + h, s);
        rhs(p + h * k3p, ps + h * k3s, y + h * k3y, spool(t + h, x, c[16]), c, d);
        x[0] = p + h / 6.0 * (k1p + 2.0 * k2p + 2.0 * k3p + d[0]);
        x[1] = ps + h / 6.0 * (k1s + 2.0 * k2s + 2.0 * k3s + d[1]);
        if (c[15] > 0.0) {
            x[2] = y + h / 6.0 * (k1y + 2.0 * k2y + 2.0 * k3y + d[2]);
        } else {
            x[2] = x[0] - c[0];
        }
    }
}

void spa_phys_init(spa_phys_state *s, const double *c, double dt, int nsub, double p0, int u0)
{
    int i;
    for (i = 0; i < SPA_PHYS_N_CONST; ++i) {
        s->c[i] = c[i];
    }
    s->dt = dt;
    s->nsub = nsub;
    s->k = 0;
    s->x[0] = c[0] + p0;
    s->x[1] = c[1];
    s->x[2] = p0;
    s->x[3] = u0 != 0 ? 1.0 : 0.0;
    s->x[4] = 0.0;
    s->x[5] = s->x[3];
    s->x[6] = s->x[3];
    s->x[7] = 0.0;
    s->qhead = 0;
    s->qcount = 0;
}

int spa_phys_step(spa_phys_state *s, int u)
{
    double tk = s->k * s->dt;
    if (command(s, tk, u) != 0) {
        return -1;
    }
    advance(s, tk);
    s->k += 1;
    return 0;
}

double spa_phys_pressure(const spa_phys_state *s)
{
    return s->x[0] - s->c[0];
}

double spa_phys_lagged(const spa_phys_state *s)
{
    return s->x[2];
}
