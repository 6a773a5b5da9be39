/* The particle system as an ODE (the notes' outside view): state
 * [x | v], the derivative [v | f/m], projection onto the controllers,
 * masses and Jacobians for implicit solvers, and the private fast paths
 * a solver gets when the system creates it. */
#include "sim/sim.h"
#include "solvers/solver.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* dst = src, n doubles, split among nt threads. */
static void par_copy(int nt, double *restrict dst, const double *restrict src, size_t n)
{
    if (nt <= 1 || n < PSYS_PAR_MIN) {
        memcpy(dst, src, n * sizeof(double));
        return;
    }
    PSYS_OMP(omp parallel for schedule(static) num_threads(nt))
    for (int t = 0; t < nt; t++) {
        size_t a = n * (size_t)t / (size_t)nt, b = n * (size_t)(t + 1) / (size_t)nt;
        memcpy(dst + a, src + a, (b - a) * sizeof(double));
    }
}

/* Clear f, let every force object add into it, then the planes' contact
 * forces, which depend on the total applied force (notes §7.3). With MPI
 * (core/comm_mpi.c), pair forces fill only this rank's rows and the rows are combined
 * before the contact forces: every rank ends with the serial f, bit for bit. */
static psys_status accumulate(const psys_system *s, const psys_force_eval *e, double *f)
{
#ifdef PSYS_MPI
    bool split = s->dist && psys__dist_begin(s, e->x);
#endif
    const size_t nd = s->n * (size_t)s->dim;
    const int nt = e->threads;
    PSYS_PAR_FOR(nt, nd)
    for (size_t i = 0; i < nd; i++)
        f[i] = 0.0;
    for (size_t i = 0; i < s->nforces; i++)
        s->forces[i].cls->apply(s->forces[i].data, e, f);
#ifdef PSYS_MPI
    if (split && psys__dist_finish(s, f) != PSYS_OK)
        return PSYS_ERR_INVALID;
#endif
    if (s->nplanes)
        psys__contact_forces(s, e->x, e->v, f);
    return PSYS_OK;
}

/* ---- ODE view ---- */

static void ode_get_state(void *ctx, double *y)
{
    const psys_system *s = ctx;
    size_t nd = s->n * (size_t)s->dim;
    if (nd == 0) /* no particles: s->x may be NULL, and memcpy(_, NULL, 0) is undefined */
        return;
    int nt = psys_system_effective_threads(s);
    if (s->ode_perm) {
        psys__order_copy(s->ode_perm, s->ode_perm_n, s->n, s->dim, s->x, y, false, nt);
        psys__order_copy(s->ode_perm, s->ode_perm_n, s->n, s->dim, s->v, y + nd, false, nt);
        return;
    }
    par_copy(nt, y, s->x, nd);
    par_copy(nt, y + nd, s->v, nd);
}

static void ode_set_state(void *ctx, const double *y)
{
    psys_system *s = ctx;
    size_t nd = s->n * (size_t)s->dim;
    if (nd == 0)
        return;
    int nt = psys_system_effective_threads(s);
    if (s->ode_perm) {
        psys__order_copy(s->ode_perm, s->ode_perm_n, s->n, s->dim, y, s->x, true, nt);
        psys__order_copy(s->ode_perm, s->ode_perm_n, s->n, s->dim, y + nd, s->v, true, nt);
        return;
    }
    par_copy(nt, s->x, y, nd);
    par_copy(nt, s->v, y + nd, nd);
}

/* Controlled particles take their prescribed state at the stage time. */
static void ode_project(void *ctx, double t, double *y)
{
    const psys_system *s = ctx;
    int d = s->dim;
    double *x = y, *v = y + s->n * (size_t)d;
    for (size_t k = 0; k < s->nctrl; k++) {
        size_t i = s->ctrl[k].particle;
        if (s->ode_perm) /* y in the springs' order */
            i = s->ode_slot[i];
        psys__controller_eval(&s->ctrl[k], d, t, x + i * d, v + i * d);
    }
}

static double ode_get_time(void *ctx) { return ((const psys_system *)ctx)->t; }
static void ode_set_time(void *ctx, double t) { ((psys_system *)ctx)->t = t; }

