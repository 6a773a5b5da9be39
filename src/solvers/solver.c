/* Solver registry and the operations every solver shares. */
#include "solvers/solver.h"

#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

static const psys__solver_class *const registry[] = {
    &psys__euler,  &psys__midpoint, &psys__rk4, &psys__symplectic_euler, &psys__verlet, &psys__rk45,
    &psys__implicit_euler, NULL,
};

size_t psys_solver_count(void) { return sizeof registry / sizeof registry[0] - 1; }

const char *psys_solver_name_at(size_t i) { return i < psys_solver_count() ? registry[i]->name : NULL; }

static const psys__solver_class *lookup(const char *name)
{
    for (size_t i = 0; registry[i]; i++)
        if (strcmp(registry[i]->name, name) == 0)
            return registry[i];
    return NULL;
}

bool psys_solver_exists(const char *name) { return name && lookup(name) != NULL; }

psys_solver *psys_solver_create(const char *name, const psys_ode *ode, psys_error *err)
{
    return psys__solver_create_fast(name, ode, NULL, NULL, err);
}

psys_solver *psys__solver_create_fast(const char *name, const psys_ode *ode, const psys__ode_fast *fast,
                                      psys_system *owner, psys_error *err)
{
    const psys__solver_class *cls = name ? lookup(name) : NULL;
    if (!cls) {
        psys__fail(err, PSYS_ERR_INVALID, "unknown solver \"%s\"", name ? name : "(null)");
        return NULL;
    }
    if (!ode || !ode->derivative || !ode->get_state || !ode->set_state || !ode->get_time || !ode->set_time) {
        psys__fail(err, PSYS_ERR_INVALID, "the ODE lacks a required callback");
        return NULL;
    }
    if (cls->second_order_only && (ode->npos == 0 || 2 * ode->npos != ode->size)) {
        psys__fail(err, PSYS_ERR_INVALID, "solver \"%s\" needs a second-order ODE (y = [positions | velocities])",
                   cls->name);
        return NULL;
    }
    psys_solver *s = calloc(1, sizeof *s);
    if (!s) {
        psys__fail(err, PSYS_ERR_NOMEM, "out of memory creating a solver");
        return NULL;
    }
    s->cls = cls;
    s->ode = *ode;
    if (fast)
        s->fast = *fast;
    s->owner = owner;
    s->n = ode->size;
    s->cap = ode->size;
    s->tol = 1e-6;
    s->threads = 1;
    s->cg_tol = 1e-6;
    s->cg_maxit = 1000;
    for (int i = 0; i < cls->nbuf; i++)
        if (!(s->buf[i] = psys__calloc(s->n, sizeof(double)))) {
            psys_solver_destroy(s);
            psys__fail(err, PSYS_ERR_NOMEM, "out of memory creating a solver");
            return NULL;
        }
    if (cls->init && cls->init(s) != PSYS_OK) {
        psys__fail(err, s->err.code, "%s", s->err.message);
        psys_solver_destroy(s);
        return NULL;
    }
    psys__ok(err);
    return s;
}

void psys_solver_destroy(psys_solver *s)
{
    if (!s)
        return;
    if (s->cls->fini)
        s->cls->fini(s);
    for (int i = 0; i < PSYS__MAX_BUFS; i++)
        free(s->buf[i]);
    free(s);
}

const char *psys_solver_name(const psys_solver *s) { return s->cls->name; }
psys_system *psys__solver_owner(const psys_solver *s) { return s->owner; }
size_t psys__solver_size(const psys_solver *s) { return s->n; }
bool psys__solver_elementwise(const psys_solver *s) { return s->cls->elementwise; }
bool psys_solver_is_adaptive(const psys_solver *s) { return s->cls->adaptive; }
int psys_solver_order(const psys_solver *s) { return s->cls->order; }
size_t psys_solver_bad_component(const psys_solver *s) { return s->bad; }
const char *psys_solver_last_error(const psys_solver *s) { return s->err.message; }
double psys_solver_next_step(const psys_solver *s) { return s->cls->adaptive ? s->h_next : 0.0; }
size_t psys_solver_rejected_steps(const psys_solver *s) { return s->rejected; }
size_t psys_solver_cg_unconverged(const psys_solver *s) { return s->cg_unconverged; }
double psys_solver_cg_worst_residual(const psys_solver *s) { return s->cg_worst; }
size_t psys_solver_cg_iterations(const psys_solver *s) { return s->cg_iterations; }

psys_status psys_solver_set_cg(psys_solver *s, double tolerance, int max_iterations)
{
    if (!(tolerance > 0) || !isfinite(tolerance) || max_iterations < 1)
        return psys__fail(&s->err, PSYS_ERR_INVALID, "CG tolerance must be > 0 and the iteration cap >= 1");
    s->cg_tol = tolerance;
    s->cg_maxit = max_iterations;
    return PSYS_OK;
}

