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

static double spool(double t, const double *x, const double *c)
{
    double direction = x[5] > 0.5 ? 1.0 : -1.0;
    double s = x[3] + (t - x[4]) * direction / c[16];
    double hit, a, b;
    if (c[27] > 0.0) {
        hit = x[4] + fabs(x[5] - x[3]) * c[16];
        if (fabs(x[5] - x[3]) > 0.0 && t > hit) {
            a = t - hit;
            b = c[27] * exp(-a / c[28]) * fabs(sin(SPA_PHYS_PI * a / c[28]));
            return direction > 0.0 ? 1.0 - b : b;
        }
    }
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
        s->x[3] = spool(tau, s->x, s->c);
        s->x[4] = tau;
        s->x[5] = s->qv[s->qhead];
        s->qhead = (s->qhead + 1) % SPA_PHYS_QUEUE;
        s->qcount -= 1;
    }
}

/* Derivatives of z = (P, Ps, y, T, Vc, Pt, Ph) at spool position sp into d. */
static void rhs(const double *z, double sp, const double *c, double *d)
{
    double p = z[0], ps = z[1], y = z[2];
    double up = c[25] > 0.0 ? z[6] : ps;
    double q_in = flow(up, p, c[5] * sp, c[6], c[7], c[4], c[19]);
    double q_out = flow(p, c[0], c[8] * (1.0 - sp), c[9], c[10], c[4], c[19]);
    double vol, dvc = 0.0, tg, r_gas, heat, mass, q_reg, src;
    if (c[20] > 0.0) {
        q_out = q_out + c[20] * c[4] * (p - c[0]);
    }
    vol = c[11] + c[12] * (p - c[0]);
    if (c[22] > 0.0) {
        vol = vol + z[4];
        dvc = (c[22] * (p - c[0]) - z[4]) / c[23];
    }
    d[4] = dvc;
    if (c[21] > 0.0) {
        tg = z[3];
        r_gas = c[3] / c[29];
        heat = p * vol * (c[29] - tg) / (tg * c[21]);
        d[0] = (c[2] * r_gas * (q_in * c[29] - q_out * tg) + heat - c[2] * p * dvc) /
               (vol + c[2] * p * c[12]);
        mass = p * vol / (r_gas * tg);
        d[3] = tg * (d[0] / p + (c[12] * d[0] + dvc) / vol - (q_in - q_out) / mass);
    } else {
        if (c[22] > 0.0) {
            d[0] = (c[2] * c[3] * (q_in - q_out) - c[2] * p * dvc) / (vol + c[2] * p * c[12]);
        } else {
            d[0] = c[2] * c[3] * (q_in - q_out) / (vol + c[2] * p * c[12]);
        }
        d[3] = 0.0;
    }
    q_reg = q_in;
    if (c[25] > 0.0) {
        q_reg = flow(ps, z[6], c[26], 0.3, 0.5, c[4], c[19]);
        d[6] = c[3] * (q_reg - q_in) / c[25];
    } else {
        d[6] = 0.0;
    }
    d[1] = (c[1] - c[13] * q_reg / c[4] - ps) / c[14];
    src = p;
    if (c[24] > 0.0) {
        d[5] = (p - z[5]) / c[24];
        src = z[5];
    } else {
        d[5] = 0.0;
    }
    if (c[15] > 0.0) {
        d[2] = (src - c[0] - y) / c[15];
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

static const int zidx[SPA_PHYS_NZ] = {0, 1, 2, 8, 9, 10, 11};

static void advance(spa_phys_state *s, double tk)
{
    const double *c = s->c;
    double *x = s->x, *d = s->d;
    double h = s->dt / s->nsub;
    double t, s2, z[SPA_PHYS_NZ], zt[SPA_PHYS_NZ], k1[SPA_PHYS_NZ], k2[SPA_PHYS_NZ],
        k3[SPA_PHYS_NZ];
    int i, j;
    for (i = 0; i < s->nsub; ++i) {
        t = tk + i * h;
        for (j = 0; j < SPA_PHYS_NZ; ++j) {
            z[j] = x[zidx[j]];
        }
        events(t, s);
        rhs(z, spool(t, x, c), c, d);
        for (j = 0; j < SPA_PHYS_NZ; ++j) {
            k1[j] = d[j];
            zt[j] = z[j] + 0.5 * h * k1[j];
        }
        events(t + 0.5 * h, s);
        s2 = spool(t + 0.5 * h, x, c);
        rhs(zt, s2, c, d);
        for (j = 0; j < SPA_PHYS_NZ; ++j) {
            k2[j] = d[j];
            zt[j] = z[j] + 0.5 * h * k2[j];
        }
        rhs(zt, s2, c, d);
        for (j = 0; j < SPA_PHYS_NZ; ++j) {
            k3[j] = d[j];
            zt[j] = z[j] + h * k3[j];
        }
        events(t + h, s);
        rhs(zt, spool(t + h, x, c), c, d);
        for (j = 0; j < SPA_PHYS_NZ; ++j) {
            x[zidx[j]] = z[j] + h / 6.0 * (k1[j] + 2.0 * k2[j] + 2.0 * k3[j] + d[j]);
        }
        if (c[15] <= 0.0) {
            x[2] = (c[24] > 0.0 ? x[10] : x[0]) - c[0];
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
    s->x[8] = c[29];
    s->x[9] = c[22] * p0;
    s->x[10] = s->x[0];
    s->x[11] = c[1];
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
