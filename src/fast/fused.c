/* The derivative [v | f/m] of a system whose forces are its springs and
 * per-particle forces (PSYS_FORCE_PER_PARTICLE with apply_rows), in one
 * pass over memory instead of one per force object plus copies.
 *
 * The generic derivative clears f, lets each force object sweep it, copies
 * x, v and f into component arrays for the spring runs and back, copies v
 * and forms f/m: about ten sweeps over arrays that at 10⁶ particles live in
 * main memory. Here a window of ring_w consecutive particles slides along
 * the plan (force_spring.c): particles enter it (x, v into component rows,
 * f = 0 plus the forces listed before the springs), the runs of each block
 * of 256 first particles add their spring forces, and particles that no
 * later run touches leave it (forces listed after the springs, then v and
 * f/m into ydot, or straight into the solver's stage work, psys__stage_pass;
 * on the AVX-512 loops a 3-D system's stage work is done among the next
 * block's springs, exitq). The window stays in cache; y is read once, ydot
 * written once.
 *
 * Same bits as the generic path: every particle's force sees the same
 * operations in the same order (0, the forces before the springs in list
 * order, its springs in plan order with a run's first ends before its
 * second ends, the forces after), and f/m is the same expression. Threads
 * own particle ranges and walk the runs touching them (the spring loop's
 * partition), each with its own window, so results do not depend on the
 * thread count either. */
#include "fast/fast.h"
#include "forces/springs.h"

#include <math.h>
#include <stdatomic.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#ifdef _OPENMP
#include <omp.h>
#endif

#define FUSED_MAX_ROWS 8 /* per-particle forces before and after the springs */
/* Overlapping runs with an offset of at least this many springs go in
 * reverse chunks (fused_part_d), shorter ones through a second loop. */
#define FUSED_CHUNK_MIN 8
/* Particles enter the window in granules of this many (a power of 2;
 * sweep_to_d). */
#define FUSED_ENTER 64
/* Leavings are held back into the run loops (exitq) for systems of at
 * least this many particles, whose solver's vectors stream from beyond L2:
 * there it was faster (cloth-1024 0.95 ×, rope-1000000 0.93 ×), at 100²
 * about 1.02 × slower (bench/README.md, "Held-back leavings"). */
#define FUSED_HOLD_MIN 32768

/* Into each clone of fused_part (SPRING_CLONES), so the loops get its
 * instruction set. */
#if defined(__GNUC__)
#define FUSED_INLINE __attribute__((always_inline)) inline
#else
#define FUSED_INLINE inline
#endif

/* The loops of run_pair_d carry no dependence between iterations (their
 * rows are distinct, and a run's two ranges are distinct where both are
 * written); GCC honours restrict only on parameters, and these pointers are
 * derived from one, so it is told directly. */
#if defined(__GNUC__) && !defined(__clang__)
#define FUSED_IVDEP _Pragma("GCC ivdep")
#else
#define FUSED_IVDEP
#endif

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

/* The row kernel of force class cls, or NULL: the fused path takes the
 * per-particle forces that have one. */
static rows_fn rows_of(const psys_force_class *cls)
{
    return (cls->traits & PSYS_FORCE_PER_PARTICLE) ? cls->apply_rows : NULL;
}

/* The fused path runs whenever a system is eligible: it was not slower
 * than the generic one at any size measured, and mostly faster, even in
 * cache (cloth-N, rk4, one thread, AMD EPYC family 26, AVX-512: N = 8 to
 * 256, 1.2 to 3.9 × faster; on an AVX2 family 25 host the two were equal
 * at 100²; bench/README.md).
 * PSYS_FUSED=0 turns it off; PSYS_FUSED=1 also runs small sets on all the
 * evaluation's threads (tests, benchmarks). */

/* Whether the fused path computes s's derivative: springs, and otherwise
 * only forces with row kernels (at most FUSED_MAX_ROWS on each side of the
 * springs), then the planes' contact forces, which need each particle's
 * total force (psys__contact_rows, as a particle leaves the window); no
 * MPI decomposition. */
static bool eligible(const psys_system *s, fused *fz)
{
    if (!s->springs || psys__springs_count(s->springs) == 0 || s->dist || s->own_mark || s->n == 0)
        return false;
    /* the planes take particles by their own index (psys__state_order_begin
     * declines systems with planes, so this does not happen) */
    if (s->nplanes && s->ode_perm)
        return false;
    const char *force = getenv("PSYS_FUSED");
    if (force && force[0] == '0')
        return false;
    fz->forced = force && force[0] == '1';
    fz->k512 = psys__springs_avx512();
    bool after = false;
    fz->npre = fz->npost = 0;
    for (size_t i = 0; i < s->nforces; i++) {
        if (s->forces[i].data == s->springs) {
            after = true;
            continue;
        }
        rows_fn fn = rows_of(s->forces[i].cls);
        int *cnt = after ? &fz->npost : &fz->npre;
        if (!fn || *cnt == FUSED_MAX_ROWS)
            return false;
        rowforce *slot = after ? &fz->post[*cnt] : &fz->pre[*cnt];
        slot->fn = fn;
        slot->data = s->forces[i].data;
        ++*cnt;
    }
    return after;
}

/* Pointers to component rows q (0 x, 1 v, 2 f) of ring slot i0. */
static inline void rows_at(double *rb, size_t S, int q, int d, size_t i0, double *out[3])
{
    for (int c = 0; c < 3; c++)
        out[c] = c < d ? rb + (size_t)(q * d + c) * S + i0 : NULL;
}

/* The input state's x (half 0) or v (half 1) from particle a on: a run of
 * particles never crosses a multiple of the window's ring_w, nor then of the
 * stage ring's R (a multiple of it). */
static inline const double *state_at(const fused *fz, int half, size_t a, const int d)
{
    if (fz->in_ring && a >= fz->zlo && a < fz->zhi)
        return fz->in_ring + (half ? fz->rd : 0) + (a & fz->rmask) * (size_t)d;
    return (half ? fz->v : fz->x) + a * (size_t)d;
}

/* Where the pass's next state goes for x (half 0) or v (half 1) from
 * particle a on, or NULL (no next state). */
static inline double *next_at(const fused *fz, int half, size_t a, const int d)
{
    if (fz->out_ring && a >= fz->zlo && a < fz->zhi)
        return fz->out_ring + (half ? fz->rd : 0) + (a & fz->rmask) * (size_t)d;
    const psys__stage_pass *p = fz->pass;
    return p->next ? p->next + (half ? fz->nd : 0) + a * (size_t)d : NULL;
}

/* The end of the piece of particles [a, e) that lies in the window's
 * slots before they wrap around (slot W − 1 is followed by slot 0). */
static inline size_t window_piece_end(const fused *fz, size_t a, size_t e)
{
    const size_t wrap = a + (fz->W - (a & fz->mask));
    return wrap < e ? wrap : e;
}

/* How many of particles [a, a + cnt) lie on a's side of the stage rings'
 * edges zlo and zhi (all of them without rings): the pieces enter and
 * leave take, each in one kind of storage. */
static inline size_t ring_piece(const fused *fz, size_t a, size_t cnt)
{
    size_t e = a + cnt;
    if (!fz->in_ring && !fz->out_ring)
        return cnt;
    if (a < fz->zlo && fz->zlo < e)
        e = fz->zlo;
    else if (a < fz->zhi && fz->zhi < e)
        e = fz->zhi;
    return e - a;
}

/* How far ahead enter_perm and leave_perm fetch the particles they gather
 * and scatter. */
#define PERM_AHEAD 8
#if defined(__GNUC__)
#define PERM_PREFETCH(p) __builtin_prefetch(p)
#else
#define PERM_PREFETCH(p) ((void)(p))
#endif

/* Entering (window_move) for slots [a, a + cnt) in the springs' internal order: x, v and
 * the masses gathered particle by particle, in pieces of SPRING_BLOCK (the
 * forces before the springs act on each particle alone). */