psys_status psys_solver_set_tolerance(psys_solver *s, double tol)
{
    if (!(tol > 0) || !isfinite(tol))
        return psys__fail(&s->err, PSYS_ERR_INVALID, "tolerance must be a finite number > 0");
    s->tol = tol;
    return PSYS_OK;
}

psys_status psys_solver_set_threads(psys_solver *s, int threads)
{
    if (threads < 0)
        return psys__fail(&s->err, PSYS_ERR_INVALID, "threads must be >= 0 (got %d)", threads);
    s->threads = threads;
    return PSYS_OK;
}

psys_status psys_solver_set_next_step(psys_solver *s, double h)
{
    if (!(h > 0) || !isfinite(h))
        return psys__fail(&s->err, PSYS_ERR_INVALID, "step size must be a finite number > 0");
    s->h_next = h;
    return PSYS_OK;
}

psys_status psys_solver_step(psys_solver *s, double h_max, double *h_taken)
{
    if (h_taken)
        *h_taken = 0.0;
    if (!(h_max > 0) || !isfinite(h_max))
        return psys__fail(&s->err, PSYS_ERR_INVALID, "step size must be a finite number > 0 (got %g)", h_max);
    double h = 0;
    psys_status st = s->cls->step(s, h_max, &h);
    if (h_taken)
        *h_taken = st == PSYS_OK ? h : 0.0;
    return st;
}

psys_status psys__solver_rebind(psys_solver *s, const psys_ode *ode)
{
    if (s->cls->init || (s->cls->second_order_only && (ode->npos == 0 || 2 * ode->npos != ode->size)))
        return PSYS_ERR_UNSUPPORTED;
    if (ode->size > s->cap) {
        size_t cap = ode->size + ode->size / 2; /* room for the next few migrations */
        for (int i = 0; i < s->cls->nbuf; i++) {
            double *p = psys__realloc(s->buf[i], cap, sizeof(double));
            if (!p)
                return PSYS_ERR_NOMEM; /* buffers grown so far stay valid and larger */
            s->buf[i] = p;
        }
        s->cap = cap;
    }
    s->ode = *ode;
    memset(&s->fast, 0, sizeof s->fast);
    s->owner = NULL;
    s->n = ode->size;
    return PSYS_OK;
}

/* Project y at t, then fn(t, y) into ydot (derivative or acceleration). */
static psys_status eval_by(psys_solver *s, psys_status (*fn)(void *, double, const double *, double *), double t,
                           double *y, double *ydot)
{
    if (s->ode.project)
        s->ode.project(s->ode.ctx, t, y);
    psys_status st = fn(s->ode.ctx, t, y, ydot);
    if (st != PSYS_OK)
        return psys__fail(&s->err, st, "the derivative evaluation failed at t = %.17g", t);
    return PSYS_OK;
}

psys_status psys__solver_eval(psys_solver *s, double t, double *y, double *ydot)
{
    return eval_by(s, s->ode.derivative, t, y, ydot);
}

psys_status psys__solver_eval_accel(psys_solver *s, double t, double *y, double *ydot)
{
    return eval_by(s, s->fast.acceleration ? s->fast.acceleration : s->ode.derivative, t, y, ydot);
}

int psys__solver_threads(const psys_solver *s)
{
#ifdef _OPENMP
    int nt = s->threads > 0 ? s->threads : omp_get_max_threads();
    return nt < 1 ? 1 : nt;
#else
    (void)s;
    return 1;
#endif
}

size_t psys__solver_first_nonfinite(const psys_solver *s, const double *y)
{
    const int nt = psys__solver_threads(s);
    uint64_t any = 0;
    PSYS_OMP(omp parallel for schedule(static) num_threads(nt) if (nt > 1 && s->n >= PSYS_PAR_MIN) reduction(|: any))
    for (size_t i = 0; i < s->n; i++)
        any |= psys__nonfinite_bit(y[i]);
    if (any >> 63)
        for (size_t i = 0; i < s->n; i++)
            if (!isfinite(y[i]))
                return i;
    return SIZE_MAX;
}

psys_status psys__solver_nonfinite(psys_solver *s, size_t bad)
{
    s->bad = bad;
    return psys__fail(&s->err, PSYS_ERR_NONFINITE, "state component %zu became non-finite", bad);
}

psys_status psys__solver_commit(psys_solver *s, double *y1, double t1)
{
    const bool known = s->y1_finite; /* the stages looked already */
    s->y1_finite = false;
    if (s->ode.project)
        s->ode.project(s->ode.ctx, t1, y1);
    const size_t bad = known ? SIZE_MAX : psys__solver_first_nonfinite(s, y1);
    if (bad != SIZE_MAX)
        return psys__solver_nonfinite(s, bad);
    s->ode.set_state(s->ode.ctx, y1);
    s->ode.set_time(s->ode.ctx, t1);
    return PSYS_OK;
}
