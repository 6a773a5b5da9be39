/* The particle system's storage: SoA particles with ids, the list of force
 * objects, and the energies summed over them. */
#include "core/core.h"

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
    s->sw = psys__switches_from_env();
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


size_t psys_system_particle_of_component(const psys_system *s, size_t k)
{
    size_t nd = s->n * (size_t)s->dim;
    return (k < nd ? k : k - nd) / (size_t)s->dim;
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