static FUSED_INLINE void enter_perm(const fused *fz, double *rb, size_t a, size_t cnt, const int d)
{
    double m[SPRING_BLOCK];
    for (size_t j0 = 0; j0 < cnt; j0 += SPRING_BLOCK) {
        const size_t c = cnt - j0 < SPRING_BLOCK ? cnt - j0 : SPRING_BLOCK, i0 = (a + j0) & fz->mask;
        double *X[3], *V[3], *F[3];
        rows_at(rb, fz->S, 0, d, i0, X);
        rows_at(rb, fz->S, 1, d, i0, V);
        rows_at(rb, fz->S, 2, d, i0, F);
        for (size_t j = 0; j < c; j++) {
            const size_t p = fz->perm[a + j0 + j], pd = p * (size_t)d;
            if (j + PERM_AHEAD < c) { /* the particles come from all over memory */
                const size_t p2 = fz->perm[a + j0 + j + PERM_AHEAD], pf = p2 * (size_t)d;
                PERM_PREFETCH(fz->x + pf);
                PERM_PREFETCH(fz->v + pf);
                PERM_PREFETCH(fz->mass + p2);
            }
            m[j] = fz->mass[p];
            for (int k = 0; k < d; k++) {
                X[k][j] = fz->x[pd + (size_t)k];
                V[k][j] = fz->v[pd + (size_t)k];
                F[k][j] = 0.0;
            }
        }
        for (int k = 0; k < fz->npre; k++)
            fz->pre[k].fn(fz->pre[k].data, d, c, m, (const double *const *)V, F, false);
    }
}

/* Particles of one piece in one kind of storage enter the window (window_move). */
static FUSED_INLINE void enter_rows(const fused *fz, double *rb, size_t a, size_t cnt, const int d)
{
    const size_t i0 = a & fz->mask;
    double *X[3], *V[3], *F[3];
    rows_at(rb, fz->S, 0, d, i0, X);
    rows_at(rb, fz->S, 1, d, i0, V);
    rows_at(rb, fz->S, 2, d, i0, F);
    const double *src[2] = {state_at(fz, 0, a, d), state_at(fz, 1, a, d)};
    double *const *dst[2] = {X, V};
    for (int q = 0; q < 2; q++) {
        const double *restrict p = src[q];
        double *restrict c0 = dst[q][0], *restrict c1 = dst[q][1], *restrict c2 = dst[q][2];
        if (d == 2) {
            for (size_t j = 0; j < cnt; j++) {
                c0[j] = p[2 * j];
                c1[j] = p[2 * j + 1];
            }
        } else {
            for (size_t j = 0; j < cnt; j++) {
                c0[j] = p[3 * j];
                c1[j] = p[3 * j + 1];
                c2[j] = p[3 * j + 2];
            }
        }
    }
    /* the first force before the springs clears F as it adds (first) */
    if (fz->npre == 0)
        for (int c = 0; c < d; c++)
            memset(F[c], 0, cnt * sizeof(double)); /* all-zero bits: +0.0 */
    for (int k = 0; k < fz->npre; k++)
        fz->pre[k].fn(fz->pre[k].data, d, cnt, fz->mass + a, (const double *const *)V, F, k == 0);
}

/* Bit 63 set when one of a[0..m) is not finite (psys__nonfinite_bit). */
static FUSED_INLINE uint64_t nonfinite_bits(const double *restrict a, size_t m)
{
    uint64_t any = 0;
    for (size_t j = 0; j < m; j++)
        any |= psys__nonfinite_bit(a[j]);
    return any;
}

/* The last pass's work in place (psys__stage_pass.in_place): the result of
 * a PSYS__ACC_BASE_* acc_op into the state at put, which holds the step's
 * start, and that start into acc; nonfinite_bits of the result where the pass
 * asks. The same expressions as stage_apply's. */
static FUSED_INLINE uint64_t stage_apply_in_place(const psys__stage_pass *p, double *restrict put,
                                                  double *restrict acc, const double *restrict k, size_t m)
{
    const double h = p->h, w = p->w;
    switch (p->acc_op) {
    case PSYS__ACC_BASE_STEP:
        for (size_t j = 0; j < m; j++) {
            const double b = put[j];
            put[j] = b + h * (w * k[j]);
            acc[j] = b;
        }
        break;
    case PSYS__ACC_BASE_FIRST:
        for (size_t j = 0; j < m; j++) {
            const double b = put[j];
            put[j] = b + h * (0.0 + w * k[j]);
            acc[j] = b;
        }
        break;
    default: /* PSYS__ACC_BASE_SUM */
        for (size_t j = 0; j < m; j++) {
            const double b = put[j];
            put[j] = b + h * (acc[j] + w * k[j]);
            acc[j] = b;
        }
        break;
    }
    return p->finite ? nonfinite_bits(put, m) : 0;
}

/* The solver's work (psys__stage_pass) on derivative components [off, off + m)
 * with values k and the step's start at base (not always p->base + off:
 * fused.base): the expressions of rk_chain_stages, element by element; or,
 * with put (the same place as base, writable), stage_apply_in_place.
 * Returns nonfinite_bits of what it wrote to acc where the pass asks
 * (.finite), read back while still in cache: the solver then need not pass
 * over the whole result again. */
static FUSED_INLINE uint64_t stage_apply(const psys__stage_pass *p, const double *restrict base, size_t off,
                                         const double *restrict k, size_t m, double *restrict nx, double *put)
{
    if (put) /* the last pass (nx NULL) with a PSYS__ACC_BASE_* acc_op: base is put */
        return stage_apply_in_place(p, put, p->acc + off, k, m);
    const double h = p->h, w = p->w, an = p->a;
    if (nx) {
        for (size_t j = 0; j < m; j++)
            nx[j] = base[j] + h * (an * k[j]);
    }
    if (!p->acc)
        return 0;
    double *restrict acc = p->acc + off;
    switch (p->acc_op) {
    case PSYS__ACC_SET:
        for (size_t j = 0; j < m; j++)
            acc[j] = 0.0 + w * k[j];
        break;
    case PSYS__ACC_ADD:
        for (size_t j = 0; j < m; j++)
            acc[j] = acc[j] + w * k[j];
        break;
    case PSYS__ACC_BASE_STEP:
        for (size_t j = 0; j < m; j++)
            acc[j] = base[j] + h * (w * k[j]);
        break;
    case PSYS__ACC_BASE_FIRST:
        for (size_t j = 0; j < m; j++)
            acc[j] = base[j] + h * (0.0 + w * k[j]);
        break;
    default: /* PSYS__ACC_BASE_SUM */
        for (size_t j = 0; j < m; j++)
            acc[j] = base[j] + h * (acc[j] + w * k[j]);
        break;
    }
    return p->finite ? nonfinite_bits(acc, m) : 0;
}

/* f/m of `cnt` particles (rows f0..f2 of the window) into acc, particle-major;
 * not-free particles (inv_mass 0) get exactly 0. */
static FUSED_INLINE void accel(const double *restrict im, const double *restrict f0, const double *restrict f1,
                               const double *restrict f2, size_t cnt, double *restrict acc, const int d)
{
    /* The products are formed unconditionally and then selected, so the
     * loop needs no masked loads (the same values: f·w where w ≠ 0). */
    if (d == 2) {
        for (size_t j = 0; j < cnt; j++) { /* vectorised (tests/cli/vectorised.sh) */
            const double w = im[j], a0 = f0[j] * w, a1 = f1[j] * w;
            acc[2 * j] = w != 0 ? a0 : 0.0;
            acc[2 * j + 1] = w != 0 ? a1 : 0.0;
        }
    } else {
        for (size_t j = 0; j < cnt; j++) { /* vectorised (tests/cli/vectorised.sh) */
            const double w = im[j], a0 = f0[j] * w, a1 = f1[j] * w, a2 = f2[j] * w;
            acc[3 * j] = w != 0 ? a0 : 0.0;
            acc[3 * j + 1] = w != 0 ? a1 : 0.0;
            acc[3 * j + 2] = w != 0 ? a2 : 0.0;
        }
    }
}

/* A pass that asked (.finite) wrote a non-finite acc where bit 63 of bits
 * is set; threads may say so at once, all with the same value. */
static FUSED_INLINE void note_nonfinite(const fused *fz, uint64_t bits)
{
    if (bits >> 63)
        atomic_store_explicit(fz->nonfinite, 1, memory_order_relaxed);
}

/* Leaving (window_move) for slots [a, a + cnt) in the springs' internal order: each
 * particle's derivative (or the solver's work on it) at its own place, the
 * same expressions element by element. */
