/* The state reordering: the solver's state held in the springs' internal
 * order for a step (psys__state_order_begin/end), so that the fused window
 * streams it instead of gathering and scattering each particle, and the
 * copies between the two orders. */
#include "fast/fused.h"
#include "solvers/solver_fast.h"

#include <stdint.h>
#include <stdlib.h>

/* The springs' internal order (slot -> particle, covering *perm_n
 * particles) when the fused derivative takes sys and the springs have one
 * (builds the plan), with the plan's version in *plan; NULL otherwise. */
static const uint32_t *fused_order(psys_system *sys, size_t *perm_n, unsigned *plan);

/* ---- The solver's state in the springs' internal order
 *
 * With the state itself in slot order (psys__state_order_begin), the
 * window reads and writes it as it does a mesh numbered in rows: streams
 * instead of a gather and a scatter across the whole state per particle
 * and stage. The state moves between the two orders once per step (the
 * solver's get_state and commit) instead of at every stage. */

bool psys__state_order_begin(psys_system *s, const psys_solver *solver)
{
    s->ode_perm = NULL;
    /* Only a solver psys_system_solver_create made for s, of s's current
     * size: any other ODE on s (a user's wrapper) may read the state by
     * particle. */
    const bool own = psys__solver_owner(solver) == s && psys__solver_size(solver) == 2 * s->n * (size_t)s->dim;
    if (!own || !psys__solver_elementwise(solver) || s->nplanes || s->dist)
        return false;
    if (s->sw.state_order_off)
        return false;
    size_t perm_n = 0;
    unsigned plan = 0;
    const uint32_t *perm = fused_order(s, &perm_n, &plan);
    if (!perm)
        return false;
    if (s->ode_epoch == s->epoch && s->ode_plan == plan) {
        /* the masses and slots of the last step still hold (the order
         * covers more particles only when some were added: a new epoch) */
        s->ode_perm = perm;
        s->ode_perm_n = perm_n;
        return true;
    }
    s->ode_epoch = s->epoch - 1; /* not valid until filled */
    if (s->ode_cap < s->n) {
        double *m = psys__realloc(s->ode_mass, s->n, sizeof(double));
        if (m)
            s->ode_mass = m;
        double *im = psys__realloc(s->ode_inv_mass, s->n, sizeof(double));
        if (im)
            s->ode_inv_mass = im;
        uint32_t *slot = psys__realloc(s->ode_slot, s->n, sizeof(uint32_t));
        if (slot)
            s->ode_slot = slot;
        if (!m || !im || !slot)
            return false; /* the particles' order, which needs no more memory */
        s->ode_cap = s->n;
    }
    const int nt = psys_system_effective_threads(s);
    psys__order_copy(perm, perm_n, s->n, 1, s->mass, s->ode_mass, false, nt);
    psys__order_copy(perm, perm_n, s->n, 1, s->inv_mass, s->ode_inv_mass, false, nt);
    if (s->nctrl) /* the projection finds its particles' slots */
        for (size_t i = 0; i < s->n; i++)
            s->ode_slot[i < perm_n ? perm[i] : i] = (uint32_t)i;
    s->ode_perm = perm;
    s->ode_perm_n = perm_n;
    s->ode_epoch = s->epoch;
    s->ode_plan = plan;
    return true;
}

void psys__state_order_end(psys_system *s) { s->ode_perm = NULL; }

static const uint32_t *fused_order(psys_system *sys, size_t *perm_n, unsigned *plan)
{
    fused fz;
    if (!psys__fused_takes(sys, &fz) || psys__springs_prepare_rings(sys->springs, sys->n, 1) != PSYS_OK)
        return NULL;
    const springs *s = sys->springs;
    *perm_n = s->perm_n;
    *plan = s->plan_version;
    return s->perm;
}

void psys__order_copy(const uint32_t *perm, size_t perm_n, size_t n, int width, const double *src, double *dst,
                      bool to_particles, int nt)
{
    const size_t w = (size_t)width;
    /* the side indexed by particle is read or written all over memory */
    const double *ahead = to_particles ? dst : src;
    (void)nt;
    PSYS_PAR_FOR(nt, n * w)
    for (size_t i = 0; i < n; i++) {
        const size_t p = i < perm_n ? perm[i] : i, from = to_particles ? i : p, to = to_particles ? p : i;
        if (i + 4 * PERM_AHEAD < perm_n)
            PERM_PREFETCH(ahead + perm[i + 4 * PERM_AHEAD] * w);
        for (size_t c = 0; c < w; c++)
            dst[to * w + c] = src[from * w + c];
    }
}
