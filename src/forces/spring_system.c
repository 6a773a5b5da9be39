/* The system's spring set seen from the public API: all springs added by
 * psys_system_add_spring live in one force object (spring.c). */
#include "forces/springs.h"

#include <stdlib.h>

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

