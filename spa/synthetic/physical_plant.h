/* A physical test plant for spa (spa.synthetic.physical): a 3/2 solenoid valve with ISO
 * 6358-1 orifice flow through both ports, a spool with dead times and a transit, a
 * polytropic chamber whose volume grows with pressure, a drooping regulator and a sensor
 * with a first-order lag. The same fixed-step Runge-Kutta scheme as the Python/numba kernels
 * of spa/synthetic/physical.py, operation for operation; the two agree within 1e-9 bar
 * (tests/test_physical_plant.py). C99, <math.h> only. Not the model: a test fixture.
 *
 * Constants (SI, absolute pressures), in this order (spa.synthetic.physical._C):
 *   0 p_atm Pa, 1 p_set Pa, 2 n, 3 R*T0 J/kg, 4 rho0 kg/m^3, 5 C_s m^3/(s*Pa), 6 b_s, 7 m_s,
 *   8 C_e m^3/(s*Pa), 9 b_e, 10 m_e, 11 V0 m^3, 12 k_v m^3/Pa, 13 droop Pa/(m^3/s),
 *   14 tau_r s, 15 tau_s s, 16 transit s, 17 t_open s, 18 t_close s, 19 laminar ratio,
 *   20 leak m^3/(s*Pa), 21 heat_tau s, 22 creep m^3/Pa, 23 creep_tau s, 24 tube_tau s,
 *   25 hose volume m^3, 26 C_line m^3/(s*Pa), 27 bounce, 28 bounce time s, 29 T0 K.
 * Each effect 20-28 is off at 0 and then drops out exactly.
 */
#ifndef SPA_PHYS_H
#define SPA_PHYS_H

#define SPA_PHYS_N_CONST 30
#define SPA_PHYS_NZ 7
#define SPA_PHYS_PI 3.14159265358979323846
#define SPA_PHYS_QUEUE 4096

typedef struct {
    double x[12]; /* P, Ps (Pa abs), y (Pa gauge), spool s_ref, t_ref, v_ref, command, spare,
                     T (K), Vc (m^3), Pt, Ph (Pa abs) */
    double qt[SPA_PHYS_QUEUE]; /* pending armature switches: time, s */
    double qv[SPA_PHYS_QUEUE]; /* ... and the connection they make (1 supply, 0 exhaust) */
    long qhead, qcount;
    double c[SPA_PHYS_N_CONST];
    double d[SPA_PHYS_NZ];
    double dt; /* controller step, s */
    int nsub;  /* Runge-Kutta steps per controller step */
    long k;    /* controller steps done */
} spa_phys_state;

/* At rest at p0 (Pa gauge), the valve settled at command u0, the regulator at its set-point. */
void spa_phys_init(spa_phys_state *s, const double *c, double dt, int nsub, double p0, int u0);
/* Apply command u (0/1) over the coming controller step and integrate over it.
 * Returns 0, or -1 when more edges are pending than the queue holds. */
int spa_phys_step(spa_phys_state *s, int u);
/* The chamber's gauge pressure and the sensor's lagged gauge pressure now, Pa. */
double spa_phys_pressure(const spa_phys_state *s);
double spa_phys_lagged(const spa_phys_state *s);

#endif /* SPA_PHYS_H */
