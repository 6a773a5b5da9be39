/* Behaviour-function ("energy") forces, notes §6 eq. 2 with the transpose of
 * docs/notes-errata.md#6-eq-2-the-transpose-of-the-jacobian:
 * for C(x_1..x_k) ∈ R^m with J = ∂C/∂x (m × k·dim),
 *   f = -Jᵀ (k_s C + k_d Ċ),  Ċ = J v,  E = ½ k_s C·C.
 * Each behaviour is one force object. Built-in functions (coincide, distance,
 * point-on-plane, point-on-sphere, angle) and user callbacks share the same
 * apply/energy/Jacobian code; only the evaluation of C and J differs. The
 * force Jacobian is the Gauss–Newton approximation ∂f/∂x ≈ -k_s JᵀJ,
 * ∂f/∂v = -k_d JᵀJ, which drops the second derivatives of C.
 *
 * Where a built-in's gradient direction is undefined (coincident particles
 * for distance, the particle at the center for point-on-sphere, a zero arm or
 * θ = 0 or π for angle) its J is zero there: no force, no NaN. Nothing here
 * allocates while applying forces: all scratch lives on the stack, bounded by
 * PSYS_BEHAVIOR_MAX_PARTICLES and PSYS_BEHAVIOR_MAX_COMPONENTS. */
#include "forces/forces.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define MAXK PSYS_BEHAVIOR_MAX_PARTICLES
#define MAXM PSYS_BEHAVIOR_MAX_COMPONENTS
#define MAXQ (MAXK * 3)

static const double PI = 3.14159265358979323846;

typedef struct behavior behavior;
typedef void (*builtin_eval)(const behavior *b, int d, const double *x, double *C, double *J);

/* One behaviour: the definition as added (defaults resolved, normal as
 * given) plus what evaluation needs. */
struct behavior {
    psys_behavior_def def;
    int dim, k, m;
    double unit_normal[3];
    builtin_eval eval; /* NULL for user functions */
};

/* ---- built-in functions: C and J = ∂C/∂x for x = [x_1 | x_2 | ...] ---- */

static double dot(const double *a, const double *b, int d)
{
    double s = 0;
    for (int c = 0; c < d; c++)
        s += a[c] * b[c];
    return s;
}

/* C = x1 - x2 (d components), J = [I | -I]. */
static void coincide_eval(const behavior *b, int d, const double *x, double *C, double *J)
{
    (void)b;
    for (int r = 0; r < d; r++)
        C[r] = x[r] - x[d + r];
    if (J) {
        memset(J, 0, sizeof(double) * (size_t)(d * 2 * d));
        for (int r = 0; r < d; r++) {
            J[r * 2 * d + r] = 1.0;
            J[r * 2 * d + d + r] = -1.0;
        }
    }
}

/* C = |l| - target with l = x1 - x0 (x0 a particle or a fixed point given
 * as `from`), J w.r.t. x1 = l̂ (zero when l = 0). */
static double length_and_dir(int d, const double *x1, const double *x0, double *u)
{
    double l[3], len;
    for (int c = 0; c < d; c++)
        l[c] = x1[c] - x0[c];
    len = sqrt(dot(l, l, d));
    for (int c = 0; c < d; c++)
        u[c] = len > 0 ? l[c] / len : 0.0;
    return len;
}

/* C = |x1 - x2| - r, J = [u | -u] with u = (x1 - x2)/|x1 - x2|. */
static void distance_eval(const behavior *b, int d, const double *x, double *C, double *J)
{
    double u[3];
    C[0] = length_and_dir(d, x, x + d, u) - b->def.r;
    if (J)
        for (int c = 0; c < d; c++) {
            J[c] = u[c];
            J[d + c] = -u[c];
        }
}

/* C = (x - point)·n̂, J = n̂ᵀ. */
static void plane_eval(const behavior *b, int d, const double *x, double *C, double *J)
{
    double rel[3];
    for (int c = 0; c < d; c++)
        rel[c] = x[c] - b->def.point[c];
    C[0] = dot(rel, b->unit_normal, d);
    if (J)
        for (int c = 0; c < d; c++)
            J[c] = b->unit_normal[c];
}

