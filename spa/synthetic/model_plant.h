/* spa's model plant in C (spa.simulate, docs/model.md section 1): the paper's two-mode valve
 * stepped one controller tick at a time, each segment by its exact closed form: the charge's
 * exponential approach to k2 (Eq. 2 solved), the discharge's square-root law with c1 (Eq. 1
 * solved, empty in finite time), and the dead times under either delay convention of
 * ValveParams.delay: "hold" (the pressure holds still t_on after a rising and t_off after a
 * falling edge; an edge during a hold restarts it) or "transport" (the command reaches the
 * plant t_on/t_off after its edge, the previous connection persisting meanwhile; a delayed
 * edge that reaches the plant no later than the one before it cancels that one). The same
 * operations as spa/model/plant.py, in the same order: the two agree to about 1e-15 bar
 * (tests/test_model_twin.py). C99, <math.h> only. The paper's laws only: a valve with its own
 * laws (ValveParams.laws) is refused by the Python side.
 *
 * Constants, in this order (spa.synthetic._model_c.model_constants):
 *   0 c1 s*bar^-0.5, 1 k2 bar, 2 tau2 s, 3 t_on s, 4 t_off s, 5 convention (0 hold, 1 transport).
 */
#ifndef SPA_MODEL_H
#define SPA_MODEL_H

#define SPA_MODEL_N_CONST 6
#define SPA_MODEL_QUEUE 4096

typedef struct {
    double c[SPA_MODEL_N_CONST];
    double dt;  /* controller step, s */
    long k;     /* controller steps done: the state is at t = k*dt */
    int cmd;    /* the last command */
    int level;  /* the plant's connection over its current segment (1 supply) */
    long ks;    /* hold: the tick the current command run started */
    double hold;  /* hold: how long its pressure holds still, s */
    double ts;    /* transport: the time the current segment started, s */
    double ps;    /* the pressure when the current run or segment started, bar */
    int has_prev; /* transport: the segment before, restored if its edge is cancelled */
    int prev_level;
    double prev_ts, prev_ps;
    double qt[SPA_MODEL_QUEUE]; /* transport: pending edges, the time they reach the plant */
    int qv[SPA_MODEL_QUEUE];    /* ... and the connection they make */
    long qhead, qcount;
    double p; /* the pressure at t = k*dt, bar gauge */
} spa_model_state;

/* At rest at p0 (bar gauge) at t = 0, the valve settled at command u0 (no transition). */
void spa_model_init(spa_model_state *s, const double *c, double dt, double p0, int u0);
/* Apply command u (0/1) over [k*dt, (k+1)*dt) and move to (k+1)*dt.
 * Returns 0, or -1 when more edges are pending than the queue holds. */
int spa_model_step(spa_model_state *s, int u);
/* The pressure now, bar gauge. */
double spa_model_pressure(const spa_model_state *s);

#endif /* SPA_MODEL_H */