static FUSED_INLINE void leave_perm(const fused *fz, double *rb, size_t a, size_t cnt, const int d)
{
    double m[SPRING_BLOCK], k[3];
    uint64_t bits = 0;
    for (size_t j0 = 0; j0 < cnt; j0 += SPRING_BLOCK) {
        const size_t c = cnt - j0 < SPRING_BLOCK ? cnt - j0 : SPRING_BLOCK, i0 = (a + j0) & fz->mask;
        double *V[3], *F[3];
        rows_at(rb, fz->S, 1, d, i0, V);
        rows_at(rb, fz->S, 2, d, i0, F);
        for (size_t j = 0; j < c && fz->npost; j++)
            m[j] = fz->mass[fz->perm[a + j0 + j]];
        for (int q = 0; q < fz->npost; q++)
            fz->post[q].fn(fz->post[q].data, d, c, m, (const double *const *)V, F, false);
        if (fz->planes) {
            double *X[3];
            rows_at(rb, fz->S, 0, d, i0, X);
            psys__contact_rows(fz->planes, fz->perm, a + j0, c, (const double *const *)X, (const double *const *)V,
                               F);
        }
        for (size_t j = 0; j < c; j++) {
            const size_t p = fz->perm[a + j0 + j], pd = p * (size_t)d;
            if (j + PERM_AHEAD < c) { /* the particles come from all over memory */
                const psys__stage_pass *ps = fz->pass;
                const size_t p2 = fz->perm[a + j0 + j + PERM_AHEAD], pf = p2 * (size_t)d;
                PERM_PREFETCH(fz->inv_mass + p2);
                PERM_PREFETCH(fz->v + pf);
                if (!ps) {
                    PERM_PREFETCH(fz->xdot + pf);
                    PERM_PREFETCH(fz->vdot + pf);
                } else {
                    for (int half = 0; half < 2; half++) { /* x and v parts */
                        const size_t h = half ? fz->nd : 0;
                        PERM_PREFETCH(fz->base[half] + pf);
                        if (ps->next)
                            PERM_PREFETCH(ps->next + h + pf);
                        if (ps->acc)
                            PERM_PREFETCH(ps->acc + h + pf);
                    }
                }
            }
            accel(fz->inv_mass + p, F[0] + j, F[1] + j, d == 3 ? F[2] + j : NULL, 1, k, d);
            if (!fz->pass) {
                for (int q = 0; q < d; q++) {
                    fz->xdot[pd + (size_t)q] = fz->v[pd + (size_t)q];
                    fz->vdot[pd + (size_t)q] = k[q];
                }
            } else {
                bits |= stage_apply(fz->pass, fz->base[0] + pd, pd, fz->v + pd, (size_t)d, next_at(fz, 0, p, d),
                                    fz->put[0] ? fz->put[0] + pd : NULL); /* x' = v */
                bits |= stage_apply(fz->pass, fz->base[1] + pd, fz->nd + pd, k, (size_t)d, next_at(fz, 1, p, d),
                                    fz->put[1] ? fz->put[1] + pd : NULL);
            }
        }
    }
    note_nonfinite(fz, bits);
}

/* The forces after the springs on particles [a, a + cnt) of one piece
 * (leave_rows). */
static FUSED_INLINE void leave_post(const fused *fz, double *rb, size_t a, size_t cnt, const int d)
{
    const size_t i0 = a & fz->mask;
    double *V[3], *F[3];
    rows_at(rb, fz->S, 1, d, i0, V);
    rows_at(rb, fz->S, 2, d, i0, F);
    for (int k = 0; k < fz->npost; k++)
        fz->post[k].fn(fz->post[k].data, d, cnt, fz->mass + a, (const double *const *)V, F, false);
    if (fz->planes) {
        double *X[3];
        rows_at(rb, fz->S, 0, d, i0, X);
        psys__contact_rows(fz->planes, NULL, a, cnt, (const double *const *)X, (const double *const *)V, F);
    }
}

/* Particles of one piece in one kind of storage leave the window (window_move): the forces
 * after the springs, then ydot = [v | f/m] (not-free particles, inv_mass 0,
 * get exactly 0). */
static FUSED_INLINE void leave_rows(const fused *fz, double *rb, size_t a, size_t cnt, const int d)
{
    const size_t i0 = a & fz->mask;
    double *F[3];
    rows_at(rb, fz->S, 2, d, i0, F);
    leave_post(fz, rb, a, cnt, d);
    const size_t ad = a * (size_t)d;
    if (!fz->pass) {
        memcpy(fz->xdot + ad, fz->v + ad, cnt * (size_t)d * sizeof(double));
        accel(fz->inv_mass + a, F[0], F[1], F[2], cnt, fz->vdot + ad, d);
        return;
    }
    uint64_t bits = stage_apply(fz->pass, fz->base[0] + ad, ad, state_at(fz, 1, a, d), cnt * (size_t)d,
                                next_at(fz, 0, a, d), fz->put[0] ? fz->put[0] + ad : NULL); /* x' = v */
    double k[3 * SPRING_BLOCK];
    for (size_t j = 0; j < cnt; j += SPRING_BLOCK) {
        const size_t m = cnt - j < SPRING_BLOCK ? cnt - j : SPRING_BLOCK;
        accel(fz->inv_mass + a + j, F[0] + j, F[1] + j, d == 3 ? F[2] + j : NULL, m, k, d);
        const size_t o = ad + j * (size_t)d;
        bits |= stage_apply(fz->pass, fz->base[1] + o, fz->nd + o, k, m * (size_t)d, next_at(fz, 1, a + j, d),
                            fz->put[1] ? fz->put[1] + o : NULL);
    }
    note_nonfinite(fz, bits);
}

/* Particles [a, a + cnt), one contiguous piece of the window, enter it
 * (`in`) or leave it: from all over memory in the springs' internal order,
 * else in pieces that each use one kind of storage (ring_piece). */
static FUSED_INLINE void window_move(const fused *fz, double *rb, size_t a, size_t cnt, const int d, const bool in)
{
    if (fz->perm) {
        if (in)
            enter_perm(fz, rb, a, cnt, d);
        else
            leave_perm(fz, rb, a, cnt, d);
        return;
    }
    for (size_t m; cnt > 0; a += m, cnt -= m) {
        m = ring_piece(fz, a, cnt);
        if (in)
            enter_rows(fz, rb, a, m, d);
        else
            leave_rows(fz, rb, a, m, d);
    }
}

/* Leavings held back (sweep_to_d): particles [lo, hi), whole octets from
 * a multiple of 8, whose forces are complete (the forces after the springs
 * included) and whose solver's work is still to do. The AVX-512 run loops
 * do one octet after each vector of springs: that work, which streams the
 * solver's vectors, then runs among the springs' instead of after them
 * (bench/README.md, "Held-back leavings"). */
typedef struct exitq {
    const fused *fz;
    double *rb;
    size_t lo, hi;
    uint64_t bits; /* nonfinite_bits of what they wrote */
} exitq;

#if SPRING_AVX512
/* Three component rows of eight particles (x0..x7, y0..y7, z0..z7) as the
 * 24 doubles of those particles particle-major, three vectors. */
__attribute__((target("avx512f"), always_inline)) static inline void aos3(const __m512d r[3], __m512d o[3])
{
    /* lanes from r[0] (0..7) and r[1] (8..15), then r[2]'s by a mask */
    o[0] = _mm512_mask_permutexvar_pd(_mm512_permutex2var_pd(r[0], _mm512_set_epi64(10, 2, 0, 9, 1, 0, 8, 0), r[1]),
                                      0x24, _mm512_set_epi64(0, 0, 1, 0, 0, 0, 0, 0), r[2]);
    o[1] = _mm512_mask_permutexvar_pd(_mm512_permutex2var_pd(r[0], _mm512_set_epi64(5, 0, 12, 4, 0, 11, 3, 0), r[1]),
                                      0x49, _mm512_set_epi64(0, 4, 0, 0, 3, 0, 0, 2), r[2]);
    o[2] = _mm512_mask_permutexvar_pd(_mm512_permutex2var_pd(r[0], _mm512_set_epi64(0, 15, 7, 0, 14, 6, 0, 13), r[1]),
                                      0x92, _mm512_set_epi64(7, 0, 0, 6, 0, 0, 5, 0), r[2]);
}

/* nonfinite_bits of eight values, bit 63 of an or of their lanes */
__attribute__((target("avx512f"), always_inline)) static inline __m512i nonfinite8(__m512d x)
{
    return _mm512_add_epi64(_mm512_and_epi64(_mm512_castpd_si512(x), _mm512_set1_epi64(0x7ff0000000000000LL)),
                            _mm512_set1_epi64(0x0010000000000000LL));
}