/* C = |x - center| - radius, J = (x - center)ᵀ/|x - center|. */
static void sphere_eval(const behavior *b, int d, const double *x, double *C, double *J)
{
    double u[3];
    C[0] = length_and_dir(d, x, b->def.center, u) - b->def.radius;
    if (J)
        for (int c = 0; c < d; c++)
            J[c] = u[c];
}

/* θ ∈ [0, π] between u = a - b and w = c - b, from atan2(|u×w|, u·w). */
static double angle_of(int d, const double *u, const double *w)
{
    double s;
    if (d == 2) {
        s = fabs(u[0] * w[1] - u[1] * w[0]);
    } else {
        double cx = u[1] * w[2] - u[2] * w[1], cy = u[2] * w[0] - u[0] * w[2], cz = u[0] * w[1] - u[1] * w[0];
        s = sqrt(cx * cx + cy * cy + cz * cz);
    }
    return atan2(s, dot(u, w, d));
}

/* C = θ - angle. With û, ŵ the unit arms and cos θ = û·ŵ,
 *   ∂θ/∂a = -(ŵ - cos θ û)/(|ŵ - cos θ û| |u|),
 *   ∂θ/∂c = -(û - cos θ ŵ)/(|û - cos θ ŵ| |w|),  ∂θ/∂b = -(∂θ/∂a + ∂θ/∂c).
 * At θ = 0 or π (or a zero arm) the direction is undefined: J = 0. */
static void angle_eval(const behavior *b, int d, const double *x, double *C, double *J)
{
    const double *xa = x, *xb = x + d, *xc = x + 2 * d;
    double u[3] = {0, 0, 0}, w[3] = {0, 0, 0};
    for (int c = 0; c < d; c++) {
        u[c] = xa[c] - xb[c];
        w[c] = xc[c] - xb[c];
    }
    C[0] = angle_of(d, u, w) - b->def.angle;
    if (!J)
        return;
    memset(J, 0, sizeof(double) * (size_t)(3 * d));
    double lu = sqrt(dot(u, u, d)), lw = sqrt(dot(w, w, d));
    if (!(lu > 0) || !(lw > 0))
        return;
    double uh[3], wh[3], pa[3], pc[3];
    for (int c = 0; c < d; c++) {
        uh[c] = u[c] / lu;
        wh[c] = w[c] / lw;
    }
    double cs = dot(uh, wh, d);
    for (int c = 0; c < d; c++) {
        pa[c] = wh[c] - cs * uh[c];
        pc[c] = uh[c] - cs * wh[c];
    }
    double na = sqrt(dot(pa, pa, d)), nc = sqrt(dot(pc, pc, d));
    if (!(na > 0) || !(nc > 0))
        return;
    for (int c = 0; c < d; c++) {
        double ga = -pa[c] / (na * lu), gc = -pc[c] / (nc * lw);
        J[c] = ga;
        J[d + c] = -(ga + gc);
        J[2 * d + c] = gc;
    }
}

typedef struct builtin {
    psys_behavior_function f;
    const char *name;
    int nparticles;
    builtin_eval eval;
    const char *const keys[3]; /* scene keys of its parameters */
} builtin;

static const builtin builtins[] = {
    {PSYS_BEHAVIOR_COINCIDE, "coincide", 2, coincide_eval, {NULL}},
    {PSYS_BEHAVIOR_DISTANCE, "distance", 2, distance_eval, {"r", NULL}},
    {PSYS_BEHAVIOR_POINT_ON_PLANE, "point-on-plane", 1, plane_eval, {"point", "normal", NULL}},
    {PSYS_BEHAVIOR_POINT_ON_SPHERE, "point-on-sphere", 1, sphere_eval, {"center", "radius", NULL}},
    {PSYS_BEHAVIOR_ANGLE, "angle", 3, angle_eval, {"angle", NULL}},
};
#define NBUILTINS (sizeof builtins / sizeof builtins[0])

static const builtin *find_builtin(psys_behavior_function f)
{
    for (size_t i = 0; i < NBUILTINS; i++)
        if (builtins[i].f == f)
            return &builtins[i];
    return NULL;
}

const char *psys_behavior_function_name(psys_behavior_function f)
{
    const builtin *bi = find_builtin(f);
    return bi ? bi->name : NULL;
}

