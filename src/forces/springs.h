/* The spring set's internals, shared by the force object (forces/spring.c),
 * its plan (forces/spring_plan.c) and the fused derivative (fast/fused.c,
 * fast/chain.c). */
#ifndef PSYS_SPRINGS_H
#define PSYS_SPRINGS_H

#include "forces/forces.h"

#include <stdatomic.h>
#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

/* Muscles (Miller's snakes and worms): spring k with a muscle has rest
 * length r(t) = rest[k]·(1 + amp·sin(omega·t + phase)) at evaluation time t.
 * Muscle arrays stay NULL until the first muscle exists, so a set without
 * muscles runs the plain loop on rest[] with no extra work. */
#define NO_MUSCLE UINT32_MAX

/* Spring loop blocking and threading (springs_apply). */
#define SPRING_BLOCK 256          /* longest run: its force scratch (6 KiB) stays in L1 */
#define SPRING_MAX_THREADS 64     /* more threads than this share 64 partitions */
#define SPRING_PARALLEL_MIN 20000 /* fewer springs than this run on one thread */

typedef struct springs {
    size_t n, cap;
    uint32_t *a, *b;
    double *ks, *kd, *rest;
    uint32_t *mslot;  /* cap entries once a muscle exists: muscle slot of spring k or NO_MUSCLE */
    double *rest_t;   /* cap entries once a muscle exists: rest length at the latest evaluation
                         time (equal to rest[k] for springs without a muscle) */
    size_t nm, mcap;  /* muscles, compact: spring, amplitude, omega, phase */
    uint32_t *midx;
    double *mamp, *momega, *mphase;
    const psys_system *owner; /* for its particle count (the SoA scratch) */
    unsigned version;         /* changes with every change of the spring set */
    /* The evaluation plan (psys__springs_plan): springs regrouped into runs of
     * equal index offset and consecutive first particles, so that the force
     * loop reads and writes particles in contiguous blocks and vectorises.
     * Spring indices users see stay those of the arrays above. */
    bool plan_ok;
    unsigned plan_version;
    size_t nruns;
    uint32_t *run_lo, *run_off, *run_len; /* run r: springs (lo + j, lo + off + j), j < len */
    size_t *run_k;                        /* first plan slot of run r */
    uint8_t *run_uni;                     /* run r's springs share ks and kd, bit for bit (read once) */
    double *pks, *pkd, *prest;            /* parameters in plan order */
    size_t *pos;                          /* plan slot of spring k */
    size_t max_off;                       /* largest run_off */
    /* The internal order of the particles (psys__springs_plan): slot i holds
     * particle perm[i] (perm NULL: slot i is particle i). Runs, thread
     * shares, windows and SoA rows count in slots. A function of the
     * springs' ends alone, so a resumed run and every MPI rank get the same
     * order. perm covers perm_n particles; beyond the springs' largest
     * index, slot = particle (springs_cover, forces/spring_plan.c, extends it as
     * particles come). */
    uint32_t *perm;
    size_t perm_n;
    /* Thread partition (springs_partition): thread t owns the particles
     * [P_t, P_t+1), P_t = ceil(t·np/T), and walks runs [rlo[t], rhi[t]),
     * every run touching a particle it owns. Recomputed when the plan, the
     * particle count or T changes; no allocation. */
    unsigned part_version;
    size_t part_np;
    int part_t;   /* T of the cached partition, 0 = none */
    bool part_ok; /* false: the ranges overlap too much to pay, run serially */
    size_t rlo[SPRING_MAX_THREADS], rhi[SPRING_MAX_THREADS];
    /* Structure-of-arrays copies of x, v and f (springs_apply): component c
     * of particle i at soa[(q·dim + c)·soa_cap + i], q = 0 x, 1 v, 2 f, so
     * the run loop reads and writes whole vectors with no shuffles. Sized at
     * psys__springs_prepare for the owner's particle count. */
    double *soa;
    size_t soa_cap;
    /* The fused derivative's windows (fast/fused.c): ring_t rings of
     * 9·ring_w doubles (x, v, f components of ring_w consecutive particles,
     * particle p at slot p mod ring_w), sized by psys__springs_prepare_fused. */
    double *ring;
    size_t ring_w;
    int ring_t;
    /* The chain sweep's stage states, where one thread sweeps a set much
     * longer than the stages' span (fast/chain.c, psys__fused_chain):
     * rings of stage_r particles instead of whole state vectors, so they
     * stay in cache and never go to memory. stage_len doubles allocated. */
    double *stage;
    size_t stage_len;
    /* The chain sweep or stage by stage, where the springs reach too far
     * for the chain to be the default: chosen by timing steps of each
     * (fast/chain_tuner.c, chain_timed). Zero (calloc): nothing timed yet. */
    struct {
        bool keyed;          /* plan, n, T below hold */
        unsigned plan;       /* plan_version the timing is for */
        size_t n;            /* particle count */
        int T;               /* threads */
        int pick;            /* -1 still timing, 0 stage by stage, 1 the chain */
        int mode;            /* the mode of the step under way (0, 1), -1 none */
        int steps;           /* steps timed */
        double t;            /* clock when that step was asked for (s) */
        double best[2];      /* shortest step of each mode (s) */
    } chain;
    /* Blocks whose leavings the fused sweeps held back into the run loops
     * (fast/fused.c, holds_back), counted once per sweep: which systems
     * take that path (tests). */
    atomic_size_t held;
} springs;

