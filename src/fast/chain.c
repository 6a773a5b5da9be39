/* The chain: every stage of a step in one sweep through memory, each stage
 * a fixed lag behind the one before, so that a large system's state and the
 * solver's sums come from memory about once a step instead of once a stage.
 * Whether a step takes the chain is chain_tuner.c's choice; the sweeps are
 * fused.c's (psys__fused_sweep). */
#include "fast/fused.h"

#include <stdatomic.h>
#include <stdint.h>
#ifdef _OPENMP
#include <omp.h>
#endif

/* ---- Every stage of a chain step in one sweep (psys__ode_fast.derivative_chain)
 *
 * A sweep that has let particles before p leave its window has loaded the
 * state only below p + reach (reach = max_off + 2·SPRING_BLOCK: a run
 * starting in p's block reaches that far). So stage i can follow stage
 * i − 1 at a distance of reach particles: all stages of a step sweep
 * through memory together, the few thousand particles between the first
 * and the last staying in cache, and at 10⁶ particles y and the weighted
 * sum come from memory about once a step instead of once per stage, and
 * the stage states, in rings that stay in cache (stage_rings), not at all.
 * Each stage has its own window; each particle sees the
 * operations of the stage-by-stage path in the same order (a sweep's bits
 * do not depend on where it stops, sweep_to_d).
 *
 * Threads own ranges of particles. Within its range [P, Q) thread t runs
 * stage i on [P + i·reach, Q − i·reach) (a trapezoid, whose states it
 * computes itself); after a barrier, thread t ≥ 1 runs the inverted
 * trapezoid at its range's start B = P, stage i ≥ 1 on [B − i·reach,
 * B + i·reach), stage by stage, from what the two trapezoids around it
 * left. The same operations per particle again: results do not depend on
 * the thread count. */

/* Particles the leading stage advances between turns of the others. */
#define CHAIN_STEP 1024

/* First run whose first particle's block is at least blk (the plan sorts
 * runs by that block first). */
static size_t run_from_block(const springs *s, size_t blk)
{
    size_t lo = 0, hi = s->nruns;
    while (lo < hi) {
        const size_t mid = lo + (hi - lo) / 2;
        if (s->run_lo[mid] / SPRING_BLOCK < blk)
            lo = mid + 1;
        else
            hi = mid;
    }
    return lo;
}

/* A sweep of [P, Q) through the runs that can touch it. */
static void chain_sweep_start(const springs *s, sweep *w, size_t P, size_t Q)
{
    const size_t reach = chain_reach(s);
    const size_t r0 = run_from_block(s, P > reach ? (P - reach) / SPRING_BLOCK : 0);
    const size_t r1 = Q > P ? run_from_block(s, (Q - 1) / SPRING_BLOCK + 1) : r0;
    psys__fused_sweep_start(s, w, r0, r1, P, Q);
}

/* Stage i on [lo[i], hi[i]) for every i < stages, stage i kept i·reach
 * particles behind stage 0, each with its window ring (rings + i·ring). */
static void chain_trapezoid(const fused *fz, int stages, int d, double *rings, size_t ring, const size_t *lo,
                            const size_t *hi)
{
    const size_t reach = chain_reach(fz->s);
    sweep w[CHAIN_MAX_STAGES];
    for (int i = 0; i < stages; i++)
        chain_sweep_start(fz->s, &w[i], lo[i], hi[i]);
    for (size_t f = lo[0];;) {
        f += CHAIN_STEP;
        bool finished = true;
        for (int i = 0; i < stages; i++) {
            if (lo[i] >= hi[i])
                continue;
            const size_t lag = (size_t)i * reach;
            size_t target = f > lag ? f - lag : 0;
            if (target >= hi[i])
                target = hi[i];
            else
                finished = false;
            if (target > w[i].done)
                psys__fused_sweep(&fz[i], d, rings + (size_t)i * ring, &w[i], target);
        }
        if (finished)
            return;
    }
}

/* The chain's stage states in rings (psys__fused_chain). Within one
 * trapezoid, stage i + 1 has left every particle before stage i's done −
 * reach − CHAIN_STEP by the time stage i writes a state: rings of R >
 * reach + CHAIN_STEP particles hold every state still to be read, and the
 * states stay in cache instead of going to memory and back once a step.
 * Near a thread's range ends the patches after the barrier read the
 * states of up to `stages` reaches (and a block) on either side: those
 * stay in the solver's whole vectors. */
static size_t ring_edge(int stages, size_t reach) { return (size_t)(stages + 1) * reach; }

/* dst: the stages of src with the states of particles [zlo, zhi) in rings
 * of R particles at mem (stage i's next state at mem + i·2·R·d). */
static void stage_rings(fused *dst, const fused *src, int stages, double *mem, size_t R, int d, size_t zlo,
                        size_t zhi)
{
    const size_t rd = R * (size_t)d;
    for (int i = 0; i < stages; i++) {
        dst[i] = src[i];
        dst[i].rmask = R - 1;
        dst[i].rd = rd;
        dst[i].zlo = zlo;
        dst[i].zhi = zhi;
        dst[i].in_ring = i > 0 ? mem + 2 * rd * (size_t)(i - 1) : NULL;
        dst[i].out_ring = i + 1 < stages ? mem + 2 * rd * (size_t)i : NULL;
    }
}