/* Notes' ParticleDerivative with each particle's own mass
 * (docs/notes-errata.md#3-particlederivative-each-particles-own-mass):
 * [x' | v'] = [v | f/m]; fixed particles have inv_mass 0 and v 0. Without
 * with_v the first half is left as it was, unless the fused sweep runs. */
static psys_status derivative_into(void *ctx, double t, const double *y, double *ydot, bool with_v)
{
    psys_system *s = ctx;
    size_t d = (size_t)s->dim, nd = s->n * d;
    psys_force_eval e;
    psys__sys_eval(s, t, y, y + nd, &e);
    bool fused = false;
    if (psys__fused_derivative(s, &e, y, ydot, NULL, &fused) != PSYS_OK)
        return psys__fail(&s->err, PSYS_ERR_NOMEM, "out of memory preparing the springs");
    if (fused)
        return PSYS_OK;
    if (s->ode_perm) /* cannot happen: psys__state_order_begin checked that the fused path takes s */
        return psys__fail(&s->err, PSYS_ERR_INVALID, "state in the springs' order without the fused derivative");
    if (s->springs && psys__springs_prepare(s->springs) != PSYS_OK)
        return psys__fail(&s->err, PSYS_ERR_NOMEM, "out of memory preparing the springs");
    if (accumulate(s, &e, s->f) != PSYS_OK)
        return psys__fail(&s->err, PSYS_ERR_INVALID, "MPI exchange of the forces failed");
    const int nt = e.threads;
    if (nd && with_v)
        par_copy(nt, ydot, y + nd, nd);
    double *restrict a = ydot + nd;
    const double *restrict f = s->f, *restrict im = s->inv_mass;
    /* Not-free particles get exactly 0, even when their force overflowed
     * (inf·0 would be NaN and blame an anchor for a free particle's blow-up).
     * One loop per dimension so the compiler sees the stride and vectorises. */
    if (d == 2) {
        PSYS_PAR_FOR(nt, nd)
        for (size_t i = 0; i < s->n; i++) {
            double w = im[i];
            a[2 * i] = w != 0 ? f[2 * i] * w : 0.0;
            a[2 * i + 1] = w != 0 ? f[2 * i + 1] * w : 0.0;
        }
    } else {
        PSYS_PAR_FOR(nt, nd)
        for (size_t i = 0; i < s->n; i++) {
            double w = im[i];
            a[3 * i] = w != 0 ? f[3 * i] * w : 0.0;
            a[3 * i + 1] = w != 0 ? f[3 * i + 1] * w : 0.0;
            a[3 * i + 2] = w != 0 ? f[3 * i + 2] * w : 0.0;
        }
    }
    return PSYS_OK;
}

static psys_status ode_derivative(void *ctx, double t, const double *y, double *ydot)
{
    return derivative_into(ctx, t, y, ydot, true);
}

/* The accelerations only (psys__ode_fast.acceleration): the derivative less its
 * copy of v into ydot's first half, where the fused sweep does not take
 * the system (it writes both halves anyway). */
static psys_status ode_acceleration(void *ctx, double t, const double *y, double *ydot)
{
    return derivative_into(ctx, t, y, ydot, false);
}

/* Whether no force reads the velocities (psys__ode_fast.velocity_free):
 * every force class says so (PSYS_FORCE_VELOCITY_FREE), and no planes
 * (contact and friction) or controlled particles (whose prescribed
 * velocities the solver's projection writes). */
static bool ode_velocity_free(void *ctx)
{
    const psys_system *s = ctx;
    if (s->nplanes || s->nctrl)
        return false;
    for (size_t i = 0; i < s->nforces; i++) {
        if (!(s->forces[i].cls->traits & PSYS_FORCE_VELOCITY_FREE))
            return false;
    }
    return true;
}

/* The derivative with the solver's stage work applied as it is computed:
 * only where the fused derivative takes the system. */
