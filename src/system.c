/* The particle system: SoA particles, the force list, and its ODE view. */
#include "internal.h"
#include "solver_fast.h"

#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

psys_system *psys_system_create(int dim, psys_error *err)
{
    if (dim != 2 && dim != 3) {
        psys__fail(err, PSYS_ERR_INVALID, "dimension must be 2 or 3 (got %d)", dim);
        return NULL;
    }
    psys_system *s = calloc(1, sizeof *s);
    if (!s) {
        psys__fail(err, PSYS_ERR_NOMEM, "out of memory creating a system");
        return NULL;
    }
    s->dim = dim;
    s->ode_epoch = s->epoch - 1; /* no masses in the springs' order filled yet */
    psys__ok(err);
    return s;
}

/* Free the force objects' data and every per-particle array. */
static void free_particles_and_forces(psys_system *s)
{
    for (size_t i = 0; i < s->nforces; i++)
        if (s->forces[i].cls->destroy)
            s->forces[i].cls->destroy(s->forces[i].data);
    for (size_t i = 0; i < s->n; i++)
        free(s->ids[i]);
    free(s->charge);
    free(s->x);
    free(s->v);
    free(s->f);
    free(s->mass);
    free(s->inv_mass);
    free(s->flags);
    free(s->ids);
    free(s->id_index);
}

void psys__system_release(psys_system *s)
{
    free_particles_and_forces(s);
    s->nforces = 0;
    s->springs = NULL;
    s->x = s->v = s->f = s->mass = s->inv_mass = s->charge = NULL;
    s->flags = NULL;
    s->ids = NULL;
    s->id_index = NULL;
    s->n = s->cap = s->nids = s->id_index_cap = 0;
    s->ncharge = s->charge_cap = 0;
}

void psys_system_destroy(psys_system *s)
{
    if (!s)
        return;
    free_particles_and_forces(s);
    for (size_t k = 0; k < s->nctrl; k++)
        psys__controller_free(&s->ctrl[k]);
    free(s->ctrl);
    free(s->planes);
    free(s->scratch);
    free(s->forces);
    free(s->ode_mass);
    free(s->ode_inv_mass);
    free(s->ode_slot);
#ifdef PSYS_MPI
    psys__dist_free(s->dist);
#endif
    free(s);
}

/* ---- id index: an open-addressing hash of particle ids, so that loading a
 * scene of n named particles (and springs naming them) takes O(n), not O(n²). */

static size_t id_hash(const char *id)
{
    uint64_t h = 1469598103934665603ull; /* FNV-1a */
    for (const unsigned char *c = (const unsigned char *)id; *c; c++)
        h = (h ^ *c) * 1099511628211ull;
    return (size_t)h;
}

static void id_index_put(psys_system *s, size_t i)
{
    size_t mask = s->id_index_cap - 1, k = id_hash(s->ids[i]) & mask;
    while (s->id_index[k])
        k = (k + 1) & mask;
    s->id_index[k] = i + 1;
    s->nids++;
}

/* Refill the index from the ids of particles 0..n-1 (no allocation). */
static void id_index_rebuild(psys_system *s)
{
    if (!s->id_index)
        return;
    memset(s->id_index, 0, s->id_index_cap * sizeof *s->id_index);
    s->nids = 0;
    for (size_t i = 0; i < s->n; i++)
        if (s->ids[i])
            id_index_put(s, i);
}

/* Room in the index for one more id (at most half the slots in use). */
static psys_status id_index_reserve(psys_system *s)
{
    if (2 * (s->nids + 1) <= s->id_index_cap)
        return PSYS_OK;
    size_t cap = s->id_index_cap ? 2 * s->id_index_cap : 64;
    size_t *t = psys__calloc(cap, sizeof *t);
    if (!t)
        return PSYS_ERR_NOMEM;
    free(s->id_index);
    s->id_index = t;
    s->id_index_cap = cap;
    id_index_rebuild(s);
    return PSYS_OK;
}

const char *psys_system_last_error(const psys_system *s) { return s->err.message; }
int psys_system_dim(const psys_system *s) { return s->dim; }
size_t psys_system_count(const psys_system *s) { return s->n; }
double psys_system_time(const psys_system *s) { return s->t; }
void psys_system_set_time(psys_system *s, double t) { s->t = t; }
const double *psys_system_positions(const psys_system *s) { return s->x; }
const double *psys_system_velocities(const psys_system *s) { return s->v; }
const double *psys_system_masses(const psys_system *s) { return s->mass; }