/* First particle of thread t's share of np particles among T. */
static inline size_t psys__part_first(size_t np, int T, int t)
{
    return (size_t)(((uint64_t)t * np + (uint64_t)T - 1) / (uint64_t)T);
}

/* The particle in slot i. */
static inline size_t psys__springs_particle(const springs *s, size_t i) { return s->perm ? s->perm[i] : i; }

/* Row stride of a fused-derivative window of w slots: padded so that its 9
 * rows do not all fall into the same cache sets (w is a power of 2), and a
 * multiple of 8, so that every row starts on a cache line as the first does. */
static inline size_t psys__springs_ring_stride(size_t w) { return (w + 24 + 7) & ~(size_t)7; }

/** Rest lengths at time t (rest[] itself without muscles). */
const double *psys__springs_rest_now(springs *s, double t);
/** Build the plan for the current spring set (forces/spring_plan.c; allocates:
 *  PSYS_ERR_NOMEM when it cannot). */
psys_status psys__springs_plan(springs *s);
/** Frees the plan's arrays and marks it not built. */
void psys__springs_plan_free(springs *s);
/** The plan, thread t's runs for *T threads among np particles (*T drops to
 *  1 when their runs overlap too much) and *T windows for the fused
 *  derivative; PSYS_ERR_NOMEM when they cannot be allocated. */
psys_status psys__springs_prepare_fused(springs *s, size_t np, int *T);
/** The plan and T windows for the fused derivative, without a thread
 *  partition of the runs; PSYS_ERR_NOMEM when they cannot be allocated. */
psys_status psys__springs_prepare_rings(springs *s, size_t np, int T);
/** At least len doubles of stage-state rings (s->stage), on cache lines. */
psys_status psys__springs_prepare_stage(springs *s, size_t len);
/** Thread t's runs (rlo[t], rhi[t]) for np particles among T threads, cached. */
void psys__springs_partition(springs *s, size_t np, int T);

/* p, which the caller knows to lie on a 64-byte boundary. */
#if defined(__GNUC__)
#define SPRING_LINE(p) __builtin_assume_aligned((p), 64)
#else
#define SPRING_LINE(p) (p)
#endif

/* Of len springs whose first ends start at slot a, those before the first
 * whose first end starts a cache line (rows on lines, 8 doubles to a line):
 * the loops run them apart, so that a vector of the rest's first ends never
 * straddles two lines. */
static inline size_t psys__springs_to_line(size_t a, size_t len)
{
    const size_t h = (8 - (a & 7)) & 7;
    return h < len ? h : len;
}

/* Forces of run springs j < len into F (component-major: F[c·SPRING_BLOCK + j]):
 *   l = x_lo - x_hi, F = [ks(|l| - r) + kd (l̇·l)/|l|] l/|l|  (f_lo -= F, f_hi += F).
 * X, V: the SoA position and velocity components (stride cap), lo and hi
 * the runs' first particles at the two ends. uni: every spring takes ks[0]
 * and kd[0] (the run's springs share them; one load instead of one per
 * spring, the same values). line: the rows start on cache lines, cap is a
 * multiple of 8 and so is lo.
 * A spring of zero length has no direction and exerts no force. */