bool psys__behavior_builtin(size_t i, psys_behavior_function *f, const char **name, int *nparticles,
                            const char *const **keys)
{
    if (i >= NBUILTINS)
        return false;
    if (f) *f = builtins[i].f;
    if (name) *name = builtins[i].name;
    if (nparticles) *nparticles = builtins[i].nparticles;
    if (keys) *keys = builtins[i].keys;
    return true;
}

psys_status psys_behavior_function_from_name(const char *name, psys_behavior_function *f)
{
    for (size_t i = 0; name && i < NBUILTINS; i++)
        if (strcmp(builtins[i].name, name) == 0) {
            if (f)
                *f = builtins[i].f;
            return PSYS_OK;
        }
    return PSYS_ERR_INVALID;
}

psys_behavior_def psys_behavior_def_default(void)
{
    psys_behavior_def def;
    memset(&def, 0, sizeof def);
    def.function = PSYS_BEHAVIOR_USER;
    def.ks = 1.0;
    def.kd = 0.0;
    def.ncomponents = 1;
    def.fd_step = 1e-6;
    def.r = -1.0;
    def.angle = -1.0;
    return def;
}

/* ---- evaluation shared by forces, energy and the checker ---- */

/* C and, if J is not NULL, J at local positions x (k*dim). */
static void eval_cj(const behavior *b, const double *x, double *C, double *J)
{
    int d = b->dim, nq = b->k * d, m = b->m;
    if (b->eval) {
        b->eval(b, d, x, C, J);
        return;
    }
    const psys_behavior_def *def = &b->def;
    if (J && !def->fd_jacobian)
        memset(J, 0, sizeof(double) * (size_t)(m * nq));
    def->eval(def->ctx, d, x, C, def->fd_jacobian ? NULL : J);
    if (!J || !def->fd_jacobian)
        return;
    /* Central differences of C, step h·max(1, |x_q|), using the step that
     * was actually representable. */
    double xl[MAXQ], cp[MAXM], cm[MAXM];
    memcpy(xl, x, sizeof(double) * (size_t)nq);
    for (int q = 0; q < nq; q++) {
        double h = def->fd_step * fmax(1.0, fabs(x[q]));
        double xp = x[q] + h, xm = x[q] - h;
        xl[q] = xp;
        def->eval(def->ctx, d, xl, cp, NULL);
        xl[q] = xm;
        def->eval(def->ctx, d, xl, cm, NULL);
        xl[q] = x[q];
        for (int r = 0; r < m; r++)
            J[r * nq + q] = (cp[r] - cm[r]) / (xp - xm);
    }
}

static bool finite_vec(const double *v, int n)
{
    for (int i = 0; i < n; i++)
        if (!isfinite(v[i]))
            return false;
    return true;
}

/* Validate def (all but particle indices) and fill b; x (k*dim local
 * positions) resolves the defaults r and angle. */
