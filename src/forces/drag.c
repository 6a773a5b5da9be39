/* Viscous drag f = -kd v (notes §4.1): a unary, non-conservative force. */
#include "forces/springs.h"

#include <stdlib.h>

typedef struct drag {
    double kd;
} drag;

double psys__drag_kd(const void *data) { return ((const drag *)data)->kd; }

static void drag_apply(void *data, const psys_force_eval *e, double *f)
{
    double kd = ((const drag *)data)->kd;
    size_t nd = e->n * (size_t)e->dim;
    const double *restrict v = e->v;
    double *restrict fo = f;
    PSYS_PAR_FOR(e->threads, nd)
    for (size_t i = 0; i < nd; i++)
        fo[i] -= kd * v[i];
}

static void drag_jacobian(void *data, const psys_force_eval *e, psys_jacobian *J)
{
    double kd = ((const drag *)data)->kd;
    int d = e->dim;
    double blk[9] = {0};
    for (int k = 0; k < d; k++)
        blk[k * d + k] = -kd;
    for (size_t i = 0; i < e->n; i++)
        psys_jacobian_add(J, i, i, NULL, blk);
}

/* The row kernel, defined below. */
SPRING_CLONES
static void drag_rows(const void *data, int dim, size_t count, const double *mass, const double *const *V,
                      double *const *F, bool first);

static void *drag_clone(const void *data)
{
    drag *c = malloc(sizeof *c);
    if (c)
        *c = *(const drag *)data;
    return c;
}

/* -kd v: each particle's own velocity only. */
const psys_force_class psys_drag_class = {.name = "drag",
                                          .apply = drag_apply,
                                          .jacobian = drag_jacobian,
                                          .destroy = free,
                                          .traits = PSYS_FORCE_PER_PARTICLE,
                                          .apply_rows = drag_rows,
                                          .clone = drag_clone};

psys_status psys_system_add_drag(psys_system *sys, double kd)
{
    if (!(kd >= 0) || kd > 1e308)
        return psys__fail(&sys->err, PSYS_ERR_INVALID, "drag kd must be finite and >= 0");
    drag *dr = calloc(1, sizeof *dr);
    if (!dr)
        return psys__fail(&sys->err, PSYS_ERR_NOMEM, "out of memory adding drag");
    dr->kd = kd;
    return psys_system_add_force(sys, &psys_drag_class, dr);
}

/* drag_apply for particles in component rows (the fused derivative). */
/* Also built for AVX2 and AVX-512 where the CPU has them (forces/springs.h). */
SPRING_CLONES
static void drag_rows(const void *data, int dim, size_t count, const double *mass, const double *const *V,
                      double *const *F, bool first)
{
    (void)mass;
    const double kd = ((const drag *)data)->kd;
    for (int c = 0; c < dim; c++) {
        const double *restrict v = V[c];
        double *restrict fc = F[c];
        if (first) {
            for (size_t j = 0; j < count; j++)
                fc[j] = 0.0 - kd * v[j];
        } else {
            for (size_t j = 0; j < count; j++)
                fc[j] -= kd * v[j];
        }
    }
}