static psys_status ode_derivative_stage(void *ctx, double t, const double *y, const psys__stage_pass *pass)
{
    psys_system *s = ctx;
    if (!y)
        return psys__fused_eligible(s) ? PSYS_OK : PSYS_ERR_UNSUPPORTED;
    psys_force_eval e;
    psys__sys_eval(s, t, y, y + s->n * (size_t)s->dim, &e);
    bool fused = false;
    if (psys__fused_derivative(s, &e, y, NULL, pass, &fused) != PSYS_OK)
        return psys__fail(&s->err, PSYS_ERR_NOMEM, "out of memory preparing the springs");
    return fused ? PSYS_OK : PSYS_ERR_UNSUPPORTED;
}

/* The chain sweep of a step from y0, or from the system's own x and v
 * (y0 NULL: psys__fused_chain). */
static psys_status chain_from(psys_system *s, double t, const double *y0, int stages, const psys__stage_pass *pass)
{
    psys_force_eval e;
    psys__sys_eval(s, t, y0 ? y0 : s->x, y0 ? y0 + s->n * (size_t)s->dim : s->v, &e);
    bool used = false;
    if (psys__fused_chain(s, &e, y0, stages, pass, &used) != PSYS_OK)
        return psys__fail(&s->err, PSYS_ERR_NOMEM, "out of memory preparing the springs");
    return used ? PSYS_OK : PSYS_ERR_UNSUPPORTED;
}

/* All stages of a chain step at once, where the fused derivative takes the
 * system and nothing depends on the stage time: no controlled particles
 * (project), no muscles (rest lengths of t). */
static psys_status ode_derivative_chain(void *ctx, double t, const double *y0, int stages, const double *c,
                                        const psys__stage_pass *pass)
{
    psys_system *s = ctx;
    (void)c; /* the forces the chain takes do not depend on time */
    if (!y0)
        return psys__fused_chain_eligible(s, stages) ? PSYS_OK : PSYS_ERR_UNSUPPORTED;
    return chain_from(s, t, y0, stages, pass);
}

/* derivative_chain from the system's own x and v: no copy of the state
 * into the solver's y0, and the result written back into x and v where the
 * solver offers it (psys__stage_pass.in_place), no copy out either. Not with
 * the state in the springs' order, where the solver's vectors and x, v
 * differ in order. */
static psys_status ode_derivative_chain_current(void *ctx, double t, int stages, const double *c,
                                                const psys__stage_pass *pass)
{
    psys_system *s = ctx;
    (void)c;
    if (s->ode_perm || s->n == 0)
        return PSYS_ERR_UNSUPPORTED;
    return chain_from(s, t, NULL, stages, pass);
}

/* Implicit-solver view: masses (0 for particles the solver must not move). */
static void ode_mass(void *ctx, double *m)
{
    const psys_system *s = ctx;
    size_t d = (size_t)s->dim;
    for (size_t i = 0; i < s->n; i++)
        for (size_t k = 0; k < d; k++)
            m[i * d + k] = (s->flags[i] & PSYS_PARTICLE_NOT_FREE) ? 0.0 : s->mass[i];
}

static psys_status ode_jacobian(void *ctx, double t, const double *y, psys_jacobian *J)
{
    const psys_system *s = ctx;
    psys_force_eval e;
    psys__sys_eval(s, t, y, y + s->n * (size_t)s->dim, &e);
    for (size_t i = 0; i < s->nforces; i++)
        if (s->forces[i].cls->jacobian)
            s->forces[i].cls->jacobian(s->forces[i].data, &e, J);
    return PSYS_OK;
}

psys_ode psys_system_ode(psys_system *s)
{
    psys_ode o;
    memset(&o, 0, sizeof o);
    o.size = 2 * s->n * (size_t)s->dim;
    o.npos = s->n * (size_t)s->dim;
    o.ctx = s;
    o.get_state = ode_get_state;
    o.set_state = ode_set_state;
    o.get_time = ode_get_time;
    o.set_time = ode_set_time;
    o.derivative = ode_derivative;
    o.project = ode_project;
    o.mass = ode_mass;
    o.jacobian = ode_jacobian;
    o.block = s->dim;
    return o;
}