static psys_status resolve(const psys_behavior_def *def, int dim, const double *x, behavior *b, psys_error *err)
{
    if (!def)
        return psys__fail(err, PSYS_ERR_INVALID, "behaviour definition is NULL");
    if (dim != 2 && dim != 3)
        return psys__fail(err, PSYS_ERR_INVALID, "dimension must be 2 or 3 (got %d)", dim);
    memset(b, 0, sizeof *b);
    b->def = *def;
    b->dim = dim;
    const builtin *bi = NULL;
    if (def->function != PSYS_BEHAVIOR_USER) {
        if (!(bi = find_builtin(def->function)))
            return psys__fail(err, PSYS_ERR_INVALID, "unknown behaviour function %d", (int)def->function);
        if (def->nparticles != bi->nparticles)
            return psys__fail(err, PSYS_ERR_INVALID, "behaviour \"%s\" needs exactly %d particle%s (got %d)",
                              bi->name, bi->nparticles, bi->nparticles == 1 ? "" : "s", def->nparticles);
        b->eval = bi->eval;
        b->m = def->function == PSYS_BEHAVIOR_COINCIDE ? dim : 1;
        b->def.eval = NULL;
        b->def.ctx = NULL;
        b->def.ncomponents = b->m;
        b->def.fd_jacobian = false;
    } else {
        if (!def->eval)
            return psys__fail(err, PSYS_ERR_INVALID, "a user-defined behaviour needs an eval function");
        if (def->ncomponents < 1 || def->ncomponents > MAXM)
            return psys__fail(err, PSYS_ERR_INVALID, "behaviour ncomponents must be 1 to %d (got %d)", MAXM,
                              def->ncomponents);
        if (def->fd_jacobian && !(def->fd_step > 0 && isfinite(def->fd_step)))
            return psys__fail(err, PSYS_ERR_INVALID, "behaviour fd_step must be finite and > 0");
        b->m = def->ncomponents;
    }
    if (def->nparticles < 1 || def->nparticles > MAXK)
        return psys__fail(err, PSYS_ERR_INVALID, "behaviour nparticles must be 1 to %d (got %d)", MAXK,
                          def->nparticles);
    b->k = def->nparticles;
    if (!isfinite(def->ks) || !isfinite(def->kd) || def->ks < 0 || def->kd < 0)
        return psys__fail(err, PSYS_ERR_INVALID, "behaviour ks and kd must be finite and >= 0");
    switch (def->function) {
    case PSYS_BEHAVIOR_DISTANCE:
        if (!isfinite(def->r))
            return psys__fail(err, PSYS_ERR_INVALID, "distance r must be finite");
        if (def->r < 0) {
            double u[3];
            b->def.r = length_and_dir(dim, x, x + dim, u);
            if (!isfinite(b->def.r)) /* a scene holding it could not be saved (JSON has no inf) */
                return psys__fail(err, PSYS_ERR_INVALID, "distance: the particles are too far apart (their distance is not finite)");
        }
        break;
    case PSYS_BEHAVIOR_POINT_ON_PLANE: {
        if (!finite_vec(def->point, dim) || !finite_vec(def->normal, dim))
            return psys__fail(err, PSYS_ERR_INVALID, "point-on-plane point and normal must be finite");
        double len = sqrt(dot(def->normal, def->normal, dim));
        if (!(len > 0) || !isfinite(len))
            return psys__fail(err, PSYS_ERR_INVALID, "point-on-plane normal must be a nonzero vector");
        for (int c = 0; c < dim; c++)
            b->unit_normal[c] = def->normal[c] / len;
        break;
    }
    case PSYS_BEHAVIOR_POINT_ON_SPHERE:
        if (!finite_vec(def->center, dim))
            return psys__fail(err, PSYS_ERR_INVALID, "point-on-sphere center must be finite");
        if (!isfinite(def->radius) || def->radius < 0)
            return psys__fail(err, PSYS_ERR_INVALID, "point-on-sphere radius must be finite and >= 0");
        break;
    case PSYS_BEHAVIOR_ANGLE:
        if (!isfinite(def->angle) || def->angle > PI)
            return psys__fail(err, PSYS_ERR_INVALID, "angle must be finite and at most pi");
        if (def->angle < 0) {
            double u[3] = {0, 0, 0}, w[3] = {0, 0, 0};
            for (int c = 0; c < dim; c++) {
                u[c] = x[c] - x[dim + c];
                w[c] = x[2 * dim + c] - x[dim + c];
            }
            b->def.angle = angle_of(dim, u, w);
            if (!isfinite(b->def.angle))
                return psys__fail(err, PSYS_ERR_INVALID, "angle: the particles' positions give no finite angle");
        }
        break;
    default:
        break;
    }
    /* Leave unused coordinates zero so saved definitions compare equal. */
    for (int c = dim; c < 3; c++) {
        b->def.point[c] = b->def.normal[c] = b->def.center[c] = 0;
    }
    for (int i = b->k; i < MAXK; i++)
        b->def.particles[i] = 0;
    return PSYS_OK;
}

int psys_behavior_components(const psys_behavior_def *def, int dim)
{
    if (!def || (dim != 2 && dim != 3))
        return 0;
    if (def->function == PSYS_BEHAVIOR_USER)
        return def->ncomponents >= 1 && def->ncomponents <= MAXM ? def->ncomponents : 0;
    if (!find_builtin(def->function))
        return 0;
    return def->function == PSYS_BEHAVIOR_COINCIDE ? dim : 1;
}

psys_status psys_behavior_eval(const psys_behavior_def *def, int dim, const double *x, double *C, double *J,
                               psys_error *err)
{
    behavior b;
    psys_status st = resolve(def, dim, x, &b, err);
    if (st != PSYS_OK)
        return st;
    eval_cj(&b, x, C, J);
    psys__ok(err);
    return PSYS_OK;
}