/* stage_apply on the 24 components of an octet (k: three vectors), element
 * by element the same expressions. */
__attribute__((target("avx512f"), always_inline)) static inline __m512i
stage8(const psys__stage_pass *p, const double *base, double *acc, const __m512d k[3], double *nx, double *put)
{
    const __m512d h = _mm512_set1_pd(p->h), w = _mm512_set1_pd(p->w), zero = _mm512_setzero_pd();
    __m512i nf = _mm512_setzero_si512();
    if (put) {
        for (int t = 0; t < 3; t++) {
            const __m512d b = _mm512_loadu_pd(put + 8 * t), wk = _mm512_mul_pd(w, k[t]);
            const __m512d in = p->acc_op == PSYS__ACC_BASE_STEP    ? wk
                               : p->acc_op == PSYS__ACC_BASE_FIRST ? _mm512_add_pd(zero, wk)
                                                                    : _mm512_add_pd(_mm512_loadu_pd(acc + 8 * t), wk);
            const __m512d r = _mm512_add_pd(b, _mm512_mul_pd(h, in));
            _mm512_storeu_pd(put + 8 * t, r);
            _mm512_storeu_pd(acc + 8 * t, b);
            nf = _mm512_or_si512(nf, nonfinite8(r));
        }
        return p->finite ? nf : _mm512_setzero_si512();
    }
    if (nx) {
        const __m512d an = _mm512_set1_pd(p->a);
        for (int t = 0; t < 3; t++)
            _mm512_storeu_pd(nx + 8 * t,
                             _mm512_add_pd(_mm512_loadu_pd(base + 8 * t), _mm512_mul_pd(h, _mm512_mul_pd(an, k[t]))));
    }
    if (!acc)
        return nf;
    for (int t = 0; t < 3; t++) {
        const __m512d wk = _mm512_mul_pd(w, k[t]);
        __m512d r;
        switch (p->acc_op) {
        case PSYS__ACC_SET:
            r = _mm512_add_pd(zero, wk);
            break;
        case PSYS__ACC_ADD:
            r = _mm512_add_pd(_mm512_loadu_pd(acc + 8 * t), wk);
            break;
        case PSYS__ACC_BASE_STEP:
            r = _mm512_add_pd(_mm512_loadu_pd(base + 8 * t), _mm512_mul_pd(h, wk));
            break;
        case PSYS__ACC_BASE_FIRST:
            r = _mm512_add_pd(_mm512_loadu_pd(base + 8 * t), _mm512_mul_pd(h, _mm512_add_pd(zero, wk)));
            break;
        default: /* PSYS__ACC_BASE_SUM */
            r = _mm512_add_pd(_mm512_loadu_pd(base + 8 * t),
                              _mm512_mul_pd(h, _mm512_add_pd(_mm512_loadu_pd(acc + 8 * t), wk)));
            break;
        }
        _mm512_storeu_pd(acc + 8 * t, r);
        nf = _mm512_or_si512(nf, nonfinite8(r));
    }
    return p->finite ? nf : _mm512_setzero_si512();
}

/* The held-back work of the octet at q->lo (3-D, the solver's pass, its
 * own storage kind: exitq), what leave_rows does after the forces: x' = v
 * from the window's v rows (the input state's v, copied), v' = f/m. */
__attribute__((target("avx512f"), always_inline)) static inline void exit8(exitq *q)
{
    const fused *fz = q->fz;
    const size_t a = q->lo, i0 = a & fz->mask, e = a * 3;
    double *V[3], *F[3];
    rows_at(q->rb, fz->S, 1, 3, i0, V);
    rows_at(q->rb, fz->S, 2, 3, i0, F);
    const psys__stage_pass *p = fz->pass;
    __m512d r[3], k[3];
    for (int c = 0; c < 3; c++)
        r[c] = _mm512_load_pd(V[c]);
    aos3(r, k);
    __m512i nf = stage8(p, fz->base[0] + e, p->acc ? p->acc + e : NULL, k, next_at(fz, 0, a, 3),
                        fz->put[0] ? fz->put[0] + e : NULL);
    const __m512d im = _mm512_loadu_pd(fz->inv_mass + a);
    const __mmask8 moving = _mm512_cmp_pd_mask(im, _mm512_setzero_pd(), _CMP_NEQ_UQ); /* accel's w != 0 */
    for (int c = 0; c < 3; c++)
        r[c] = _mm512_maskz_mov_pd(moving, _mm512_mul_pd(_mm512_load_pd(F[c]), im));
    aos3(r, k);
    nf = _mm512_or_si512(nf, stage8(p, fz->base[1] + e, p->acc ? p->acc + fz->nd + e : NULL, k,
                                    next_at(fz, 1, a, 3), fz->put[1] ? fz->put[1] + e : NULL));
    q->bits |= (uint64_t)_mm512_reduce_or_epi64(nf);
    q->lo = a + 8;
}
/* q NULL: nothing held back (a constant where sweep_to_d is inlined, so
 * the loops carry no test then). */
#define EXIT_STEP(q)                              \
    do {                                          \
        if ((q) != NULL && (q)->lo < (q)->hi)     \
            exit8(q);                             \
    } while (0)

/* The held-back octets that are left. */
__attribute__((target("avx512f"))) static void exit_flush(exitq *q)
{
    while (q->lo < q->hi)
        exit8(q);
}
#else
static void exit_flush(exitq *q) { (void)q; }
#endif

/* Forces of run springs j < len with their ends at ring slots a + j and
 * b + j (rows of stride S: x, v, f components): f_a -= F in the loop, and
 * f_b += F too when `apart` (the two ranges do not overlap, so no particle
 * gets two of the run's additions), else F is kept in Fk (stride
 * SPRING_BLOCK) for a second loop. The operations of run_forces_d.
 * Each row is addressed from one base, the two ends at j and j + (b - a)
 * (the ring slots of the two ranges never coincide: they lie less than
 * the window apart, and a piece is cut where either range wraps). */
static FUSED_INLINE void run_pair_d(double *rb, size_t S, size_t a, size_t b, const double *restrict ks,
                                    const double *restrict kd, const double *restrict rest, size_t len,
                                    double *restrict Fk, const bool apart, const bool uni, const int d,
                                    const bool line)
{
    /* uni: the run's springs share ks and kd, read once (two loads fewer
     * per spring, the same values) */
    const double ks0 = ks[0], kd0 = kd[0];
    const ptrdiff_t o = (ptrdiff_t)b - (ptrdiff_t)a;
    /* line: slot a starts a cache line in every row (S is a multiple of 8,
     * and saying so lets the compiler know it of each row) */
    double *const r0 = line ? SPRING_LINE(rb + a) : rb + a;
    S = line ? S & ~(size_t)7 : S;
    const double *x0 = r0, *x1 = r0 + S, *v0 = r0 + (size_t)d * S, *v1 = r0 + (size_t)(d + 1) * S;
    double *f0 = r0 + (size_t)(2 * d) * S, *f1 = r0 + (size_t)(2 * d + 1) * S;
    double *restrict F0 = Fk, *restrict F1 = Fk + SPRING_BLOCK, *restrict F2 = Fk + 2 * SPRING_BLOCK;
    if (d == 2) {
        FUSED_IVDEP
        for (size_t j = 0; j < len; j++) { /* vectorised (tests/cli/vectorised.sh) */
            const ptrdiff_t jb = (ptrdiff_t)j + o;
            double l0 = x0[j] - x0[jb], l1 = x1[j] - x1[jb];
            double d0 = v0[j] - v0[jb], d1 = v1[j] - v1[jb];
            double mag = psys__spring_mag(uni ? ks0 : ks[j], uni ? kd0 : kd[j], rest[j], l0 * l0 + l1 * l1,
                                          d0 * l0 + d1 * l1);
            double g0 = mag * l0, g1 = mag * l1;
            f0[j] -= g0;
            f1[j] -= g1;
            if (apart) {
                f0[jb] += g0;
                f1[jb] += g1;
            } else {
                F0[j] = g0;
                F1[j] = g1;
            }
        }
        return;
    }
    const double *x2 = r0 + 2 * S, *v2 = r0 + 5 * S;
    double *f2 = r0 + 8 * S;
    FUSED_IVDEP
    for (size_t j = 0; j < len; j++) { /* vectorised (tests/cli/vectorised.sh) */
        const ptrdiff_t jb = (ptrdiff_t)j + o;
        double l0 = x0[j] - x0[jb], l1 = x1[j] - x1[jb], l2 = x2[j] - x2[jb];
        double d0 = v0[j] - v0[jb], d1 = v1[j] - v1[jb], d2 = v2[j] - v2[jb];
        double len2 = l0 * l0 + l1 * l1, dot = d0 * l0 + d1 * l1;
        len2 = len2 + l2 * l2;
        dot = dot + d2 * l2;
        double mag = psys__spring_mag(uni ? ks0 : ks[j], uni ? kd0 : kd[j], rest[j], len2, dot);
        double g0 = mag * l0, g1 = mag * l1, g2 = mag * l2;
        f0[j] -= g0;
        f1[j] -= g1;
        f2[j] -= g2;
        if (apart) {
            f0[jb] += g0;
            f1[jb] += g1;
            f2[jb] += g2;
        } else {
            F0[j] = g0;
            F1[j] = g1;
            F2[j] = g2;
        }
    }
}

