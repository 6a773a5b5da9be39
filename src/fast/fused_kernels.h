/* The inner loops of the fused sweep: the solver's stage work on leaving
 * particles, the spring runs on the window's rows, and their AVX-512 forms.
 * Static always-inline functions in a header that fused.c alone includes,
 * so that they inline into each instruction-set clone of its sweep
 * (SPRING_CLONES, fused_sweep_512) as they did when all were one file. */
#ifndef PSYS_FAST_FUSED_KERNELS_H
#define PSYS_FAST_FUSED_KERNELS_H

#include "fast/fused.h"

#include <stdatomic.h>
#include <stdint.h>

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
 * head or tail (those took a sizeable share of a cloth's time:
 * bench/HISTORY.md). The operations of run_pair_d on each spring, in the
 * same order: the same bits. Lanes outside the run load nothing and store
 * nothing. */
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
 * from there on, a vector of first ends never straddles two lines (faster:
 * bench/README.md; figures in bench/HISTORY.md). The same operations on
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

#endif