static bool all_finite(const double *a, int n)
{
    for (int i = 0; i < n; i++)
        if (!isfinite(a[i]))
            return false;
    return true;
}

/* Grow every per-particle array to hold at least want particles. */
static psys_status reserve(psys_system *s, size_t want)
{
    if (want <= s->cap)
        return PSYS_OK;
    size_t cap = s->cap ? s->cap : 16;
    while (cap < want)
        cap *= 2;
    size_t d = (size_t)s->dim;
    void *p;
#define GROW(field, count, type)                                         \
    p = psys__realloc(s->field, (count), sizeof(type));                  \
    if (!p)                                                              \
        return psys__fail(&s->err, PSYS_ERR_NOMEM, "out of memory adding particles"); \
    s->field = p;
    GROW(x, cap * d, double)
    GROW(v, cap * d, double)
    GROW(f, cap * d, double)
    GROW(mass, cap, double)
    GROW(inv_mass, cap, double)
    GROW(flags, cap, unsigned char)
    GROW(ids, cap, char *)
#undef GROW
    s->cap = cap;
    return psys__planes_reserve(s);
}

psys_status psys_system_add_particle(psys_system *s, const double *x, const double *v,
                                     double mass, const char *id, size_t *index)
{
    int d = s->dim;
    if (!x || !all_finite(x, d) || (v && !all_finite(v, d)))
        return psys__fail(&s->err, PSYS_ERR_INVALID, "particle position and velocity must be finite");
    if (!(mass >= DBL_MIN) || !isfinite(mass)) /* DBL_MIN: 1/mass finite */
        return psys__fail(&s->err, PSYS_ERR_INVALID, "particle mass must be a finite number > 0 and normal (got %g)",
                          mass);
    if (id) {
        size_t dup;
        if (psys_system_find(s, id, &dup) == PSYS_OK)
            return psys__fail(&s->err, PSYS_ERR_INVALID, "duplicate particle id \"%s\"", id);
    }
    return psys__system_add_particle_unique(s, x, v, mass, id, index);
}

psys_status psys__system_reserve(psys_system *s, size_t want) { return reserve(s, want); }

void psys__system_truncate(psys_system *s, size_t n)
{
    for (size_t i = n; i < s->n; i++) {
        free(s->ids[i]);
        s->ids[i] = NULL;
    }
    if (n < s->n) {
        s->n = n;
        id_index_rebuild(s);
    }
    if (s->ncharge > s->n)
        s->ncharge = s->n; /* removed particles take no charge with them to their successors */
}

psys_status psys__system_add_particle_unique(psys_system *s, const double *x, const double *v, double mass,
                                             const char *id, size_t *index)
{
    int d = s->dim;
    if (!x || !all_finite(x, d) || (v && !all_finite(v, d)))
        return psys__fail(&s->err, PSYS_ERR_INVALID, "particle position and velocity must be finite");
    if (!(mass >= DBL_MIN) || !isfinite(mass)) /* DBL_MIN: 1/mass finite */
        return psys__fail(&s->err, PSYS_ERR_INVALID, "particle mass must be a finite number > 0 and normal (got %g)",
                          mass);
    if (reserve(s, s->n + 1) != PSYS_OK)
        return PSYS_ERR_NOMEM;
    char *copy = NULL;
    if (id && (id_index_reserve(s) != PSYS_OK || !(copy = psys__strdup(id))))
        return psys__fail(&s->err, PSYS_ERR_NOMEM, "out of memory adding a particle");
    size_t i = s->n;
    for (int k = 0; k < d; k++) {
        s->x[i * d + k] = x[k];
        s->v[i * d + k] = v ? v[k] : 0.0;
        s->f[i * d + k] = 0.0;
    }
    s->mass[i] = mass;
    s->inv_mass[i] = 1.0 / mass;
    s->flags[i] = 0;
    s->ids[i] = copy;
    if (copy)
        id_index_put(s, i);
    s->n++;
    s->epoch++;
    if (index)
        *index = i;
    return PSYS_OK;
}