#if SPRING_AVX512
/* Eight springs of run_pair_512: f_a -= g, and f_b += g (apart) or g into
 * the scratch at pf. */
__attribute__((target("avx512f"), always_inline)) static inline void
spring8(double *ra, ptrdiff_t o, size_t S, const spring_par8 *p, size_t i, double *pf, __mmask8 m, const bool full,
        const bool uni, const bool apart, const int d)
{
    __m512d g[3];
    psys__spring_g8(ra, o, S, p, i, m, full, uni, d, g);
    double *rb_ = (double *)psys__lanes_at(ra, o);
    for (int c = 0; c < d; c++) {
        double *fa = ra + (size_t)(2 * d + c) * S;
        if (full) {
            _mm512_store_pd(fa, _mm512_sub_pd(_mm512_load_pd(fa), g[c]));
        } else {
            _mm512_mask_store_pd(fa, m, _mm512_sub_pd(_mm512_maskz_load_pd(m, fa), g[c]));
        }
        if (apart) {
            double *fb = rb_ + (size_t)(2 * d + c) * S;
            if (full)
                _mm512_storeu_pd(fb, _mm512_add_pd(_mm512_loadu_pd(fb), g[c]));
            else
                _mm512_mask_storeu_pd(fb, m, _mm512_add_pd(_mm512_maskz_loadu_pd(m, fb), g[c]));
        } else if (full) {
            _mm512_storeu_pd(pf + (size_t)c * SPRING_BLOCK, g[c]);
        } else {
            _mm512_mask_storeu_pd(pf + (size_t)c * SPRING_BLOCK, m, g[c]);
        }
    }
}

/* A run of offset o < 8 (a row's near neighbours) on AVX-512, both ends in
 * one pass: in the vector of particles p..p+7 (from the line holding the
 * first end a), p − g_p for the first ends, then + g_{p−o} for the second
 * ends, g_{p−o} shifted in from this vector's springs and the last vector's.
 * Each particle sees the plan's order (its first end before its second end;
 * the scratch and second loop of the plain path do the same), so the same
 * bits, with one load and store of each force instead of three of each. */
__attribute__((target("avx512f"), always_inline)) static inline void
run_near_512_d(double *rb, size_t S, size_t a, size_t o, const double *ks, const double *kd, const double *rest,
               size_t len, const bool uni, const int d, exitq *q)
{
    const size_t h0 = a & 7, endA = h0 + len, endB = endA + o;
    double *r = __builtin_assume_aligned((double *)psys__lanes_at(rb + a, -(ptrdiff_t)h0), 64); /* on a cache line */
    const spring_par8 p = psys__spring_par8(ks, kd, rest, h0);
    /* lane l takes lane l − o of this vector's forces, or lane 8 + l − o
     * of the last one's */
    const __m512i shift = _mm512_add_epi64(_mm512_set_epi64(7, 6, 5, 4, 3, 2, 1, 0), _mm512_set1_epi64(8 - (long long)o));
    S &= ~(size_t)7;
    __m512d gp[3] = {_mm512_setzero_pd(), _mm512_setzero_pd(), _mm512_setzero_pd()};
    for (size_t i = 0; i < endB; i += 8) {
        /* lanes [lo, hi) of this vector, as a mask */
#define LANES(lo, hi) \
    ((__mmask8)(((lo) >= i + 8 || (hi) <= i) ? 0u : ((0xffu << ((lo) > i ? (lo) - i : 0)) & (0xffu >> ((hi) >= i + 8 ? 0 : i + 8 - (hi))))))
        const __mmask8 mA = LANES(h0, endA), mB = LANES(h0 + o, endB), mf = mA | mB;
#undef LANES
        __m512d g[3];
        double *ra = r + i;
        if (mA == 0xff) {
            psys__spring_g8(ra, (ptrdiff_t)o, S, &p, i, mA, true, uni, d, g);
        } else {
            psys__spring_g8(ra, (ptrdiff_t)o, S, &p, i, mA, false, uni, d, g);
        }
        for (int c = 0; c < d; c++) {
            double *fa = ra + (size_t)(2 * d + c) * S;
            const __m512d sh = _mm512_permutex2var_pd(gp[c], shift, g[c]);
            if (mA == 0xff && mB == 0xff) {
                _mm512_store_pd(fa, _mm512_add_pd(_mm512_sub_pd(_mm512_load_pd(fa), g[c]), sh));
            } else {
                __m512d f = _mm512_maskz_load_pd(mf, fa);
                f = _mm512_mask_sub_pd(f, mA, f, g[c]);
                f = _mm512_mask_add_pd(f, mB, f, sh);
                _mm512_mask_store_pd(fa, mf, f);
            }
            gp[c] = g[c];
        }
        EXIT_STEP(q);
    }
}

__attribute__((target("avx512f"))) static void run_near_512(double *rb, size_t S, size_t a, size_t o,
                                                            const double *ks, const double *kd, const double *rest,
                                                            size_t len, bool uni, int d, exitq *q)
{
    if (d == 3) {
        if (uni)
            run_near_512_d(rb, S, a, o, ks, kd, rest, len, true, 3, q);
        else
            run_near_512_d(rb, S, a, o, ks, kd, rest, len, false, 3, q);
    } else {
        if (uni)
            run_near_512_d(rb, S, a, o, ks, kd, rest, len, true, 2, q);
        else
            run_near_512_d(rb, S, a, o, ks, kd, rest, len, false, 2, q);
    }
}

/* run_pair on AVX-512: eight springs to a vector from the line holding the
 * first end a, the first and last vectors masked, so a run has no scalar
 * head or tail (they took about a tenth of cloth-100's time). The
 * operations of run_pair_d on each spring, in the same order: the same
 * bits. Lanes outside the run load nothing and store nothing. */
__attribute__((target("avx512f"), always_inline)) static inline void
run_pair_512_d(double *rb, size_t S, size_t a, size_t b, const double *ks, const double *kd, const double *rest,
               size_t len, double *Fk, const bool uni, const bool apart, const int d, exitq *q)
{
    const size_t h0 = a & 7, end = h0 + len;
    const ptrdiff_t o = (ptrdiff_t)b - (ptrdiff_t)a;
    double *r = __builtin_assume_aligned((double *)psys__lanes_at(rb + a, -(ptrdiff_t)h0), 64); /* on a cache line */
    double *pf = (double *)psys__lanes_at(Fk, -(ptrdiff_t)h0);
    const spring_par8 p = psys__spring_par8(ks, kd, rest, h0);
    S &= ~(size_t)7;
    size_t i = 0;
    if (h0 || end < 8) {
        __mmask8 m = (__mmask8)(0xffu << h0);
        if (end < 8)
            m &= (__mmask8)((1u << end) - 1);
        spring8(r, o, S, &p, 0, pf, m, false, uni, apart, d);
        i = 8;
    }
    for (; i + 8 <= end; i += 8) {
        spring8(r + i, o, S, &p, i, pf + i, 0xff, true, uni, apart, d);
        EXIT_STEP(q);
    }
    if (i < end)
        spring8(r + i, o, S, &p, i, pf + i, (__mmask8)((1u << (end - i)) - 1), false, uni, apart, d);
}

