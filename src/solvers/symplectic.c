/* Solvers for second-order systems y = [x | v] with x' = v:
 * symplectic (semi-implicit) Euler and velocity Verlet. */
#include "solvers/solver.h"

#include <string.h>

enum { Y0, YDOT, Y1, YPRED };

/* v1 = v0 + h a(t, x0, v0);  x1 = x0 + h v1 */
static psys_status symplectic_euler_step(psys_solver *s, double h, double *h_taken)
{
    size_t np = s->ode.npos;
    double *y0 = s->buf[Y0], *ydot = s->buf[YDOT], *y1 = s->buf[Y1];
    double t = s->ode.get_time(s->ode.ctx);
    s->ode.get_state(s->ode.ctx, y0);
    psys_status st = psys__solver_eval_accel(s, t, y0, ydot);
    if (st != PSYS_OK)
        return st;
    const double *a = ydot + np;
    const int nt = psys__solver_threads(s);
    PSYS_PAR_FOR(nt, np)
    for (size_t i = 0; i < np; i++) {
        double v1 = y0[np + i] + h * a[i];
        y1[np + i] = v1;
        y1[i] = y0[i] + h * v1;
    }
    *h_taken = h;
    return psys__solver_commit(s, y1, t + h);
}

/* v½ = v0 + h/2 a(x0, v0);  x1 = x0 + h v½;  v1 = v½ + h/2 a(x1, ṽ1).
 * The second evaluation sees the predicted end velocity ṽ1 = v0 + h a0, which
 * keeps second order when forces depend on velocity (damping, drag); for
 * velocity-independent forces this is exactly velocity Verlet, and where
 * the ODE says so (velocity_free) the second evaluation takes [x1 | v½]
 * itself, the same accelerations without writing the state [x1 | ṽ1]. */
static psys_status verlet_step(psys_solver *s, double h, double *h_taken)
{
    size_t np = s->ode.npos;
    double *y0 = s->buf[Y0], *ydot = s->buf[YDOT], *y1 = s->buf[Y1], *ypred = s->buf[YPRED];
    double t = s->ode.get_time(s->ode.ctx), hh = 0.5 * h;
    const bool vfree = s->fast.velocity_free && s->fast.velocity_free(s->ode.ctx);
    s->ode.get_state(s->ode.ctx, y0);
    psys_status st = psys__solver_eval_accel(s, t, y0, ydot);
    if (st != PSYS_OK)
        return st;
    const int nt = psys__solver_threads(s);
    PSYS_PAR_FOR(nt, np)
    for (size_t i = 0; i < np; i++) {
        double vh = y0[np + i] + hh * ydot[np + i];
        y1[np + i] = vh;
        y1[i] = y0[i] + h * vh;
        if (!vfree) {
            ypred[i] = y1[i];
            ypred[np + i] = y0[np + i] + h * ydot[np + i];
        }
    }
    if ((st = psys__solver_eval_accel(s, t + h, vfree ? y1 : ypred, ydot)) != PSYS_OK)
        return st;
    PSYS_PAR_FOR(nt, np)
    for (size_t i = 0; i < np; i++)
        y1[np + i] += hh * ydot[np + i];
    *h_taken = h;
    return psys__solver_commit(s, y1, t + h);
}

const psys__solver_class psys__symplectic_euler = {.name = "symplectic-euler", .order = 1, .adaptive = false, .second_order_only = true, .elementwise = true, .nbuf = 3, .tab = NULL, .step = symplectic_euler_step};
const psys__solver_class psys__verlet = {.name = "verlet", .order = 2, .adaptive = false, .second_order_only = true, .elementwise = true, .nbuf = 4, .tab = NULL, .step = verlet_step};