psys_status psys_system_find(const psys_system *s, const char *id, size_t *index)
{
    if (!s->id_index_cap)
        return PSYS_ERR_INVALID; /* no particle has an id */
    size_t mask = s->id_index_cap - 1;
    for (size_t k = id_hash(id) & mask; s->id_index[k]; k = (k + 1) & mask) {
        size_t i = s->id_index[k] - 1;
        if (strcmp(s->ids[i], id) == 0) {
            if (index)
                *index = i;
            return PSYS_OK;
        }
    }
    return PSYS_ERR_INVALID;
}

const char *psys_system_particle_id(const psys_system *s, size_t i)
{
    return i < s->n ? s->ids[i] : NULL;
}

psys_status psys_system_set_fixed(psys_system *s, size_t i, bool fixed)
{
    if (i >= s->n)
        return psys__fail(&s->err, PSYS_ERR_INVALID, "no particle %zu", i);
    if (fixed && (s->flags[i] & PSYS_PARTICLE_CONTROLLED))
        return psys__fail(&s->err, PSYS_ERR_INVALID, "particle %zu is controlled; release it before fixing it", i);
    s->epoch++;
    if (fixed) {
        s->flags[i] |= PSYS_PARTICLE_FIXED;
        s->inv_mass[i] = 0.0; /* a = f/m becomes 0 with no branch in the hot loop */
        for (int k = 0; k < s->dim; k++)
            s->v[i * s->dim + k] = 0.0;
    } else {
        s->flags[i] &= (unsigned char)~PSYS_PARTICLE_FIXED;
        if (!(s->flags[i] & PSYS_PARTICLE_CONTROLLED))
            s->inv_mass[i] = 1.0 / s->mass[i];
    }
    return PSYS_OK;
}

bool psys_system_is_fixed(const psys_system *s, size_t i)
{
    return i < s->n && (s->flags[i] & PSYS_PARTICLE_FIXED);
}

psys_status psys_system_set_particle(psys_system *s, size_t i, const double *x, const double *v)
{
    int d = s->dim;
    if (i >= s->n)
        return psys__fail(&s->err, PSYS_ERR_INVALID, "no particle %zu", i);
    if ((x && !all_finite(x, d)) || (v && !all_finite(v, d)))
        return psys__fail(&s->err, PSYS_ERR_INVALID, "particle position and velocity must be finite");
    if (x)
        memcpy(s->x + i * d, x, sizeof(double) * (size_t)d);
    if (v && !(s->flags[i] & PSYS_PARTICLE_FIXED))
        memcpy(s->v + i * d, v, sizeof(double) * (size_t)d);
    return PSYS_OK;
}

psys_status psys_system_add_force(psys_system *s, const psys_force_class *cls, void *data)
{
    if (!cls || !cls->apply) {
        if (cls && cls->destroy)
            cls->destroy(data);
        return psys__fail(&s->err, PSYS_ERR_INVALID, "a force class needs an apply function");
    }
    if (s->nforces == s->forces_cap) {
        size_t cap = s->forces_cap ? s->forces_cap * 2 : 8;
        psys__force *p = psys__realloc(s->forces, cap, sizeof *p);
        if (!p) {
            if (cls->destroy)
                cls->destroy(data);
            return psys__fail(&s->err, PSYS_ERR_NOMEM, "out of memory adding a force");
        }
        s->forces = p;
        s->forces_cap = cap;
    }
    s->forces[s->nforces].cls = cls;
    s->forces[s->nforces].data = data;
    s->nforces++;
    s->epoch++;
    return PSYS_OK;
}

size_t psys_system_force_count(const psys_system *s) { return s->nforces; }

const psys_force_class *psys_system_force_class(const psys_system *s, size_t i)
{
    return i < s->nforces ? s->forces[i].cls : NULL;
}

void *psys_system_force_data(const psys_system *s, size_t i)
{
    return i < s->nforces ? s->forces[i].data : NULL;
}