/* run_pair_512_d with uni and apart as constants (d is one). */
__attribute__((target("avx512f"), always_inline)) static inline void
run_pair_512_c(double *rb, size_t S, size_t a, size_t b, const double *ks, const double *kd, const double *rest,
               size_t len, double *Fk, bool uni, bool apart, const int d, exitq *q)
{
    if (uni && apart)
        run_pair_512_d(rb, S, a, b, ks, kd, rest, len, Fk, true, true, d, q);
    else if (uni)
        run_pair_512_d(rb, S, a, b, ks, kd, rest, len, Fk, true, false, d, q);
    else if (apart)
        run_pair_512_d(rb, S, a, b, ks, kd, rest, len, Fk, false, true, d, q);
    else
        run_pair_512_d(rb, S, a, b, ks, kd, rest, len, Fk, false, false, d, q);
}

__attribute__((target("avx512f"))) static void run_pair_512(double *rb, size_t S, size_t a, size_t b,
                                                            const double *ks, const double *kd, const double *rest,
                                                            size_t len, double *Fk, bool uni, bool apart, int d, exitq *q)
{
    if (d == 3)
        run_pair_512_c(rb, S, a, b, ks, kd, rest, len, Fk, uni, apart, 3, q);
    else
        run_pair_512_c(rb, S, a, b, ks, kd, rest, len, Fk, uni, apart, 2, q);
}
#endif

/* run_pair_d with ks and kd read once where the run's springs share them,
 * the springs before the first whose first end starts a cache line apart:
 * from there on, a vector of first ends never straddles two lines (about
 * 0.9 × the time of cloth-100, bench/README.md). The same operations on
 * each spring. */
static FUSED_INLINE void run_pair(double *rb, size_t S, size_t a, size_t b, const double *ks, const double *kd,
                                  const double *rest, size_t len, double *Fk, bool uni, const bool apart, const int d,
                                  const bool k512, exitq *q)
{
#if SPRING_AVX512
    if (k512) {
        run_pair_512(rb, S, a, b, ks, kd, rest, len, Fk, uni, apart, d, q);
        return;
    }
#else
    (void)k512;
#endif
    (void)q;
    const size_t h = psys__springs_to_line(a, len);
    if (h) {
        if (uni)
            run_pair_d(rb, S, a, b, ks, kd, rest, h, Fk, apart, true, d, false);
        else
            run_pair_d(rb, S, a, b, ks, kd, rest, h, Fk, apart, false, d, false);
    }
    if (len > h) {
        if (uni)
            run_pair_d(rb, S, a + h, b + h, ks + h, kd + h, rest + h, len - h, Fk + h, apart, true, d, true);
        else
            run_pair_d(rb, S, a + h, b + h, ks + h, kd + h, rest + h, len - h, Fk + h, apart, false, d, true);
    }
}

/* Springs [c, e) of the run (lo, off, plan slot k): both ends in the loop
 * (e - c ≤ off, so no particle is both a first and a second end here), cut
 * where either end's range wraps around the ring. */
static FUSED_INLINE void run_piece_apart(const fused *fz, double *rb, size_t lo, size_t hi, size_t k, size_t c,
                                         size_t e, double *F, bool uni, const int d, const bool k512, exitq *q)
{
    const springs *s = fz->s;
    const size_t W = fz->W, mask = fz->mask;
    while (c < e) {
        const size_t pa = (lo + c) & mask, pb = (hi + c) & mask;
        size_t m = e - c;
        if (W - pa < m)
            m = W - pa;
        if (W - pb < m)
            m = W - pb;
        run_pair(rb, fz->S, pa, pb, s->pks + k + c, s->pkd + k + c, s->prest + k + c, m, F, uni, true, d, k512, q);
        c += m;
    }
}

/* How far past the particles it finishes a sweep can reach: every particle
 * of a run whose first end's block starts before upto lies before upto +
 * this − 2 (a block of 256 first ends, a run of at most 256). In the chain
 * (psys__fused_chain), the lag between stages. */
static size_t chain_reach(const springs *s) { return s->max_off + 2 * SPRING_BLOCK; }

/* A sweep of particles [P, Q) through runs [r0, r1) that can stop after
 * any particle and go on later: the window [done, loaded) and the next run
 * r are kept between calls. */
typedef struct sweep {
    size_t r, r1, P, Q, loaded, done;
} sweep;

/* A sweep of [P, Q) through runs [r0, r1), nothing done yet: the window
 * starts at the block of the first run touching [P, Q), or at P. */
static void sweep_start(const springs *s, sweep *w, size_t r0, size_t r1, size_t P, size_t Q)
{
    size_t start = P;
    for (size_t r = r0; r < r1; r++) {
        size_t lo = s->run_lo[r], hi = lo + s->run_off[r], len = s->run_len[r];
        if ((lo < Q && lo + len > P) || (hi < Q && hi + len > P)) {
            size_t b = lo & ~(size_t)(SPRING_BLOCK - 1);
            start = b < P ? b : P;
            break;
        }
    }
    *w = (sweep){.r = r0, .r1 = r1, .P = P, .Q = Q, .loaded = start, .done = start};
}

/* Go on with sweep w until every particle before `upto` (and in [P, Q))
 * has left the window: the runs whose block of first particles starts
 * before upto (no later run touches a particle before it). The window is
 * the same and each particle sees the same operations wherever a sweep
 * stops: the bits of one sweep from P to Q. */
