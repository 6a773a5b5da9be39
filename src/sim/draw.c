/* Drawing through a renderer's callbacks (psys_draw, Box2D b2DebugDraw
 * style) and bounds for framing. The library itself never draws: the CLI's
 * cairo renderer and the viewer implement psys_draw. */
#include "sim/sim.h"

#include <math.h>
#include <string.h>

psys_status psys_system_bounds(const psys_system *sys, double *lo, double *hi)
{
    int d = sys->dim;
    for (int k = 0; k < d; k++)
        lo[k] = hi[k] = 0;
    if (sys->n == 0)
        return PSYS_ERR_INVALID;
    for (int k = 0; k < d; k++)
        lo[k] = hi[k] = sys->x[k];
    for (size_t i = 1; i < sys->n; i++)
        for (int k = 0; k < d; k++) {
            double c = sys->x[i * (size_t)d + (size_t)k];
            if (c < lo[k])
                lo[k] = c;
            if (c > hi[k])
                hi[k] = c;
        }
    return PSYS_OK;
}

/* Geometric mean of the masses: a typical mass that one heavy particle (a sun
 * among planets) does not dominate. */
static double typical_mass(const psys_system *sys)
{
    double s = 0;
    for (size_t i = 0; i < sys->n; i++)
        s += log(sys->mass[i]);
    return sys->n ? exp(s / (double)sys->n) : 1.0;
}

psys_status psys_system_draw(const psys_system *sys, const psys_draw *draw)
{
    if (!sys || !draw)
        return PSYS_ERR_INVALID;
    int d = sys->dim;
    void *ctx = draw->ctx;
    if (draw->begin)
        draw->begin(ctx, d, sys->t);
    if (draw->plane) {
        for (size_t k = 0; k < sys->nplanes; k++)
            draw->plane(ctx, sys->planes[k].p, sys->planes[k].n);
    }
    if (draw->guide) {
        psys_behavior_def def;
        for (size_t f = 0; f < sys->nforces; f++) {
            if (psys_system_behavior(sys, f, &def) != PSYS_OK)
                continue;
            if (def.function == PSYS_BEHAVIOR_POINT_ON_PLANE) {
                double nn = 0, n[3] = {0, 0, 0};
                for (int c = 0; c < d; c++)
                    nn += def.normal[c] * def.normal[c];
                nn = sqrt(nn);
                if (!(nn > 0))
                    continue;
                for (int c = 0; c < d; c++)
                    n[c] = def.normal[c] / nn;
                draw->guide(ctx, def.point, n, -1.0);
            } else if (def.function == PSYS_BEHAVIOR_POINT_ON_SPHERE) {
                draw->guide(ctx, def.center, NULL, def.radius);
            }
        }
    }
    if (draw->spring && sys->springs) {
        size_t ns = psys__springs_count(sys->springs);
        for (size_t k = 0; k < ns; k++) {
            size_t a, b;
            psys__springs_get(sys->springs, k, &a, &b, NULL, NULL, NULL);
            const double *xa = sys->x + a * (size_t)d, *xb = sys->x + b * (size_t)d;
            double l2 = 0;
            for (int c = 0; c < d; c++)
                l2 += (xb[c] - xa[c]) * (xb[c] - xa[c]);
            double r = psys__springs_rest_at(sys->springs, k, sys->t);
            double strain = r > 0 ? (sqrt(l2) - r) / r : 0.0;
            draw->spring(ctx, xa, xb, strain);
        }
    }
    if (draw->link) {
        psys_behavior_def def;
        for (size_t f = 0; f < sys->nforces; f++) {
            if (psys_system_behavior(sys, f, &def) != PSYS_OK || def.function == PSYS_BEHAVIOR_POINT_ON_PLANE
                || def.function == PSYS_BEHAVIOR_POINT_ON_SPHERE)
                continue;
            for (int k = 0; k + 1 < def.nparticles; k++)
                if (def.particles[k] < sys->n && def.particles[k + 1] < sys->n)
                    draw->link(ctx, sys->x + def.particles[k] * (size_t)d, sys->x + def.particles[k + 1] * (size_t)d);
        }
    }
    if (draw->particle && sys->n) {
        double base = draw->radius > 0 && isfinite(draw->radius) ? draw->radius : 0.0;
        double mref = base > 0 ? typical_mass(sys) : 1.0;
        for (size_t i = 0; i < sys->n; i++) {
            double r = 0;
            if (base > 0) {
                double s = cbrt(sys->mass[i] / mref);
                r = base * (s < 0.5 ? 0.5 : s > 2.0 ? 2.0 : s);
            }
            draw->particle(ctx, i, sys->x + i * (size_t)d, r, sys->flags[i] & PSYS_PARTICLE_NOT_FREE);
        }
    }
    if (draw->end)
        draw->end(ctx);
    return PSYS_OK;
}