psys__ode_fast psys__system_ode_fast(psys_system *s)
{
    (void)s; /* the hooks take the system as ctx, as psys_system_ode's callbacks do */
    psys__ode_fast f;
    f.derivative_stage = ode_derivative_stage;
    f.acceleration = ode_acceleration;
    f.velocity_free = ode_velocity_free;
    f.derivative_chain = ode_derivative_chain;
    f.derivative_chain_current = ode_derivative_chain_current;
    return f;
}

psys_solver *psys_system_solver_create(psys_system *s, const char *name, psys_error *err)
{
    if (!s) {
        psys__fail(err, PSYS_ERR_INVALID, "no system to create a solver for");
        return NULL;
    }
    const psys_ode o = psys_system_ode(s);
    const psys__ode_fast f = psys__system_ode_fast(s);
    return psys__solver_create_fast(name, &o, &f, s, err);
}

psys_status psys_system_compute_forces(psys_system *s, double *f)
{
    psys_force_eval e;
    psys__sys_eval(s, s->t, s->x, s->v, &e);
    if (s->springs && psys__springs_prepare(s->springs) != PSYS_OK)
        return psys__fail(&s->err, PSYS_ERR_NOMEM, "out of memory preparing the springs");
    if (accumulate(s, &e, f) != PSYS_OK)
        return psys__fail(&s->err, PSYS_ERR_INVALID, "MPI exchange of the forces failed");
    return PSYS_OK;
}


/* ---- Jacobians ---- */

typedef struct dense_sink {
    psys_jacobian base;
    size_t nd;
    int dim;
    double *dfdx, *dfdv;
} dense_sink;

static void dense_add(psys_jacobian *J, size_t i, size_t j, const double *dfdx, const double *dfdv)
{
    dense_sink *ds = (dense_sink *)J;
    int d = ds->dim;
    for (int r = 0; r < d; r++)
        for (int c = 0; c < d; c++) {
            size_t at = (i * d + r) * ds->nd + j * d + c;
            if (dfdx)
                ds->dfdx[at] += dfdx[r * d + c];
            if (dfdv)
                ds->dfdv[at] += dfdv[r * d + c];
        }
}


psys_status psys_system_dense_jacobian(psys_system *s, double *dfdx, double *dfdv)
{
    size_t nd = s->n * (size_t)s->dim;
    dense_sink ds = {{dense_add, NULL, false}, nd, s->dim, dfdx, dfdv};
    memset(dfdx, 0, nd * nd * sizeof(double));
    memset(dfdv, 0, nd * nd * sizeof(double));
    psys_force_eval e;
    psys__sys_eval(s, s->t, s->x, s->v, &e);
    for (size_t i = 0; i < s->nforces; i++) {
        if (!s->forces[i].cls->jacobian)
            return psys__fail(&s->err, PSYS_ERR_UNSUPPORTED, "force \"%s\" provides no Jacobian",
                              s->forces[i].cls->name);
        s->forces[i].cls->jacobian(s->forces[i].data, &e, &ds.base);
    }
    return PSYS_OK;
}

psys_status psys_system_fd_jacobian(psys_system *s, double eps, double *dfdx, double *dfdv)
{
    size_t nd = s->n * (size_t)s->dim;
    double *fp = psys__calloc(nd, sizeof(double)), *fm = psys__calloc(nd, sizeof(double));
    if (!fp || !fm) {
        free(fp);
        free(fm);
        return psys__fail(&s->err, PSYS_ERR_NOMEM, "out of memory for finite differences");
    }
    double *vars[2] = {s->x, s->v};
    double *outs[2] = {dfdx, dfdv};
    for (int w = 0; w < 2; w++)
        for (size_t j = 0; j < nd; j++) {
            double keep = vars[w][j];
            vars[w][j] = keep + eps;
            psys_system_compute_forces(s, fp);
            vars[w][j] = keep - eps;
            psys_system_compute_forces(s, fm);
            vars[w][j] = keep;
            for (size_t i = 0; i < nd; i++)
                outs[w][i * nd + j] = (fp[i] - fm[i]) / (2 * eps);
        }
    free(fp);
    free(fm);
    return PSYS_OK;
}