static FUSED_INLINE void sweep_to_d(const fused *fz, double *rb, sweep *w, size_t upto, const int d,
                                    const bool k512, const bool hold)
{
    const springs *s = fz->s;
    const size_t W = fz->W, mask = fz->mask, S = fz->S, P = w->P, Q = w->Q;
    _Alignas(64) double F[3 * SPRING_BLOCK];
    size_t loaded = w->loaded, done = w->done, r = w->r;
    /* Leavings held back into the run loops (hold: holds_back) */
    exitq q = {fz, rb, 0, 0, 0}, *const qp = hold ? &q : NULL;
    size_t held = 0;
    /* The particles this sweep could need, [0, reach_end): the chain's stage
     * before has left them (its lag is chain_reach). */
    const size_t reach = chain_reach(s);
    const size_t reach_end = upto < fz->n && fz->n - upto > reach - 2 ? upto + reach - 2 : fz->n;
    /* Particles enter up to p, rounded up to whole granules where the window
     * and reach_end allow: each entry pays its loops' set-up and tails, and
     * a run asks for a few particles at a time. Entering earlier changes no
     * operation on a particle. The window's bound keeps entries off the
     * slots still in use (W past the first particle still in the window,
     * held back or not; a block's leavings are held back only where its
     * runs fit under it). reach_end binds (test_fused.chain_same_bits,
     * reach_edge). */
#define LOAD_TO(p)                                                          \
    if (loaded < (p)) {                                                     \
        size_t t_ = ((p) + FUSED_ENTER - 1) & ~(size_t)(FUSED_ENTER - 1);   \
        const size_t first_ = hold && q.lo < q.hi ? q.lo : done;            \
        if (t_ > first_ + W)                                                \
            t_ = first_ + W;                                                \
        if (t_ > reach_end)                                                 \
            t_ = reach_end;                                                 \
        if (t_ < (p))                                                       \
            t_ = (p);                                                       \
        while (loaded < t_) {                                               \
            const size_t u_ = window_piece_end(fz, loaded, t_);             \
            window_move(fz, rb, loaded, u_ - loaded, d, true);              \
            loaded = u_;                                                    \
        }                                                                   \
    }
#define LEAVE_TO(p)                                                         \
    while (done < (p)) {                                                    \
        const size_t e_ = window_piece_end(fz, done, (p));                  \
        LOAD_TO(e_)                                                         \
        size_t a_ = done > P ? done : P, z_ = e_ < Q ? e_ : Q;              \
        if (a_ < z_)                                                        \
            window_move(fz, rb, a_, z_ - a_, d, false);                     \
        done = e_;                                                          \
    }
    for (; r < w->r1; r++) {
        const size_t lo = s->run_lo[r], hi = lo + s->run_off[r], len = s->run_len[r], k = s->run_k[r];
        /* Runs come in blocks of first particle: nothing before this block
         * receives any more forces. */
        const size_t b = lo & ~(size_t)(SPRING_BLOCK - 1);
        if (b >= upto)
            break;
        if (!((lo < Q && lo + len > P) || (hi < Q && hi + len > P)))
            continue;
        if (hold && b > done) {
            /* Hold back the solver's work on [done, b) (exitq): the block's
             * runs touch nothing before b, and b < Q (this run touches
             * [P, Q) from at or after b). */
            exit_flush(&q);
            const size_t lo_ = done > P ? done : P, A = (lo_ + 7) & ~(size_t)7;
            size_t need = b; /* the block's runs reach particles before need */
            for (size_t r2 = r; r2 < w->r1 && (s->run_lo[r2] & ~(size_t)(SPRING_BLOCK - 1)) == b; r2++) {
                const size_t e2 = s->run_lo[r2] + s->run_off[r2] + s->run_len[r2];
                need = e2 > need ? e2 : need;
            }
            /* an octet across a stage ring's edge would take two kinds of
             * storage (state_at, next_at) */
            const bool cut = (fz->in_ring || fz->out_ring)
                             && ((fz->zlo > A && fz->zlo < b && (fz->zlo & 7)) || (fz->zhi > A && fz->zhi < b && (fz->zhi & 7)));
            /* what the block's runs enter must not reach the held-back slots */
            if (b - done <= SPRING_BLOCK && A < b && need <= A + W && !cut) {
                LOAD_TO(b)
                if (lo_ < A) /* the first octet's tail, in one ring piece */
                    window_move(fz, rb, lo_, A - lo_, d, false);
                for (size_t a_ = A; a_ < b;) {
                    const size_t e_ = window_piece_end(fz, a_, b);
                    leave_post(fz, rb, a_, e_ - a_, d);
                    a_ = e_;
                }
                q.lo = A;
                q.hi = b;
                done = b;
                held++;
            }
        }
        LEAVE_TO(b)
        LOAD_TO(hi + len)
        if (len < SPRING_SHORT) {
            run_short(rb, rb + (size_t)d * S, rb + (size_t)(2 * d) * S, S, mask, lo, hi, s->pks + k, s->pkd + k,
                      s->prest + k, len, 0, len, 0, len, d);
            continue;
        }
        const size_t off = hi - lo;
        const bool uni = s->run_uni[r];
        if (off >= len) {
            /* the two ranges are apart: both ends in one loop */
            run_piece_apart(fz, rb, lo, hi, k, 0, len, F, uni, d, k512, qp);
            continue;
        }
        if (off >= FUSED_CHUNK_MIN) {
            /* Overlapping ranges, long offset: chunks of at most off springs
             * from the last back to the first, both ends in the loop. A
             * particle that is a second end (spring j) and a first end
             * (spring j + off ≥ the chunk's end) gets its first-end force
             * in an earlier chunk, as in the plan order (all first ends,
             * then all second ends). */
            for (size_t e = len; e > 0;) {
                const size_t c = e > off ? e - off : 0;
                run_piece_apart(fz, rb, lo, hi, k, c, e, F, uni, d, k512, qp);
                e = c;
            }
            continue;
        }
        /* Short offsets (1, 2: a row's neighbours): the first ends in the
         * loop, the forces kept for a second loop over the second ends. The
         * run's ends in the ring, cut where either wraps around. */
        const size_t ia = lo & mask, ib = hi & mask;
#if SPRING_AVX512
        if (k512 && ib == ia + off && ib + len <= W) { /* neither range wraps around the ring */
            run_near_512(rb, S, ia, off, s->pks + k, s->pkd + k, s->prest + k, len, uni, d, qp);
            continue;
        }
#endif
        const size_t ja = W - ia < len ? W - ia : len, jb = W - ib < len ? W - ib : len;
        const size_t cut[4] = {0, ja < jb ? ja : jb, ja < jb ? jb : ja, len};
        for (int p = 0; p < 3; p++)
            if (cut[p] < cut[p + 1]) {
                const size_t j0 = cut[p];
                const size_t pa = (lo + j0) & mask, pb = (hi + j0) & mask, m = cut[p + 1] - j0;
                run_pair(rb, S, pa, pb, s->pks + k + j0, s->pkd + k + j0, s->prest + k + j0, m, F + j0, uni, false,
                         d, k512, qp);
            }
        for (int c = 0; c < d; c++) {
            double *restrict Fr = rb + (size_t)(2 * d + c) * S;
            const double *restrict Fc = F + c * SPRING_BLOCK;
            for (size_t j = 0; j < jb; j++)
                Fr[ib + j] += Fc[j];
            for (size_t j = jb; j < len; j++)
                Fr[j - jb] += Fc[j];
        }
    }
    if (hold) {
        exit_flush(&q);
        note_nonfinite(fz, q.bits);
        if (held)
            atomic_fetch_add_explicit(fz->held, held, memory_order_relaxed);
    }
    const size_t end = upto < Q ? upto : Q;
    LEAVE_TO(end)
#undef LOAD_TO
#undef LEAVE_TO
    w->loaded = loaded;
    w->done = done;
    w->r = r;
}

SPRING_CLONES
static void fused_sweep_plain(const fused *fz, int d, double *rb, sweep *w, size_t upto)
{
    if (d == 2)
        sweep_to_d(fz, rb, w, upto, 2, false, false);
    else
        sweep_to_d(fz, rb, w, upto, 3, false, false);
}

#if SPRING_AVX512
__attribute__((target("avx512f"), flatten)) static void fused_sweep_512(const fused *fz, int d, double *rb, sweep *w,
                                                                      size_t upto)
{
    if (d == 2)
        sweep_to_d(fz, rb, w, upto, 2, true, false);
    else
        sweep_to_d(fz, rb, w, upto, 3, true, false);
}

/* Whether a 3-D sweep on the AVX-512 loops holds leavings back (exitq):
 * with the solver's pass, the particles in their own order, no planes, a
 * large system (FUSED_HOLD_MIN). */
static bool holds_back(const fused *fz)
{
    return fz->pass && !fz->perm && !fz->planes && (fz->n >= FUSED_HOLD_MIN || fz->forced);
}

/* fused_sweep_512 holding leavings back (holds_back), 3-D: a function of
 * its own, so that the loops that do not hold back stay as they were
 * (cloth-100, never held back, was slower with both in one function). */
__attribute__((target("avx512f"), flatten)) static void fused_sweep_512_held(const fused *fz, double *rb, sweep *w,
                                                                           size_t upto)
{
    sweep_to_d(fz, rb, w, upto, 3, true, true);
}
#endif

static void fused_sweep(const fused *fz, int d, double *rb, sweep *w, size_t upto)
{
#if SPRING_AVX512
    if (fz->k512) {
        if (d == 3 && holds_back(fz))
            fused_sweep_512_held(fz, rb, w, upto);
        else
            fused_sweep_512(fz, d, rb, w, upto);
        return;
    }
#endif
    fused_sweep_plain(fz, d, rb, w, upto);
}

/* Particles [P, Q) through runs [r0, r1) in one sweep. */
static void fused_part(const fused *fz, int d, double *rb, size_t r0, size_t r1, size_t P, size_t Q)
{
    sweep w;
    sweep_start(fz->s, &w, r0, r1, P, Q);
    fused_sweep(fz, d, rb, &w, Q);
}

/* fz (its forces from eligible()) over sys's springs, windows and
 * particles: the state y, and either ydot or the solver's pass. */
static void fused_bind(fused *fz, const psys_system *sys, const double *x, const double *v, double *ydot,
                       const psys__stage_pass *pass, atomic_int *nonfinite)
{
    const springs *s = sys->springs;
    const size_t nd = sys->n * (size_t)sys->dim;
    fz->s = s;
    fz->n = sys->n;
    fz->W = s->ring_w;
    fz->mask = s->ring_w - 1;
    fz->S = psys__springs_ring_stride(s->ring_w);
    fz->x = x;
    fz->v = v;
    fz->mass = sys->mass;
    fz->inv_mass = sys->inv_mass;
    fz->perm = s->perm;
    if (sys->ode_perm) { /* y, ydot and the pass already in slot order (psys__state_order_begin) */
        fz->mass = sys->ode_mass;
        fz->inv_mass = sys->ode_inv_mass;
        fz->perm = NULL;
    }
    fz->xdot = ydot;
    fz->vdot = ydot ? ydot + nd : NULL;
    fz->pass = pass;
    /* base NULL: the chain from the system's own state (psys__fused_chain) */
    fz->base[0] = pass && pass->base ? pass->base : sys->x;
    fz->base[1] = pass && pass->base ? pass->base + nd : sys->v;
    fz->nonfinite = nonfinite;
    fz->held = &((springs *)sys->springs)->held;
    fz->put[0] = fz->put[1] = NULL;
    fz->nd = nd;
    fz->in_ring = NULL;
    fz->out_ring = NULL;
    fz->rmask = fz->rd = fz->zlo = fz->zhi = 0;
    fz->planes = sys->nplanes ? sys : NULL;
}