psys_status psys_behavior_check_jacobian(const psys_behavior_def *def, int dim, const double *x, double eps,
                                         double *worst_abs_error, int *row, int *col)
{
    behavior b;
    psys_status st = resolve(def, dim, x, &b, NULL);
    if (st != PSYS_OK)
        return st;
    if (!(eps > 0) || !isfinite(eps))
        eps = 1e-6;
    /* Ask for the analytic J whatever fd_jacobian says, then difference C. */
    b.def.fd_jacobian = false;
    int nq = b.k * dim, m = b.m, wr = 0, wc = 0;
    double Ja[MAXM * MAXQ], C[MAXM], cp[MAXM], cm[MAXM], xl[MAXQ], worst = 0;
    eval_cj(&b, x, C, Ja);
    memcpy(xl, x, sizeof(double) * (size_t)nq);
    for (int q = 0; q < nq; q++) {
        double xp = x[q] + eps, xm = x[q] - eps;
        xl[q] = xp;
        eval_cj(&b, xl, cp, NULL);
        xl[q] = xm;
        eval_cj(&b, xl, cm, NULL);
        xl[q] = x[q];
        for (int r = 0; r < m; r++) {
            double e = fabs(Ja[r * nq + q] - (cp[r] - cm[r]) / (xp - xm));
            if (!isfinite(e))
                e = INFINITY;
            if (e > worst || (q == 0 && r == 0)) {
                worst = e;
                wr = r;
                wc = q;
            }
        }
    }
    if (worst_abs_error)
        *worst_abs_error = worst;
    if (row)
        *row = wr;
    if (col)
        *col = wc;
    return PSYS_OK;
}

/* ---- the force class ---- */

static void gather(const behavior *b, const double *src, double *out)
{
    int d = b->dim;
    for (int i = 0; i < b->k; i++)
        memcpy(out + i * d, src + b->def.particles[i] * (size_t)d, sizeof(double) * (size_t)d);
}

/* The force on each of b's particles, out[i·d + c], from their positions and
 * velocities x, v gathered in b's order (the one evaluation for apply here
 * and for a domain decomposition's owner of the behaviour, mpi/bonded.c). */
static void behavior_forces_of(const behavior *b, const double *x, const double *v, double *out)
{
    int d = b->dim, nq = b->k * d, m = b->m;
    double C[MAXM], J[MAXM * MAXQ], lam[MAXM];
    eval_cj(b, x, C, J);
    for (int r = 0; r < m; r++) {
        const double *Jr = J + r * nq;
        lam[r] = b->def.ks * C[r] + b->def.kd * dot(Jr, v, nq);
    }
    for (int q = 0; q < nq; q++) {
        double s = 0;
        for (int r = 0; r < m; r++)
            s += J[r * nq + q] * lam[r];
        out[q] = -s;
    }
}

static void behavior_apply(void *data, const psys_force_eval *e, double *f)
{
    const behavior *b = data;
    int d = b->dim;
    double x[MAXQ], v[MAXQ], out[MAXQ];
    gather(b, e->x, x);
    gather(b, e->v, v);
    behavior_forces_of(b, x, v, out);
    for (int i = 0; i < b->k; i++) {
        double *fi = f + b->def.particles[i] * (size_t)d;
        for (int c = 0; c < d; c++)
            fi[c] += out[i * d + c]; /* f + (-s): the same bits as f - s */
    }
}

void psys__behavior_forces(const void *data, const double *x, const double *v, double *out)
{
    behavior_forces_of(data, x, v, out);
}
int psys__behavior_count(const void *data) { return ((const behavior *)data)->k; }
size_t psys__behavior_particle(const void *data, int i) { return ((const behavior *)data)->def.particles[i]; }
const psys_behavior_def *psys__behavior_def(const void *data) { return &((const behavior *)data)->def; }
void *psys__behavior_clone(const void *data)
{
    behavior *b = malloc(sizeof *b);
    if (b)
        memcpy(b, data, sizeof *b);
    return b;
}

