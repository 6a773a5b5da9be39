/* The simulation box (docs/scene-format.md#periodic-box) and per-particle
 * charges: system-wide settings that pair forces read.
 *
 * A periodic axis wraps free particles' positions into [lo, hi) after every
 * accepted step (psys_system_advance; velocities unchanged) and pair forces
 * measure distances by the minimum image. Non-periodic axes of a box have
 * no effect (use planes for walls). */
#include "forces/forces.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>


/* ---- charges ---- */

psys_status psys_system_set_charge(psys_system *s, size_t i, double q)
{
    if (i >= s->n)
        return psys__fail(&s->err, PSYS_ERR_INVALID, "no particle %zu", i);
    if (!isfinite(q))
        return psys__fail(&s->err, PSYS_ERR_INVALID, "charge must be finite (got %g)", q);
    if (i >= s->charge_cap) {
        size_t cap = s->charge_cap ? s->charge_cap : 16;
        while (cap <= i)
            cap *= 2;
        if (cap < s->cap)
            cap = s->cap;
        double *p = psys__realloc(s->charge, cap, sizeof(double));
        if (!p)
            return psys__fail(&s->err, PSYS_ERR_NOMEM, "out of memory setting a charge");
        s->charge = p;
        s->charge_cap = cap;
    }
    for (size_t k = s->ncharge; k < i; k++)
        s->charge[k] = 0.0;
    s->charge[i] = q;
    if (i >= s->ncharge)
        s->ncharge = i + 1;
    return PSYS_OK;
}

double psys_system_charge(const psys_system *s, size_t i)
{
    return i < s->ncharge && i < s->n ? s->charge[i] : 0.0;
}

/* ---- box ---- */

psys_status psys_system_set_box(psys_system *s, const double *lo, const double *hi, const bool *periodic)
{
    int d = s->dim;
    psys__box b;
    memset(&b, 0, sizeof b);
    if (lo) {
        if (!hi || !periodic)
            return psys__fail(&s->err, PSYS_ERR_INVALID, "a box needs lo, hi and periodic");
        b.on = true;
        for (int k = 0; k < d; k++) {
            if (!isfinite(lo[k]) || !isfinite(hi[k]))
                return psys__fail(&s->err, PSYS_ERR_INVALID, "box corners must be finite");
            if (!(hi[k] > lo[k]) || !isfinite(hi[k] - lo[k]))
                return psys__fail(&s->err, PSYS_ERR_INVALID,
                                  "box hi must be greater than lo on every axis (axis %d: lo %g, hi %g)", k, lo[k],
                                  hi[k]);
            b.lo[k] = lo[k];
            b.hi[k] = hi[k];
            b.len[k] = hi[k] - lo[k];
            b.periodic[k] = periodic[k];
            b.any_periodic |= periodic[k];
        }
    }
    for (size_t i = 0; i < s->nforces; i++) {
        const psys_force_class *cls = s->forces[i].cls;
        if (cls != &psys_pair_class && cls != &psys_pair_user_class)
            continue;
        char msg[300];
        if (psys__pair_check_box(s->forces[i].data, &b, msg, sizeof msg) != PSYS_OK)
            return psys__fail(&s->err, PSYS_ERR_INVALID, "pair force %zu: %s", i, msg);
    }
    s->box = b;
    return PSYS_OK;
}

bool psys_system_box(const psys_system *s, double *lo, double *hi, bool *periodic)
{
    for (int k = 0; k < s->dim; k++) {
        if (lo) lo[k] = s->box.lo[k];
        if (hi) hi[k] = s->box.hi[k];
        if (periodic) periodic[k] = s->box.periodic[k];
    }
    return s->box.on;
}

/* x into [lo, hi): subtract whole box lengths; a result that rounds onto hi
 * (x a hair below lo) is taken as lo. */
static double wrap1(double x, double lo, double hi, double len)
{
    if (x >= lo && x < hi)
        return x;
    if (!isfinite(x))
        return x; /* left for the solver's non-finite check */
    double w = x - len * floor((x - lo) / len);
    if (w >= hi)
        w -= len;
    if (w < lo)
        w = lo;
    return w;
}

/* Particles per block of psys__box_wrap: a block whose particles all lie
 * in the box (the usual case) is passed by one vectorised test. */
#define WRAP_BLOCK 64

/* Whether some coordinate of particles [i0, i1) lies outside [lo, hi) on
 * its axis (lo, hi: ±inf on axes that do not wrap), NaN included. */
__attribute__((always_inline)) static inline bool block_outside(const double *x, size_t i0, size_t i1, const int d,
                                                                const double *lo, const double *hi)
{
    int out = 0;
    for (size_t i = i0; i < i1; i++)
        for (int k = 0; k < d; k++)
            out |= !(x[i * (size_t)d + (size_t)k] >= lo[k] && x[i * (size_t)d + (size_t)k] < hi[k]);
    return out != 0;
}

PSYS_CLONES static bool any_outside(const double *x, size_t i0, size_t i1, int d, const double *lo, const double *hi)
{
    return d == 3 ? block_outside(x, i0, i1, 3, lo, hi) : block_outside(x, i0, i1, 2, lo, hi);
}

void psys__box_wrap(psys_system *s)
{
    if (!s->box.any_periodic)
        return;
    int d = s->dim;
    double lo[3], hi[3];
    for (int k = 0; k < d; k++) {
        lo[k] = s->box.periodic[k] ? s->box.lo[k] : -INFINITY;
        hi[k] = s->box.periodic[k] ? s->box.hi[k] : INFINITY;
    }
    const size_t nb = (s->n + WRAP_BLOCK - 1) / WRAP_BLOCK;
    const int nt = psys_system_effective_threads(s);
    (void)nt;
    PSYS_PAR_FOR(nt, s->n * (size_t)d)
    for (size_t b = 0; b < nb; b++) {
        const size_t i0 = b * WRAP_BLOCK, i1 = i0 + WRAP_BLOCK < s->n ? i0 + WRAP_BLOCK : s->n;
        if (!any_outside(s->x, i0, i1, d, lo, hi))
            continue;
        for (size_t i = i0; i < i1; i++) {
            if (s->flags[i] & PSYS_PARTICLE_NOT_FREE)
                continue;
            for (int k = 0; k < d; k++)
                if (s->box.periodic[k])
                    s->x[i * d + k] = wrap1(s->x[i * d + k], s->box.lo[k], s->box.hi[k], s->box.len[k]);
        }
    }
}

void psys_system_wrap_positions(psys_system *s) { psys__box_wrap(s); }
