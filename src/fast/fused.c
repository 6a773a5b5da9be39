/* The fused derivative: eligibility, the window that particles enter and
 * leave, the sweep through the spring runs, and the derivative's driver.
 * The window, the sweep and the kernels of fused_kernels.h are one
 * translation unit because they inline into each other in every clone of
 * the sweep; the chain (chain.c) calls a sweep at a time. */

/* The derivative [v | f/m] of a system whose forces are its springs and
 * per-particle forces (PSYS_FORCE_PER_PARTICLE with apply_rows), in one
 * pass over memory instead of one per force object plus copies.
 *
 * The generic derivative clears f, lets each force object sweep it, copies
 * x, v and f into component arrays for the spring runs and back, copies v
 * and forms f/m: about ten sweeps over arrays that at 10⁶ particles live in
 * main memory. Here a window of ring_w consecutive particles slides along
 * the plan (forces/spring.c): particles enter it (x, v into component rows,
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
#include "fast/fused.h"
#include "fast/fused_kernels.h"

#include <math.h>
#include <stdatomic.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#ifdef _OPENMP
#include <omp.h>
#endif

/* Overlapping runs with an offset of at least this many springs go in
 * reverse chunks (fused_part_d), shorter ones through a second loop. */
#define FUSED_CHUNK_MIN 8
/* Particles enter the window in granules of this many (a power of 2;
 * sweep_to_d). */
#define FUSED_ENTER 64
/* Leavings are held back into the run loops (exitq) for systems of at
 * least this many particles, whose solver's vectors stream from beyond L2:
 * there it was faster, on small cloths slower (bench/README.md, "Held-back
 * leavings"; figures in bench/HISTORY.md). */
#define FUSED_HOLD_MIN 32768

/* The row kernel of force class cls, or NULL: the fused path takes the
 * per-particle forces that have one. */
static rows_fn rows_of(const psys_force_class *cls)
{
    return (cls->traits & PSYS_FORCE_PER_PARTICLE) ? cls->apply_rows : NULL;
}

/* The fused path runs whenever a system is eligible: it was not slower
 * than the generic one at any size measured, and mostly faster, even in
 * cache (bench/README.md; figures in bench/HISTORY.md).
 * PSYS_FUSED=0 turns it off; PSYS_FUSED=1 also runs small sets on all the
 * evaluation's threads (tests, benchmarks). */

/* Whether the fused path computes s's derivative: springs, and otherwise
 * only forces with row kernels (at most FUSED_MAX_ROWS on each side of the
 * springs), then the planes' contact forces, which need each particle's
 * total force (psys__contact_rows, as a particle leaves the window); no
 * MPI decomposition. */
bool psys__fused_takes(const psys_system *s, fused *fz)
{
    if (!s->springs || psys__springs_count(s->springs) == 0 || s->dist || s->own_mark || s->n == 0)
        return false;
    /* the planes take particles by their own index (psys__state_order_begin
     * declines systems with planes, so this does not happen) */
    if (s->nplanes && s->ode_perm)
        return false;
    if (s->sw.fused == '0')
        return false;
    fz->forced = s->sw.fused == '1';
    fz->k512 = psys__springs_avx512(s);
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

/* A sweep of [P, Q) through runs [r0, r1), nothing done yet: the window
 * starts at the block of the first run touching [P, Q), or at P. */
void psys__fused_sweep_start(const springs *s, sweep *w, size_t r0, size_t r1, size_t P, size_t Q)
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
 * (with both in one function those were slower: bench/HISTORY.md). */
__attribute__((target("avx512f"), flatten)) static void fused_sweep_512_held(const fused *fz, double *rb, sweep *w,
                                                                           size_t upto)
{
    sweep_to_d(fz, rb, w, upto, 3, true, true);
}
#endif

void psys__fused_sweep(const fused *fz, int d, double *rb, sweep *w, size_t upto)
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
    psys__fused_sweep_start(fz->s, &w, r0, r1, P, Q);
    psys__fused_sweep(fz, d, rb, &w, Q);
}

/* fz (its forces from psys__fused_takes()) over sys's springs, windows and
 * particles: the state y, and either ydot or the solver's pass. */
void psys__fused_bind(fused *fz, const psys_system *sys, const double *x, const double *v, double *ydot,
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
void psys__fused_answer_finite(const psys_system *sys, const psys__stage_pass *pass, int stages,
                               atomic_int *nonfinite)
{
    for (int i = 0; pass && i < stages; i++)
        if (pass[i].finite && pass[i].acc && sys->nctrl == 0)
            *pass[i].finite = atomic_load_explicit(nonfinite, memory_order_relaxed) == 0;
}

bool psys__fused_eligible(const psys_system *sys)
{
    fused fz;
    return psys__fused_takes(sys, &fz);
}

psys_status psys__fused_derivative(psys_system *sys, const psys_force_eval *e, const double *y, double *ydot,
                                   const psys__stage_pass *pass, bool *used)
{
    fused fz;
    *used = false;
    if (!psys__fused_takes(sys, &fz))
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
    psys__fused_bind(&fz, sys, y, y + nd, ydot, pass, &nonfinite);
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
    psys__fused_answer_finite(sys, pass, 1, &nonfinite);
    *used = true;
    return PSYS_OK;
}

size_t psys__fused_held(const psys_system *sys)
{
    springs *s = sys->springs;
    return s ? atomic_load_explicit(&s->held, memory_order_relaxed) : 0;
}