static double behavior_energy(void *data, const psys_force_eval *e)
{
    const behavior *b = data;
    double x[MAXQ], C[MAXM];
    gather(b, e->x, x);
    eval_cj(b, x, C, NULL);
    return 0.5 * b->def.ks * dot(C, C, b->m);
}

/* Gauss–Newton: ∂f_i/∂x_j ≈ -k_s J_iᵀ J_j, ∂f_i/∂v_j = -k_d J_iᵀ J_j. */
static void behavior_jacobian(void *data, const psys_force_eval *e, psys_jacobian *Jsink)
{
    const behavior *b = data;
    int d = b->dim, nq = b->k * d, m = b->m;
    double x[MAXQ], C[MAXM], J[MAXM * MAXQ];
    gather(b, e->x, x);
    eval_cj(b, x, C, J);
    for (int i = 0; i < b->k; i++)
        for (int j = 0; j < b->k; j++) {
            double bx[9], bv[9];
            for (int r = 0; r < d; r++)
                for (int c = 0; c < d; c++) {
                    double s = 0;
                    for (int l = 0; l < m; l++)
                        s += J[l * nq + i * d + r] * J[l * nq + j * d + c];
                    bx[r * d + c] = -b->def.ks * s;
                    bv[r * d + c] = -b->def.kd * s;
                }
            psys_jacobian_add(Jsink, b->def.particles[i], b->def.particles[j], bx, bv);
        }
}

static const struct psys__force_terms behavior_terms = {PSYS__TERMS_BEHAVIOR};
/* One term over the behaviour's particles (damped: not velocity-free). */
const psys_force_class psys_behavior_class = {.name = "behavior",
                                              .apply = behavior_apply,
                                              .energy = behavior_energy,
                                              .jacobian = behavior_jacobian,
                                              .destroy = free,
                                              .traits = PSYS_FORCE_BONDED,
                                              .clone = psys__behavior_clone,
                                              .terms = &behavior_terms};
const psys_force_class psys_behavior_user_class = {.name = "user-behavior",
                                                   .apply = behavior_apply,
                                                   .energy = behavior_energy,
                                                   .jacobian = behavior_jacobian,
                                                   .destroy = free,
                                                   .traits = PSYS_FORCE_BONDED,
                                                   .clone = psys__behavior_clone,
                                                   .terms = &behavior_terms};

psys_status psys_system_add_behavior(psys_system *sys, const psys_behavior_def *def)
{
    int d = sys->dim;
    if (!def)
        return psys__fail(&sys->err, PSYS_ERR_INVALID, "behaviour definition is NULL");
    if (def->nparticles < 1 || def->nparticles > MAXK)
        return psys__fail(&sys->err, PSYS_ERR_INVALID, "behaviour nparticles must be 1 to %d (got %d)", MAXK,
                          def->nparticles);
    double x[MAXQ];
    for (int i = 0; i < def->nparticles; i++) {
        if (def->particles[i] >= sys->n)
            return psys__fail(&sys->err, PSYS_ERR_INVALID, "behaviour refers to particle %zu, which does not exist",
                              def->particles[i]);
        for (int j = 0; j < i; j++)
            if (def->particles[j] == def->particles[i])
                return psys__fail(&sys->err, PSYS_ERR_INVALID,
                                  "a behaviour's particles must be different (particle %zu is listed twice)",
                                  def->particles[i]);
        memcpy(x + i * d, sys->x + def->particles[i] * (size_t)d, sizeof(double) * (size_t)d);
    }
    behavior *b = malloc(sizeof *b);
    if (!b)
        return psys__fail(&sys->err, PSYS_ERR_NOMEM, "out of memory adding a behaviour");
    psys_status st = resolve(def, d, x, b, &sys->err);
    if (st != PSYS_OK) {
        free(b);
        return st;
    }
    return psys_system_add_force(sys, b->eval ? &psys_behavior_class : &psys_behavior_user_class, b);
}

psys_status psys_system_behavior(const psys_system *sys, size_t i, psys_behavior_def *def)
{
    const psys_force_class *cls = psys_system_force_class(sys, i);
    if (cls != &psys_behavior_class && cls != &psys_behavior_user_class)
        return PSYS_ERR_INVALID;
    if (def)
        *def = ((const behavior *)psys_system_force_data(sys, i))->def;
    return PSYS_OK;
}