static inline void run_forces_d(const double *restrict X, const double *restrict V, size_t cap, size_t lo,
                                size_t hi, const double *restrict ks, const double *restrict kd,
                                const double *restrict rest, size_t len, double *restrict F, const bool uni,
                                const int d, const bool line)
{
    const double ks0 = ks[0], kd0 = kd[0];
    if (line) { /* slot lo starts a cache line in every row: so say so */
        X = (const double *)SPRING_LINE(X + lo) - lo;
        V = (const double *)SPRING_LINE(V + lo) - lo;
        cap &= ~(size_t)7;
    }
    const double *restrict xa0 = X + lo, *restrict xb0 = X + hi, *restrict va0 = V + lo, *restrict vb0 = V + hi;
    const double *restrict xa1 = X + cap + lo, *restrict xb1 = X + cap + hi;
    const double *restrict va1 = V + cap + lo, *restrict vb1 = V + cap + hi;
    const double *restrict xa2 = X + 2 * cap + lo, *restrict xb2 = X + 2 * cap + hi;
    const double *restrict va2 = V + 2 * cap + lo, *restrict vb2 = V + 2 * cap + hi;
    double *restrict F0 = F, *restrict F1 = F + SPRING_BLOCK, *restrict F2 = F + 2 * SPRING_BLOCK;
    for (size_t j = 0; j < len; j++) { /* vectorised (tests/cli/vectorised.sh) */
        double l0 = xa0[j] - xb0[j], l1 = xa1[j] - xb1[j];
        double d0 = va0[j] - vb0[j], d1 = va1[j] - vb1[j];
        double len2 = l0 * l0 + l1 * l1, dot = d0 * l0 + d1 * l1, l2 = 0;
        if (d == 3) {
            l2 = xa2[j] - xb2[j];
            double d2 = va2[j] - vb2[j];
            len2 = len2 + l2 * l2;
            dot = dot + d2 * l2;
        }
        double mag = psys__spring_mag(uni ? ks0 : ks[j], uni ? kd0 : kd[j], rest[j], len2, dot);
        F0[j] = mag * l0;
        F1[j] = mag * l1;
        if (d == 3)
            F2[j] = mag * l2;
    }
}

/* Runs shorter than this skip the vector loops (run_short): a mesh whose
 * particles come in no particular order forms hardly any runs, and a vector
 * loop's set-up and remainder per spring cost it several times the spring
 * itself (bench/README.md). */
#define SPRING_SHORT 4

/* A run of len < SPRING_SHORT springs (lo + j, hi + j), plan slots k + j,
 * on component rows of stride S (X: positions, V: velocities, F: forces;
 * a particle's slot is its index & mask): the operations of run_forces_d per
 * spring, and the additions in plan order, the first ends (f -= F) before
 * the second (f += F). Only the ends at j in [a0, a1) and [b0, b1) are
 * written. */
static inline void run_short(const double *X, const double *V, double *F, size_t S, size_t mask, size_t lo,
                             size_t hi, const double *ks, const double *kd, const double *rest, size_t len, size_t a0,
                             size_t a1, size_t b0, size_t b1, const int d)
{
    double G[3][SPRING_SHORT];
    for (size_t j = 0; j < len; j++) {
        const size_t a = (lo + j) & mask, b = (hi + j) & mask;
        double l0 = X[a] - X[b], l1 = X[S + a] - X[S + b];
        double d0 = V[a] - V[b], d1 = V[S + a] - V[S + b];
        double len2 = l0 * l0 + l1 * l1, dot = d0 * l0 + d1 * l1, l2 = 0;
        if (d == 3) {
            l2 = X[2 * S + a] - X[2 * S + b];
            double d2 = V[2 * S + a] - V[2 * S + b];
            len2 = len2 + l2 * l2;
            dot = dot + d2 * l2;
        }
        double mag = psys__spring_mag(ks[j], kd[j], rest[j], len2, dot);
        G[0][j] = mag * l0;
        G[1][j] = mag * l1;
        G[2][j] = mag * l2;
    }
    for (int c = 0; c < d; c++) {
        double *Fc = F + (size_t)c * S;
        for (size_t j = a0; j < a1; j++)
            Fc[(lo + j) & mask] -= G[c][j];
        for (size_t j = b0; j < b1; j++)
            Fc[(hi + j) & mask] += G[c][j];
    }
}

/* On x86-64 with GCC, also AVX2 and AVX-512 builds of the loop, chosen at
 * load time by what the CPU has (4 or 8 doubles per instruction instead of
 * 2). The same operations in the same order (no FMA: -ffp-contract=off;
 * sqrt and division are correctly rounded at every width), so the same bits. */
#if defined(__GNUC__) && !defined(__clang__) && defined(__x86_64__) && defined(__linux__)
#define SPRING_CLONES __attribute__((target_clones("avx512f", "avx2", "default")))
#else
#define SPRING_CLONES
#endif

/* On x86-64 with GCC or Clang: AVX-512 run loops (fast/fused_kernels.h,
 * forces/spring.c) where the CPU has AVX-512, eight springs to a vector with
 * the first and last vectors of a run masked. */
