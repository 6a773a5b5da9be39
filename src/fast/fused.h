/* Private declarations of the fused spring path (src/fast/): the state a
 * sweep carries (fused, sweep) and the functions that the chain (chain.c),
 * its timed choice (chain_tuner.c) and the state ordering (order.c) call in
 * fused.c. The hot loops stay in fused.c, inlined into each other there;
 * across files a whole sweep is one call (psys__fused_sweep). */
#ifndef PSYS_FAST_FUSED_H
#define PSYS_FAST_FUSED_H

#include "fast/fast.h"
#include "forces/springs.h"

#include <stdatomic.h>
#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#define FUSED_MAX_ROWS 8 /* per-particle forces before and after the springs */

typedef void (*rows_fn)(const void *data, int dim, size_t count, const double *mass, const double *const *V,
                        double *const *F, bool first);

typedef struct rowforce {
    rows_fn fn;
    const void *data;
} rowforce;

typedef struct fused {
    const springs *s;
    size_t n, W, mask, S; /* ring slots (a power of 2) and row stride */
    const double *x, *v, *mass, *inv_mass; /* particle-major x, v (y's halves) */
    const uint32_t *perm;                  /* the springs' internal order (slot -> particle), or NULL */
    double *xdot, *vdot;                   /* ydot's halves (no pass) */
    const psys__stage_pass *pass;           /* or the solver's work on ydot */
    const double *base[2];                 /* the pass's base, x and v halves (the system's own x, v where
                                              the chain reads them in place: psys__fused_chain) */
    double *put[2];                        /* those x, v, where this last pass writes the result there and
                                              the start into acc (psys__stage_pass.in_place), or NULL */
    atomic_int *nonfinite;                 /* set when a pass asked to (.finite) wrote a non-finite acc */
    atomic_size_t *held;                   /* the springs' count of held-back blocks */
    size_t nd;
    /* The chain's stage states of particles [zlo, zhi) in rings of R
     * particles (psys__fused_chain): x of particle p at ring[(p mod R)·d],
     * its v rd = R·d further on. The input state's ring (x, v above hold
     * the rest) and the pass's next's, or NULL. */
    const double *in_ring;
    double *out_ring;
    size_t rmask, rd, zlo, zhi;
    rowforce pre[FUSED_MAX_ROWS], post[FUSED_MAX_ROWS];
    const psys_system *planes; /* the system, where it has planes: their contact forces after the post
                                  forces (psys__contact_rows), or NULL */
    bool forced; /* PSYS_FUSED=1: small sets threaded too (read once per evaluation), and their
                    leavings held back (FUSED_HOLD_MIN; tests) */
    bool k512;   /* the AVX-512 run loops (run_pair_512, run_near_512); PSYS_SPRING_PLAIN=1: the
                    compiler's loops (tests, benchmarks) */
    int npre, npost;
} fused;

/* How far ahead enter_perm and leave_perm fetch the particles they gather
 * and scatter. */
#define PERM_AHEAD 8
#if defined(__GNUC__)
#define PERM_PREFETCH(p) __builtin_prefetch(p)
#else
#define PERM_PREFETCH(p) ((void)(p))
#endif

/* How far past the particles it finishes a sweep can reach: every particle
 * of a run whose first end's block starts before upto lies before upto +
 * this − 2 (a block of 256 first ends, a run of at most 256). In the chain
 * (psys__fused_chain), the lag between stages. */
static inline size_t chain_reach(const springs *s) { return s->max_off + 2 * SPRING_BLOCK; }

/* A sweep of particles [P, Q) through runs [r0, r1) that can stop after
 * any particle and go on later: the window [done, loaded) and the next run
 * r are kept between calls. */
typedef struct sweep {
    size_t r, r1, P, Q, loaded, done;
} sweep;

/* The most stages of one chain step (chain.c, chain_tuner.c). */
#define CHAIN_MAX_STAGES 7

/* Whether the fused path computes s's derivative; fz gets its forces
 * (fused.c). */
bool psys__fused_takes(const psys_system *s, fused *fz);
/* fz (its forces from psys__fused_takes) over sys's springs, windows and
 * particles: the state (x, v), and either ydot or the solver's pass. */
void psys__fused_bind(fused *fz, const psys_system *sys, const double *x, const double *v, double *ydot,
                      const psys__stage_pass *pass, atomic_int *nonfinite);
/* A sweep of [P, Q) through runs [r0, r1), nothing done yet. */
void psys__fused_sweep_start(const springs *s, sweep *w, size_t r0, size_t r1, size_t P, size_t Q);
/* Go on with sweep w until every particle before upto has left the window,
 * on the run loops fz chose (the plain clones or AVX-512). */
void psys__fused_sweep(const fused *fz, int d, double *rb, sweep *w, size_t upto);
/* Answers the passes that asked (psys__stage_pass.finite) once their
 * sweeps are done. */
void psys__fused_answer_finite(const psys_system *sys, const psys__stage_pass *pass, int stages,
                               atomic_int *nonfinite);
/* Whether the chain takes sys for `stages` stages; fz gets its forces
 * (chain_tuner.c). */
bool psys__chain_takes(psys_system *sys, int stages, fused *fz, bool ask);

#endif