psys_status psys_system_add_spring(psys_system *s, size_t a, size_t b, double ks, double kd, double rest)
{
    if (a >= s->n || b >= s->n)
        return psys__fail(&s->err, PSYS_ERR_INVALID, "spring refers to a particle that does not exist");
    if (a == b)
        return psys__fail(&s->err, PSYS_ERR_INVALID, "a spring needs two different particles");
    if (!isfinite(ks) || !isfinite(kd) || ks < 0 || kd < 0)
        return psys__fail(&s->err, PSYS_ERR_INVALID, "spring ks and kd must be finite and >= 0");
    if (!isfinite(rest))
        return psys__fail(&s->err, PSYS_ERR_INVALID, "spring rest length must be finite");
    if (rest < 0) {
        double l2 = 0;
        for (int k = 0; k < s->dim; k++) {
            double dx = s->x[a * s->dim + k] - s->x[b * s->dim + k];
            l2 += dx * dx;
        }
        rest = sqrt(l2);
        if (!isfinite(rest)) { /* the squares overflowed: scale by the largest component */
            double big = 0, q2 = 0;
            for (int k = 0; k < s->dim; k++)
                big = fmax(big, fabs(s->x[a * s->dim + k] - s->x[b * s->dim + k]));
            for (int k = 0; k < s->dim; k++) {
                double q = (s->x[a * s->dim + k] - s->x[b * s->dim + k]) / big;
                q2 += q * q;
            }
            rest = big * sqrt(q2);
        }
        if (!isfinite(rest)) /* a scene holding it could not be saved (JSON has no inf) */
            return psys__fail(&s->err, PSYS_ERR_INVALID,
                              "particles %zu and %zu are too far apart for a spring (their distance is not finite)", a, b);
    }
    if (!s->springs) {
        void *set = psys__springs_create(s);
        if (!set)
            return psys__fail(&s->err, PSYS_ERR_NOMEM, "out of memory adding a spring");
        if (psys_system_add_force(s, &psys_spring_class, set) != PSYS_OK)
            return s->err.code;
        s->springs = set;
    }
    if (psys__springs_add(s->springs, a, b, ks, kd, rest) != PSYS_OK)
        return psys__fail(&s->err, PSYS_ERR_NOMEM, "out of memory adding a spring");
    return PSYS_OK;
}

size_t psys_system_spring_count(const psys_system *s)
{
    return s->springs ? psys__springs_count(s->springs) : 0;
}

psys_status psys_system_spring(const psys_system *s, size_t k, size_t *a, size_t *b,
                               double *ks, double *kd, double *rest)
{
    if (k >= psys_system_spring_count(s))
        return PSYS_ERR_INVALID;
    psys__springs_get(s->springs, k, a, b, ks, kd, rest);
    return PSYS_OK;
}

void psys__sys_eval(const psys_system *s, double t, const double *x, const double *v, psys_force_eval *e)
{
    e->dim = s->dim;
    e->n = s->n;
    e->t = t;
    e->x = x;
    e->v = v;
    e->mass = s->mass;
    e->inv_mass = s->inv_mass;
    e->flags = s->flags;
    e->threads = psys_system_effective_threads(s);
}

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
 * (mpi.c), pair forces fill only this rank's rows and the rows are combined
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

size_t psys_system_particle_of_component(const psys_system *s, size_t k)
{
    size_t nd = s->n * (size_t)s->dim;
    return (k < nd ? k : k - nd) / (size_t)s->dim;
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

double psys_system_kinetic_energy(const psys_system *s)
{
    size_t d = (size_t)s->dim;
    double ke = 0;
    for (size_t i = 0; i < s->n; i++) {
        if (s->flags[i] & PSYS_PARTICLE_NOT_FREE)
            continue;
        double v2 = 0;
        for (size_t k = 0; k < d; k++)
            v2 += s->v[i * d + k] * s->v[i * d + k];
        ke += 0.5 * s->mass[i] * v2;
    }
    return ke;
}

double psys_system_potential_energy(const psys_system *s)
{
    psys_force_eval e;
    psys__sys_eval(s, s->t, s->x, s->v, &e);
    double u = 0;
    for (size_t i = 0; i < s->nforces; i++)
        if (s->forces[i].cls->energy)
            u += s->forces[i].cls->energy(s->forces[i].data, &e);
    return u;
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

void psys_jacobian_add(psys_jacobian *J, size_t i, size_t j, const double *dfdx, const double *dfdv)
{
    J->add(J, i, j, dfdx, dfdv);
}

bool psys_jacobian_wants_definite(const psys_jacobian *J) { return J->definite; }

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