#if defined(__GNUC__) && defined(__x86_64__)
#include <immintrin.h>
#define SPRING_AVX512 1
/** Whether the AVX-512 run loops run for the springs of sys (NULL: a copy
 *  without a system): the CPU has AVX-512F and sys was not created with
 *  PSYS_SPRING_PLAIN=1 (the compiler's loops; tests, benchmarks). */
bool psys__springs_avx512(const psys_system *sys);

/* The address n doubles after p (n < 0: before), which may lie outside p's
 * array: only for lanes a mask keeps out of every access. */
static inline uintptr_t psys__lanes_at(const double *p, ptrdiff_t n)
{
    return (uintptr_t)p + (uintptr_t)n * sizeof(double);
}

/* A run's parameters as the AVX-512 loops read them: the loops start at
 * the cache line holding the run's first end, whose first spring is then
 * lane h0, so ks, kd and rest are seen h0 entries early (index i of the
 * vector at i); ks0, kd0: every lane's ks and kd where the run shares them. */
typedef struct spring_par8 {
    const double *ks, *kd, *rest;
    __m512d ks0, kd0;
} spring_par8;

__attribute__((target("avx512f"), always_inline)) static inline spring_par8
psys__spring_par8(const double *ks, const double *kd, const double *rest, size_t h0)
{
    const ptrdiff_t back = -(ptrdiff_t)h0;
    return (spring_par8){.ks = (const double *)psys__lanes_at(ks, back),
                         .kd = (const double *)psys__lanes_at(kd, back),
                         .rest = (const double *)psys__lanes_at(rest, back),
                         .ks0 = _mm512_set1_pd(ks[0]),
                         .kd0 = _mm512_set1_pd(kd[0])};
}

/* The forces g of eight springs of a run from the slot ra of their first
 * ends (on a cache line), their second ends o slots on, their parameters at
 * index i of p: the operations of run_forces_d, lane by lane. Lanes outside
 * m load nothing (their g is 0). full: m is all lanes (plain loads). */
__attribute__((target("avx512f"), always_inline)) static inline void
psys__spring_g8(const double *ra, ptrdiff_t o, size_t S, const spring_par8 *p, size_t i, __mmask8 m, const bool full,
                const bool uni, const int d, __m512d g[3])
{
#define LD_A(p) (full ? _mm512_load_pd(p) : _mm512_maskz_load_pd(m, (p)))
#define LD_U(p) (full ? _mm512_loadu_pd(p) : _mm512_maskz_loadu_pd(m, (p)))
    const double *rb_ = (const double *)psys__lanes_at(ra, o);
    __m512d l[3], dv[3];
    for (int c = 0; c < d; c++) {
        l[c] = _mm512_sub_pd(LD_A(ra + (size_t)c * S), LD_U(rb_ + (size_t)c * S));
        dv[c] = _mm512_sub_pd(LD_A(ra + (size_t)(d + c) * S), LD_U(rb_ + (size_t)(d + c) * S));
    }
    __m512d len2 = _mm512_add_pd(_mm512_mul_pd(l[0], l[0]), _mm512_mul_pd(l[1], l[1]));
    __m512d dot = _mm512_add_pd(_mm512_mul_pd(dv[0], l[0]), _mm512_mul_pd(dv[1], l[1]));
    if (d == 3) {
        len2 = _mm512_add_pd(len2, _mm512_mul_pd(l[2], l[2]));
        dot = _mm512_add_pd(dot, _mm512_mul_pd(dv[2], l[2]));
    }
    const __m512d kks = uni ? p->ks0 : LD_U(p->ks + i), kkd = uni ? p->kd0 : LD_U(p->kd + i);
    const __m512d L = _mm512_sqrt_pd(len2), inv = _mm512_div_pd(_mm512_set1_pd(1.0), L);
    __m512d mag = _mm512_mul_pd(
        _mm512_add_pd(_mm512_mul_pd(kks, _mm512_sub_pd(L, LD_U(p->rest + i))), _mm512_mul_pd(_mm512_mul_pd(kkd, dot), inv)),
        inv);
    /* len2 == 0: +0; a NaN len2 keeps its NaN, as in psys__spring_mag */
    mag = _mm512_maskz_mov_pd(_mm512_cmp_pd_mask(len2, _mm512_setzero_pd(), _CMP_NEQ_UQ), mag);
    for (int c = 0; c < d; c++)
        g[c] = _mm512_mul_pd(mag, l[c]);
#undef LD_A
#undef LD_U
}

#else
#define SPRING_AVX512 0
static inline bool psys__springs_avx512(const psys_system *sys)
{
    (void)sys;
    return false;
}
#endif
#endif