psys_status psys__fused_chain(psys_system *sys, const psys_force_eval *e, const double *y0, int stages,
                              const psys__stage_pass *pass, bool *used)
{
    fused fz[CHAIN_MAX_STAGES];
    *used = false;
    if (!psys__chain_takes(sys, stages, &fz[0], false))
        return PSYS_OK;
    springs *s = sys->springs;
    const size_t n = sys->n, nd = n * (size_t)sys->dim;
    int T = e->threads < 1 ? 1 : e->threads > SPRING_MAX_THREADS ? SPRING_MAX_THREADS : e->threads;
    if (s->n < SPRING_PARALLEL_MIN && nd < PSYS_PAR_MIN && !fz[0].forced)
        T = 1;
#ifndef _OPENMP
    T = 1;
#endif
    psys_status st = psys__springs_prepare_rings(s, n, 1); /* the plan and the window's size */
    if (st != PSYS_OK)
        return st;
    const size_t reach = chain_reach(s);
    /* Each range must hold its two trapezoids' slopes. */
    const size_t slopes = 2 * (size_t)(stages - 1) * reach + 1;
    if ((size_t)T > n / slopes)
        T = n / slopes > 1 ? (int)(n / slopes) : 1;
    st = psys__springs_prepare_rings(s, n, T * stages);
    if (st != PSYS_OK)
        return st;
    atomic_int nonfinite = 0;
    for (int i = 0; i < stages; i++) {
        if (i > 0)
            fz[i] = fz[0];
        const double *y = i == 0 ? y0 : pass[i - 1].next;
        /* y0 NULL: the system's x and v as they are (no copy) */
        psys__fused_bind(&fz[i], sys, y ? y : sys->x, y ? y + nd : sys->v, NULL, &pass[i], &nonfinite);
    }
    /* The last pass's result straight into x and v, the start into acc
     * (psys__stage_pass.in_place), where the start is read there (y0 NULL)
     * and nothing is projected. Every stage reads a particle's start before
     * the last stage leaves it (that needs their states around it), on any
     * thread, so no read of the start comes after its write. */
    const psys__stage_pass *fin = &pass[stages - 1];
    const bool in_place = !y0 && fin->in_place && fin->acc && !fin->next && fin->acc_op >= PSYS__ACC_BASE_STEP &&
                          sys->nctrl == 0;
    if (in_place) {
        fz[stages - 1].put[0] = sys->x;
        fz[stages - 1].put[1] = sys->v;
    }
    const size_t ring = 9 * psys__springs_ring_stride(s->ring_w);
    /* Stage states in rings (stage_rings): R particles, a multiple of the
     * window's, each thread its own; only where its sweep is long enough
     * for them to pay and the particles are in their own order. */
    size_t R = s->ring_w;
    while (R <= reach + CHAIN_STEP)
        R *= 2;
    const size_t rd = R * (size_t)sys->dim, per = 2 * rd * (size_t)(stages - 1);
    const size_t share = n / (size_t)T, edges = T <= 1 ? 0 : 2 * ring_edge(stages, reach);
    const bool rings_on = !fz[0].perm && share > edges && share - edges >= 2 * R
                          && psys__springs_prepare_stage(s, per * (size_t)T) == PSYS_OK;
    size_t lo[CHAIN_MAX_STAGES], hi[CHAIN_MAX_STAGES];
    if (T <= 1) {
        fused fr[CHAIN_MAX_STAGES];
        if (rings_on)
            stage_rings(fr, fz, stages, s->stage, R, sys->dim, 0, n);
        for (int i = 0; i < stages; i++) {
            lo[i] = 0;
            hi[i] = n;
        }
        chain_trapezoid(rings_on ? fr : fz, stages, sys->dim, s->ring, ring, lo, hi);
    } else {
#ifdef _OPENMP
#pragma omp parallel num_threads(T) private(lo, hi)
        {
            /* the team may be smaller than asked: its ranges are then longer */
            const int Ta = omp_get_num_threads(), t = omp_get_thread_num();
            const size_t P = psys__part_first(n, Ta, t), Q = psys__part_first(n, Ta, t + 1);
            double *rings = s->ring + (size_t)t * (size_t)stages * ring;
            for (int i = 0; i < stages; i++) {
                lo[i] = t == 0 ? 0 : P + (size_t)i * reach;
                hi[i] = t == Ta - 1 ? n : Q - (size_t)i * reach;
            }
            /* the states the patches between ranges read stay whole */
            const size_t edge = ring_edge(stages, reach);
            fused fr[CHAIN_MAX_STAGES];
            if (rings_on)
                stage_rings(fr, fz, stages, s->stage + (size_t)t * per, R, sys->dim, t == 0 ? 0 : P + edge,
                            t == Ta - 1 ? n : Q - edge);
            chain_trapezoid(rings_on ? fr : fz, stages, sys->dim, rings, ring, lo, hi);
#pragma omp barrier
            for (int i = 1; i < stages && t > 0; i++) {
                sweep w;
                chain_sweep_start(s, &w, P - (size_t)i * reach, P + (size_t)i * reach);
                psys__fused_sweep(&fz[i], sys->dim, rings, &w, P + (size_t)i * reach);
            }
        }
#endif
    }
    psys__fused_answer_finite(sys, pass, stages, &nonfinite);
    if (in_place)
        *fin->in_place = 1;
    *used = true;
    return PSYS_OK;
}
