/* Uniform gravity f = m g (notes §4.1): a unary force object. */
#include "forces/springs.h"

#include <stdlib.h>

typedef struct gravity {
    double g[3];
} gravity;

const double *psys__gravity_g(const void *data) { return ((const gravity *)data)->g; }

static void gravity_apply(void *data, const psys_force_eval *e, double *f)
{
    const gravity *gr = data;
    const double *restrict m = e->mass;
    double *restrict fo = f;
    /* One loop per dimension so the compiler sees the stride and vectorises. */
    if (e->dim == 2) {
        const double g0 = gr->g[0], g1 = gr->g[1];
        PSYS_PAR_FOR(e->threads, 2 * e->n)
        for (size_t i = 0; i < e->n; i++) {
            fo[2 * i] += m[i] * g0;
            fo[2 * i + 1] += m[i] * g1;
        }
    } else {
        const double g0 = gr->g[0], g1 = gr->g[1], g2 = gr->g[2];
        PSYS_PAR_FOR(e->threads, 3 * e->n)
        for (size_t i = 0; i < e->n; i++) {
            fo[3 * i] += m[i] * g0;
            fo[3 * i + 1] += m[i] * g1;
            fo[3 * i + 2] += m[i] * g2;
        }
    }
}

/* U = -Σ m g·x over free particles (fixed ones cannot exchange energy). */
static double gravity_energy(void *data, const psys_force_eval *e)
{
    const gravity *gr = data;
    int d = e->dim;
    double u = 0;
    for (size_t i = 0; i < e->n; i++) {
        if (e->flags[i] & PSYS_PARTICLE_NOT_FREE)
            continue;
        double gx = 0;
        for (int k = 0; k < d; k++)
            gx += gr->g[k] * e->x[i * d + k];
        u -= e->mass[i] * gx;
    }
    return u;
}

/* Constant force: both Jacobians are zero, so there is nothing to add. */
static void gravity_jacobian(void *data, const psys_force_eval *e, psys_jacobian *J)
{
    (void)data;
    (void)e;
    (void)J;
}

/* The row kernel, defined below. */
SPRING_CLONES
static void gravity_rows(const void *data, int dim, size_t count, const double *mass, const double *const *V,
                         double *const *F, bool first);

static void *gravity_clone(const void *data)
{
    gravity *c = malloc(sizeof *c);
    if (c)
        *c = *(const gravity *)data;
    return c;
}

/* m g reads neither velocities nor other particles. */
const psys_force_class psys_gravity_class = {.name = "gravity",
                                             .apply = gravity_apply,
                                             .energy = gravity_energy,
                                             .jacobian = gravity_jacobian,
                                             .destroy = free,
                                             .traits = PSYS_FORCE_VELOCITY_FREE | PSYS_FORCE_PER_PARTICLE,
                                             .apply_rows = gravity_rows,
                                             .clone = gravity_clone};

psys_status psys_system_add_gravity(psys_system *sys, const double *g)
{
    gravity *gr = calloc(1, sizeof *gr);
    if (!gr)
        return psys__fail(&sys->err, PSYS_ERR_NOMEM, "out of memory adding gravity");
    for (int k = 0; k < sys->dim; k++)
        gr->g[k] = g[k];
    return psys_system_add_force(sys, &psys_gravity_class, gr);
}

/* gravity_apply for particles in component rows (the fused derivative). */
/* Also built for AVX2 and AVX-512 where the CPU has them (forces/springs.h). */
SPRING_CLONES
static void gravity_rows(const void *data, int dim, size_t count, const double *mass, const double *const *V,
                         double *const *F, bool first)
{
    (void)V;
    const gravity *gr = data;
    for (int c = 0; c < dim; c++) {
        const double gc = gr->g[c];
        const double *restrict m = mass;
        double *restrict fc = F[c];
        if (first) {
            for (size_t j = 0; j < count; j++)
                fc[j] = 0.0 + m[j] * gc;
        } else {
            for (size_t j = 0; j < count; j++)
                fc[j] += m[j] * gc;
        }
    }
}