/* Answers the passes that asked (psys__stage_pass.finite) once their sweeps
 * are done: whether all they wrote to acc was finite (nonfinite unset).
 * Controlled particles: not answered, since the solver's projection of the
 * result may change it. */
static void answer_finite(const psys_system *sys, const psys__stage_pass *pass, int stages, atomic_int *nonfinite)
{
    for (int i = 0; pass && i < stages; i++)
        if (pass[i].finite && pass[i].acc && sys->nctrl == 0)
            *pass[i].finite = atomic_load_explicit(nonfinite, memory_order_relaxed) == 0;
}

bool psys__fused_eligible(const psys_system *sys)
{
    fused fz;
    return eligible(sys, &fz);
}

psys_status psys__fused_derivative(psys_system *sys, const psys_force_eval *e, const double *y, double *ydot,
                                   const psys__stage_pass *pass, bool *used)
{
    fused fz;
    *used = false;
    if (!eligible(sys, &fz))
        return PSYS_OK;
    springs *s = sys->springs;
    const size_t n = sys->n, nd = n * (size_t)sys->dim;
    int T = e->threads < 1 ? 1 : e->threads > SPRING_MAX_THREADS ? SPRING_MAX_THREADS : e->threads;
    /* Small sets run on one thread, unless the fused path is forced: then
     * at the evaluation's thread count, so tests reach every thread path. */
    if (s->n < SPRING_PARALLEL_MIN && nd < PSYS_PAR_MIN && !fz.forced)
        T = 1;
    psys_status st = psys__springs_prepare_fused(s, n, &T);
    if (st != PSYS_OK)
        return st;
    const double *rest = psys__springs_rest_now(s, e->t);
    for (size_t m = 0; m < s->nm; m++)
        s->prest[s->pos[s->midx[m]]] = rest[s->midx[m]];
    atomic_int nonfinite = 0;
    fused_bind(&fz, sys, y, y + nd, ydot, pass, &nonfinite);
    const size_t ring = 9 * fz.S;
    if (T <= 1) {
        fused_part(&fz, sys->dim, s->ring, 0, s->nruns, 0, n);
    } else {
#ifdef _OPENMP
#pragma omp parallel for schedule(static, 1) num_threads(T)
#endif
        for (int t = 0; t < T; t++)
            fused_part(&fz, sys->dim, s->ring + (size_t)t * ring, s->rlo[t], s->rhi[t], psys__part_first(n, T, t),
                       psys__part_first(n, T, t + 1));
    }
    answer_finite(sys, pass, 1, &nonfinite);
    *used = true;
    return PSYS_OK;
}

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

#define CHAIN_MAX_STAGES 7
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
    sweep_start(s, w, r0, r1, P, Q);
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
                fused_sweep(&fz[i], d, rings + (size_t)i * ring, &w[i], target);
        }
        if (finished)
            return;
    }
}

/* By default the chain runs when the springs reach at most this many
 * particles (ropes, chains, strips of a few dozen columns): there the
 * stages' span stays in L2 and the sweep was faster (bench/README.md:
 * rope-10⁶ rk4 0.81 and 0.87 × the time of stage by stage on 1 thread,
 * 0.83 and 0.90 × on 2). Cloths (bend springs two rows long: reach 712 at
 * 100 columns, 1,024 at 256) reach further: see chain_timed.
 * PSYS_CHAIN=1 runs it whenever it can (tests), 0 never. */
#define CHAIN_AUTO_REACH 600

/* Beyond that reach the two were measured either way round on different
 * hosts (cloth-1024 rk4, bench/README.md: the chain 1.02-1.05 × the time of
 * stage by stage on an Intel host, 0.58-0.72 × on an AMD one), so there
 * each system's first steps time both, alternating, CHAIN_TRIALS steps of
 * each, and the mode whose fastest step was faster stays. A step's time
 * runs from the solver asking whether the chain takes it to the next
 * step's asking; the fastest of several leaves out a first step's set-up
 * and the caller's work between steps. The same bits either way. */
#define CHAIN_TRIALS 3

/* Seconds on a clock that does not jump where there is one (POSIX). */
static double chain_clock(void)
{
    struct timespec ts;
#ifdef CLOCK_MONOTONIC
    clock_gettime(CLOCK_MONOTONIC, &ts);
#else
    timespec_get(&ts, TIME_UTC);
#endif
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

/* The mode of the step the solver is asking about (1: the chain), by
 * timing: at each asking, the step before it is timed. */
static int chain_timed(psys_system *sys, springs *s)
{
    const int T = psys_system_effective_threads(sys);
    const double now = chain_clock();
    if (!s->chain.keyed || s->chain.plan != s->plan_version || s->chain.n != sys->n || s->chain.T != T) {
        s->chain.keyed = true;
        s->chain.plan = s->plan_version;
        s->chain.n = sys->n;
        s->chain.T = T;
        s->chain.pick = -1;
        s->chain.mode = -1;
        s->chain.steps = 0;
        s->chain.best[0] = s->chain.best[1] = INFINITY;
    }
    if (s->chain.pick < 0 && s->chain.mode >= 0) {
        const double dt = now - s->chain.t;
        if (dt >= 0 && dt < s->chain.best[s->chain.mode])
            s->chain.best[s->chain.mode] = dt;
        if (++s->chain.steps == 2 * CHAIN_TRIALS)
            s->chain.pick = s->chain.best[1] < s->chain.best[0];
    }
    s->chain.mode = s->chain.pick >= 0 ? s->chain.pick : s->chain.steps % 2 == 0;
    s->chain.t = now;
    return s->chain.mode;
}

/* Whether the chain takes sys for `stages` stages; fz gets its forces.
 * ask: the solver asks before a step (the timed choice advances); else the
 * step itself, which follows the answer given. */
static bool chain_takes(psys_system *sys, int stages, fused *fz, bool ask)
{
    if (stages < 2 || stages > CHAIN_MAX_STAGES || sys->nctrl || !eligible(sys, fz))
        return false;
    springs *s = sys->springs;
    const char *env = getenv("PSYS_CHAIN");
    if ((env && env[0] == '0') || s->nm != 0)
        return false;
    if (env && env[0] == '1')
        return true;
    /* the plan's reach (an allocation failure: no, and the stage path reports it) */
    if (psys__springs_prepare_rings(s, sys->n, 1) != PSYS_OK)
        return false;
    if (chain_reach(s) <= CHAIN_AUTO_REACH)
        return true;
    return ask ? chain_timed(sys, s) == 1 : s->chain.mode == 1;
}

bool psys__fused_chain_eligible(psys_system *sys, int stages)
{
    fused fz;
    return chain_takes(sys, stages, &fz, true);
}

size_t psys__fused_held(const psys_system *sys)
{
    springs *s = sys->springs;
    return s ? atomic_load_explicit(&s->held, memory_order_relaxed) : 0;
}

int psys__fused_chain_pick(const psys_system *sys)
{
    const springs *s = sys->springs;
    return s && s->chain.keyed ? s->chain.pick : -1;
}

bool psys__system_timing_settled(const psys_system *sys)
{
    const springs *s = sys->springs;
    /* timing started (a mode under way) and not yet decided */
    return !s || !s->chain.keyed || s->chain.pick >= 0 || s->chain.mode < 0;
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
    if (!chain_takes(sys, stages, &fz[0], false))
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
        fused_bind(&fz[i], sys, y ? y : sys->x, y ? y + nd : sys->v, NULL, &pass[i], &nonfinite);
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
                fused_sweep(&fz[i], sys->dim, rings, &w, P + (size_t)i * reach);
            }
        }
#endif
    }
    answer_finite(sys, pass, stages, &nonfinite);
    if (in_place)
        *fin->in_place = 1;
    *used = true;
    return PSYS_OK;
}

/* ---- The solver's state in the springs' internal order
 *
 * With the state itself in slot order (psys__state_order_begin), the
 * window reads and writes it as it does a mesh numbered in rows: streams
 * instead of a gather and a scatter across the whole state per particle
 * and stage. The state moves between the two orders once per step (the
 * solver's get_state and commit) instead of at every stage. */

const uint32_t *psys__fused_order(psys_system *sys, size_t *perm_n, unsigned *plan)
{
    fused fz;
    if (!eligible(sys, &fz) || psys__springs_prepare_rings(sys->springs, sys->n, 1) != PSYS_OK)
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
