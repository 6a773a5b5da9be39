/* A force type written outside the library with its public API alone: a
 * constant acceleration g on every particle, the same operations as the
 * built-in gravity, so the same bits. my_gravity_class declares its traits
 * (velocity-free, per-particle, with row kernel and copy); my_plain_class
 * is the same force with no traits and no optional members, as a class
 * written before traits existed (tests/test_traits.c, tests/test_mpi.c). */
#ifndef PSYS_TESTS_MY_GRAVITY_H
#define PSYS_TESTS_MY_GRAVITY_H

#include "psys/psys.h"

#include <stdlib.h>

typedef struct my_gravity {
    double g[3];
    /* where set, each apply records the velocity of particle 0 it was
     * given (seen_v[3·k..], k = *seen_n), up to 8 calls; single-threaded
     * runs without springs only (the fused path calls apply_rows instead) */
    double *seen_v;
    int *seen_n;
} my_gravity;

static void my_gravity_apply(void *data, const psys_force_eval *e, double *f)
{
    const my_gravity *gr = data;
    const int d = e->dim;
    if (gr->seen_n && *gr->seen_n < 8 && e->n > 0) {
        for (int k = 0; k < d; k++)
            gr->seen_v[3 * *gr->seen_n + k] = e->v[k];
        ++*gr->seen_n;
    }
    for (size_t i = 0; i < e->n; i++)
        for (int k = 0; k < d; k++)
            f[i * (size_t)d + (size_t)k] += e->mass[i] * gr->g[k];
}

static double my_gravity_energy(void *data, const psys_force_eval *e)
{
    const my_gravity *gr = data;
    const int d = e->dim;
    double u = 0;
    for (size_t i = 0; i < e->n; i++) {
        if (e->flags[i] & PSYS_PARTICLE_NOT_FREE)
            continue;
        double gx = 0;
        for (int k = 0; k < d; k++)
            gx += gr->g[k] * e->x[i * (size_t)d + (size_t)k];
        u -= e->mass[i] * gx;
    }
    return u;
}

/* A constant force: both Jacobians are zero. */
static void my_gravity_jacobian(void *data, const psys_force_eval *e, psys_jacobian *J)
{
    (void)data;
    (void)e;
    (void)J;
}

/* my_gravity_apply for particles in component rows. */
static void my_gravity_rows(const void *data, int dim, size_t count, const double *mass, const double *const *V,
                            double *const *F, bool first)
{
    (void)V;
    const my_gravity *gr = data;
    for (int c = 0; c < dim; c++) {
        if (first) {
            for (size_t j = 0; j < count; j++)
                F[c][j] = 0.0 + mass[j] * gr->g[c];
        } else {
            for (size_t j = 0; j < count; j++)
                F[c][j] += mass[j] * gr->g[c];
        }
    }
}

static void *my_gravity_clone(const void *data)
{
    my_gravity *c = malloc(sizeof *c);
    if (c) {
        *c = *(const my_gravity *)data;
        c->seen_v = NULL; /* the copy records nothing */
        c->seen_n = NULL;
    }
    return c;
}

static const psys_force_class my_gravity_class = {.name = "my-gravity",
                                                  .apply = my_gravity_apply,
                                                  .energy = my_gravity_energy,
                                                  .jacobian = my_gravity_jacobian,
                                                  .destroy = free,
                                                  .traits = PSYS_FORCE_VELOCITY_FREE | PSYS_FORCE_PER_PARTICLE,
                                                  .apply_rows = my_gravity_rows,
                                                  .clone = my_gravity_clone};

static const psys_force_class my_plain_class = {.name = "my-plain-gravity",
                                                .apply = my_gravity_apply,
                                                .energy = my_gravity_energy,
                                                .jacobian = my_gravity_jacobian,
                                                .destroy = free};

/* Add a my_gravity of acceleration g (dim components) with class cls. */
static psys_status my_gravity_add(psys_system *s, const psys_force_class *cls, const double *g)
{
    my_gravity *gr = calloc(1, sizeof *gr);
    if (!gr)
        return PSYS_ERR_NOMEM;
    for (int k = 0; k < psys_system_dim(s); k++)
        gr->g[k] = g[k];
    return psys_system_add_force(s, cls, gr);
}

#endif
