/* Grid pair forces four rows at a time (AVX2 with FMA): the lanes of a
 * vector are four rows i, each walking its own neighbour list: consecutive
 * particles, or consecutive slots of the grid's cell order where the
 * particles' numbering is not local (psys__pair_group_lists), so that a
 * group's rows are near each other in space either way.
 *
 * Why: the row kernel (pair_row_forces) vectorises over a particle's
 * partners and then adds their forces one after another, a chain of additions
 * as long as the list, and GCC loads the partners one by one there. Here each
 * lane adds its own partners' forces in its own list order, so the four
 * chains run side by side, and each partner comes in as one 32-byte record
 * (x, y, z, 0) of a copy of the positions, four of them transposed into
 * vectors (cheaper than gathers; bench/HISTORY.md).
 *
 * Same bits: per lane, the operations of pair_row_terms and pair_kernel in
 * the same order (the fused multiply-adds of pair_force_r2 and of the sums,
 * division and square root correctly rounded), and the same sum in list
 * order starting from +0. Lanes whose list has ended keep their sums.
 * Groups in which some |x_i - x_j| reaches 1.5 box lengths on a periodic
 * axis are computed again by pair_row_forces (the exact minimum image); so
 * are the last n mod 4 rows.
 *
 * Lists: a copy of the grid's full lists interleaved by group (entry k of
 * the group's rows side by side, psys__pair_group_lists), made after each
 * build: the loop then reads one stream of indices instead of one per row,
 * which is faster (bench/HISTORY.md).
 * A row shorter than its group's longest is padded with its own index, a
 * partner masked out.
 *
 * Partial evaluations (the rows a wrap or a small move changed, a few per
 * group of consecutive rows) take the marked rows eight at a time wherever
 * they lie, with their lists interleaved on the fly (group8_sparse): cheaper
 * than every group of eight consecutive rows that holds one (bench/HISTORY.md). */
#include "pair/pair.h"

#include <stddef.h>
#include <stdlib.h>
#include <string.h>

#if (defined(__GNUC__) || defined(__clang__)) && defined(__x86_64__)
#define PSYS_GROUP_AVX2 1
#endif

#define GROUP 4
#define GROUP_MAX 8 /* lanes of the widest loop (AVX-512) */
#define GROUP_CHUNK 16 /* groups per parallel task */
#define GROUP_N_MAX ((size_t)1 << 30) /* the lists hold 4·j, the offset of j's record in Q */

/* The row of group slot t (psys__pair_group_lists): particle t, or the
 * particle in slot t of the cell order. */
static inline size_t group_row(const pair_grid *g, size_t t) { return g->gl_cells ? g->cell_list[t] : t; }

#if defined(PSYS_GROUP_AVX2)
#include <immintrin.h>

static bool group_wanted(const pair_force *p)
{
    /* PSYS_GROUP_OFF in the environment forces the row kernel, so the tests
     * cover both paths on any machine */
    return (p->law == PSYS_PAIR_LENNARD_JONES || p->law == PSYS_PAIR_SOFT_REPULSION)
           && __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma") && !p->sys->sw.group_off;
}

#define AVX2 __attribute__((target("avx2,fma")))

/* Row i through pair_row_forces (the exact minimum image), stored into out;
 * the law as a constant, as the group loop supports it. Built for AVX2 with
 * FMA like the loops (it runs only where they do), so the fused
 * multiply-adds are instructions. */
AVX2 static void group_row_alone(const pair_force *p, const pair_image *m, const double *w, size_t i, double *out)
{
    const pair_grid *g = &p->grid;
    const int d = p->dim;
    double a[3] = {0, 0, 0};
    if (p->law == PSYS_PAIR_LENNARD_JONES)
        pair_row_forces(p, PSYS_PAIR_LENNARD_JONES, d, m, w, i, g->nb + g->nb_start[i], 0, g->nb_num[i], true, a);
    else
        pair_row_forces(p, PSYS_PAIR_SOFT_REPULSION, d, m, w, i, g->nb + g->nb_start[i], 0, g->nb_num[i], true, a);
    for (int k = 0; k < d; k++)
        out[i * (size_t)d + (size_t)k] = a[k];
}

/* The loops' constants, one vector of equal lanes each (V: __m256d or
 * __m512d); the eight-lane set is the four-lane one widened (group8_consts_of). */
#define GROUP_CONST_FIELDS(V) V hl[3], ln[3], fr[3], sign, rc2, rcbits, zero, one, two, sig2, lj24, kc, radius
#define GROUP_NCONST 19

typedef struct group_consts {
    union {
        struct {
            GROUP_CONST_FIELDS(__m256d);
        };
        __m256d v[GROUP_NCONST];
    };
    double inlo[3], inhi[3]; /* group_near's bounds (±inf on free axes) */
} group_consts;
_Static_assert(offsetof(group_consts, radius) == (GROUP_NCONST - 1) * sizeof(__m256d), "GROUP_NCONST");

/* One axis: e = x_i - x_j, then the one-box minimum image of
 * pair_delta_folded (exact false); with flag, *far flags |e| >= 1.5 boxes
 * (without, the caller knows no |e| gets there: the GROUP_AXES modes). */
AVX2 static inline __m256d group_delta(const group_consts *c, int k, __m256d e, __m256d *far, const bool flag)
{
    const __m256d a = _mm256_andnot_pd(c->sign, e);
    const __m256d near = _mm256_sub_pd(e, _mm256_or_pd(c->ln[k], _mm256_and_pd(c->sign, e)));
    if (flag)
        *far = _mm256_or_pd(*far, _mm256_cmp_pd(a, c->fr[k], _CMP_GE_OQ));
    return _mm256_blendv_pd(e, near, _mm256_cmp_pd(a, c->hl[k], _CMP_GT_OQ));
}

/* pair_kernel's g for lennard-jones or soft-repulsion (forces only). */
AVX2 static inline __m256d group_kernel(const group_consts *c, const int law, __m256d r2)
{
    const __m256d in = _mm256_and_pd(_mm256_cmp_pd(r2, c->rc2, _CMP_LT_OQ), _mm256_cmp_pd(r2, c->zero, _CMP_GT_OQ));
    const __m256d safe = _mm256_blendv_pd(c->one, r2, in);
    __m256d g;
    if (law == PSYS_PAIR_LENNARD_JONES) {
        const __m256d ir2 = _mm256_div_pd(c->one, safe), s2 = _mm256_mul_pd(c->sig2, ir2);
        const __m256d s6 = _mm256_mul_pd(_mm256_mul_pd(s2, s2), s2);
        g = _mm256_mul_pd(_mm256_mul_pd(_mm256_mul_pd(c->lj24, s6), _mm256_sub_pd(_mm256_mul_pd(c->two, s6), c->one)),
                          ir2);
    } else {
        const __m256d r = _mm256_sqrt_pd(safe), dr = _mm256_sub_pd(c->radius, r);
        g = _mm256_div_pd(_mm256_mul_pd(c->kc, dr), r);
    }
    return _mm256_and_pd(g, in);
}

/* How group_rows treats x_i - x_j: as it is (no periodic axis); as it is,
 * flagging any |x_i - x_j| above half a box on a periodic axis (then the
 * minimum image would have changed something); or through the one-box
 * minimum image, flagging |x_i - x_j| of 1.5 boxes or more. */
enum { GROUP_PLAIN, GROUP_CHECK, GROUP_IMAGE, GROUP_AXES };
/* GROUP_AXES + mask (mask 1 to 7): the minimum image on the axes of mask
 * only, the others as they are, nothing flagged: only when every position
 * lies in the box (see psys__pair_group_forces for when that is exact and
 * why no difference then reaches 1.5 boxes). */
#define GROUP_IMAGES(mode, k) ((mode) == GROUP_IMAGE || ((mode) >= GROUP_AXES && (((mode) - GROUP_AXES) >> (k)) & 1))

/* One group's inputs: the positions as records (Q), its interleaved lists
 * and its rows' list lengths. */
typedef struct group_in {
    const double *Q;
    const uint32_t *il;  /* entry k of lane l at il[k·width + l], as 4·j (Q + il[.] is j's record) */
    const uint32_t *num; /* the rows' list lengths */
    uint32_t len;        /* the longest */
    size_t i0;           /* the first row, lane l being row i0 + l, unless row is set */
    const uint32_t *row; /* or lane l is row row[l] (a group in the grid's cell order) */
    /* eight rows with their lists interleaved on the fly instead (group8_rows
     * only, with row; il unused): their lists (ascending j, as in pair_grid.nb) */
    const uint32_t *const *lst;
} group_in;

/* Rows i0..i0+3 into s (s[k][l]: component k of row i0+l). True if a
 * difference was flagged (see the modes): the caller computes the group
 * again the next way up. */
AVX2 __attribute__((always_inline)) static inline bool group_rows(const group_consts *c, const int law, const int d,
                                                                  const int mode, const group_in *in,
                                                                  double s[3][GROUP_MAX])
{
    const size_t i0 = in->i0;
    const double *Q = in->Q;
    size_t own[GROUP];
    for (int l = 0; l < GROUP; l++)
        own[l] = in->row ? in->row[l] : i0 + (size_t)l;
    /* the rows' own records, transposed */
    const __m256d r0 = _mm256_load_pd(Q + 4 * own[0]), r1 = _mm256_load_pd(Q + 4 * own[1]);
    const __m256d r2_ = _mm256_load_pd(Q + 4 * own[2]), r3 = _mm256_load_pd(Q + 4 * own[3]);
    const __m256d v0 = _mm256_unpacklo_pd(r0, r1), v1 = _mm256_unpackhi_pd(r0, r1);
    const __m256d v2 = _mm256_unpacklo_pd(r2_, r3), v3 = _mm256_unpackhi_pd(r2_, r3);
    const __m256d xi0 = _mm256_permute2f128_pd(v0, v2, 0x20), xi1 = _mm256_permute2f128_pd(v1, v3, 0x20);
    const __m256d xi2 = d == 3 ? _mm256_permute2f128_pd(v0, v2, 0x31) : c->zero;
    __m256d a0 = c->zero, a1 = c->zero, a2 = c->zero, far = c->zero;
    const uint32_t *n = in->num, len = in->len;
    const uint32_t lo01 = n[0] < n[1] ? n[0] : n[1], lo23 = n[2] < n[3] ? n[2] : n[3];
    const uint32_t full = lo01 < lo23 ? lo01 : lo23;
    const __m128i num = _mm_loadu_si128((const __m128i *)n);
    for (uint32_t k = 0; k < len; k++) {
        const uint32_t *j = in->il + (size_t)GROUP * k;
        /* the four partners' records (x, y, z, 0), transposed: one load per
         * partner beats three gathers (bench/HISTORY.md) */
        const __m256d p0 = _mm256_load_pd(Q + j[0]), p1 = _mm256_load_pd(Q + j[1]);
        const __m256d p2 = _mm256_load_pd(Q + j[2]), p3 = _mm256_load_pd(Q + j[3]);
        const __m256d u0 = _mm256_unpacklo_pd(p0, p1), u1 = _mm256_unpackhi_pd(p0, p1);
        const __m256d u2 = _mm256_unpacklo_pd(p2, p3), u3 = _mm256_unpackhi_pd(p2, p3);
        __m256d e0 = _mm256_sub_pd(xi0, _mm256_permute2f128_pd(u0, u2, 0x20));
        __m256d e1 = _mm256_sub_pd(xi1, _mm256_permute2f128_pd(u1, u3, 0x20));
        __m256d e2 = c->zero;
        if (d == 3)
            e2 = _mm256_sub_pd(xi2, _mm256_permute2f128_pd(u0, u2, 0x31));
        if (mode >= GROUP_IMAGE) {
            if (GROUP_IMAGES(mode, 0))
                e0 = group_delta(c, 0, e0, &far, mode == GROUP_IMAGE);
            if (GROUP_IMAGES(mode, 1))
                e1 = group_delta(c, 1, e1, &far, mode == GROUP_IMAGE);
            if (d == 3 && GROUP_IMAGES(mode, 2))
                e2 = group_delta(c, 2, e2, &far, mode == GROUP_IMAGE);
        } else if (mode == GROUP_CHECK) {
            far = _mm256_or_pd(far, _mm256_cmp_pd(_mm256_andnot_pd(c->sign, e0), c->hl[0], _CMP_GT_OQ));
            far = _mm256_or_pd(far, _mm256_cmp_pd(_mm256_andnot_pd(c->sign, e1), c->hl[1], _CMP_GT_OQ));
            if (d == 3)
                far = _mm256_or_pd(far, _mm256_cmp_pd(_mm256_andnot_pd(c->sign, e2), c->hl[2], _CMP_GT_OQ));
        }
        /* pair_force_r2 and the fused sums of pair_row_forces */
        __m256d r2 = _mm256_fmadd_pd(e1, e1, _mm256_mul_pd(e0, e0));
        if (d == 3)
            r2 = _mm256_fmadd_pd(e2, e2, r2);
        const __m256d gg = group_kernel(c, law, r2);
        const __m256d s0 = _mm256_fmadd_pd(gg, e0, a0), s1 = _mm256_fmadd_pd(gg, e1, a1);
        const __m256d s2 = d == 3 ? _mm256_fmadd_pd(gg, e2, a2) : a2;
        if (k >= full) { /* lanes whose list has ended (padding) keep their sums */
            const __m256d live = _mm256_castsi256_pd(_mm256_cvtepi32_epi64(_mm_cmpgt_epi32(num, _mm_set1_epi32((int)k))));
            a0 = _mm256_blendv_pd(a0, s0, live);
            a1 = _mm256_blendv_pd(a1, s1, live);
            a2 = _mm256_blendv_pd(a2, s2, live);
        } else {
            a0 = s0;
            a1 = s1;
            a2 = s2;
        }
    }
    _mm256_storeu_pd(s[0], a0);
    _mm256_storeu_pd(s[1], a1);
    _mm256_storeu_pd(s[2], a2);
    return _mm256_movemask_pd(far) != 0;
}

/* FN (group_rows or group8_rows) with the law, dimension and mode as
 * constants: one inlined copy of the loop for each. */
#define GROUP_MODES(FN, LAW, D)                                       \
    return mode == GROUP_PLAIN     ? FN(c, LAW, D, GROUP_PLAIN, in, s)   \
           : mode == GROUP_CHECK   ? FN(c, LAW, D, GROUP_CHECK, in, s)   \
           : mode == GROUP_AXES + 1 ? FN(c, LAW, D, GROUP_AXES + 1, in, s) \
           : mode == GROUP_AXES + 2 ? FN(c, LAW, D, GROUP_AXES + 2, in, s) \
           : mode == GROUP_AXES + 3 ? FN(c, LAW, D, GROUP_AXES + 3, in, s) \
           : mode == GROUP_AXES + 4 ? FN(c, LAW, D, GROUP_AXES + 4, in, s) \
           : mode == GROUP_AXES + 5 ? FN(c, LAW, D, GROUP_AXES + 5, in, s) \
           : mode == GROUP_AXES + 6 ? FN(c, LAW, D, GROUP_AXES + 6, in, s) \
           : mode == GROUP_AXES + 7 ? FN(c, LAW, D, GROUP_AXES + 7, in, s) \
                                   : FN(c, LAW, D, GROUP_IMAGE, in, s);
#define GROUP_DISPATCH(FN)                                  \
    if (law == PSYS_PAIR_LENNARD_JONES) {                   \
        if (d == 3) {                                       \
            GROUP_MODES(FN, PSYS_PAIR_LENNARD_JONES, 3)     \
        }                                                   \
        GROUP_MODES(FN, PSYS_PAIR_LENNARD_JONES, 2)         \
    }                                                       \
    if (d == 3) {                                           \
        GROUP_MODES(FN, PSYS_PAIR_SOFT_REPULSION, 3)        \
    }                                                       \
    GROUP_MODES(FN, PSYS_PAIR_SOFT_REPULSION, 2)

AVX2 static bool group_rows_as(const group_consts *c, int law, int d, int mode, const group_in *in,
                               double s[3][GROUP_MAX])
{
    GROUP_DISPATCH(group_rows)
}

/* The periodic axes on which some of rows i0..i0+width-1 lies less than
 * the list radius plus twice the skin inside a face (bit k for axis k; a
 * NaN counts as near on every axis). On the other axes their partners
 * normally need no image (the group loops check it, unless every position
 * lies within half a skin of the box: see psys__pair_group_forces). */
static inline unsigned group_near(const group_consts *c, int d, const double *Q, size_t i0, const uint32_t *row,
                                  int width)
{
    unsigned near = 0;
    for (int k = 0; k < d; k++)
        for (int l = 0; l < width; l++) {
            const double v = Q[4 * (row ? row[l] : i0 + (size_t)l) + (size_t)k];
            if (!(v >= c->inlo[k] && v <= c->inhi[k])) {
                near |= 1u << k;
                break;
            }
        }
    return near;
}

AVX2 static void group_consts_of(const pair_force *p, const pair_image *m, group_consts *c)
{
    double hl[3], ln[3], il[3], fr[3];
    pair_image_fold(m, hl, ln, il, fr);
    for (int k = 0; k < 3; k++) {
        c->hl[k] = _mm256_set1_pd(hl[k]);
        c->ln[k] = _mm256_set1_pd(ln[k]);
        c->fr[k] = _mm256_set1_pd(fr[k]);
    }
    c->sign = _mm256_set1_pd(-0.0);
    const psys__box *box = &p->sys->box;
    const double margin = sqrt(p->rlist2) + 2 * p->def.skin;
    for (int k = 0; k < 3; k++) {
        const bool per = m->on && m->per[k];
        c->inlo[k] = per ? box->lo[k] + margin : -INFINITY;
        c->inhi[k] = per ? box->hi[k] - margin : INFINITY;
    }
    c->zero = _mm256_setzero_pd();
    c->one = _mm256_set1_pd(1.0);
    c->two = _mm256_set1_pd(2.0);
    c->rc2 = _mm256_set1_pd(p->rc2);
    /* group8_kernel's test of 0 < r² < rc²: the bits of rc² less one (0:
     * no cutoff, nothing inside, as the comparisons give) */
    uint64_t rb = 0;
    if (p->rc2 > 0)
        memcpy(&rb, &p->rc2, sizeof rb), rb -= 1;
    c->rcbits = _mm256_castsi256_pd(_mm256_set1_epi64x((long long)rb));
    c->sig2 = _mm256_set1_pd(p->sig2);
    c->lj24 = _mm256_set1_pd(p->lj24);
    c->kc = _mm256_set1_pd(p->kc);
    c->radius = _mm256_set1_pd(p->def.radius);
}

/* ---- Eight rows at a time (AVX-512: AVX512F, VL, DQ) ----
 * The same scheme with eight lanes: the partners' records loaded two to a
 * 512-bit register and transposed (gathers were much slower;
 * bench/HISTORY.md). Per lane the operations and the order of
 * group_rows, so the same bits. */
#define GROUP8 8
#define GROUP8_BLOCK 32 /* entries of a sparse group interleaved at a time */
#define SPARSE_SPAN 4096 /* rows scanned for marked ones per parallel task */
/* Lennard-Jones with σ = 1, as a law of its own for the eight-lane loop */
#define GROUP8_LJ_UNIT (-1)
#define AVX512 __attribute__((target("avx512f,avx512vl,avx512dq")))

static bool group8_wanted(const pair_force *p)
{
    return __builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512vl")
           && __builtin_cpu_supports("avx512dq") && !p->sys->sw.group8_off;
}

typedef struct group8_consts {
    bool unit_sigma; /* σ² == 1 */
    union {
        struct {
            GROUP_CONST_FIELDS(__m512d);
        };
        __m512d v[GROUP_NCONST];
    };
} group8_consts;

/* group_delta on eight lanes: copysign(L, e) as one bitwise operation
 * (L | (sign & e)), subtracted only in the lanes past half a box, the others
 * keeping e: the same numbers as the blend of group_delta, two instructions
 * fewer. */
AVX512 static inline __m512d group8_delta(const group8_consts *c, int k, __m512d e, __mmask8 *far, const bool flag)
{
    const __m512d a = _mm512_andnot_pd(c->sign, e);
    /* 0xf8: A | (B & C), A = L, B = sign, C = e */
    const __m512d sl = _mm512_castsi512_pd(_mm512_ternarylogic_epi64(
        _mm512_castpd_si512(c->ln[k]), _mm512_castpd_si512(c->sign), _mm512_castpd_si512(e), 0xf8));
    if (flag)
        *far |= _mm512_cmp_pd_mask(a, c->fr[k], _CMP_GE_OQ);
    return _mm512_mask_sub_pd(e, _mm512_cmp_pd_mask(a, c->hl[k], _CMP_GT_OQ), e, sl);
}

/* Lennard-Jones: the division masked to the pairs inside the cutoff, the
 * others getting 1/r² = 0 and so g = ±0: a ±0 term fused into a sum that
 * starts at +0 leaves it as it is (no such sum of finite terms is -0), so
 * the same bits as the masked g of the row kernel, two instructions fewer
 * per entry. */
AVX512 static inline __m512d group8_kernel(const group8_consts *c, const int law, __m512d r2)
{
    /* 0 < r² < rc² as one unsigned comparison of the bits less one: +0
     * wraps to the largest number, -0, NaN and r² ≥ rc² (positive doubles
     * order as their bits) lie above, so the same mask as the two
     * comparisons of pair_kernel, one instruction fewer */
    const __mmask8 in = _mm512_cmplt_epu64_mask(_mm512_sub_epi64(_mm512_castpd_si512(r2), _mm512_set1_epi64(1)),
                                                _mm512_castpd_si512(c->rcbits));
    if (law == PSYS_PAIR_LENNARD_JONES || law == GROUP8_LJ_UNIT) {
        /* σ² = 1 (reduced units): σ²·(1/r²) is 1/r² exactly. 2·s⁶ - 1 as
         * one fused multiply-subtract (AVX-512F has it): 2·s⁶ is exact, so
         * the one rounding is the subtraction's, the same bits as the row
         * kernel's product and difference, one instruction fewer */
        const __m512d ir2 = _mm512_maskz_div_pd(in, c->one, r2);
        const __m512d s2 = law == GROUP8_LJ_UNIT ? ir2 : _mm512_mul_pd(c->sig2, ir2);
        const __m512d s6 = _mm512_mul_pd(_mm512_mul_pd(s2, s2), s2);
        return _mm512_mul_pd(_mm512_mul_pd(_mm512_mul_pd(c->lj24, s6), _mm512_fmsub_pd(c->two, s6, c->one)),
                             ir2);
    }
    const __m512d safe = _mm512_mask_blend_pd(in, c->one, r2);
    const __m512d r = _mm512_sqrt_pd(safe), dr = _mm512_sub_pd(c->radius, r);
    return _mm512_maskz_mov_pd(in, _mm512_div_pd(_mm512_mul_pd(c->kc, dr), r));
}

/* The eight records (x, y, z, 0) at Q + j[l], transposed into v[0..2]: q0
 * holds records 0 and 2, q1 1 and 3, q2 4 and 6, q3 5 and 7, so that the
 * 128-bit lanes picked below come out in order. */
AVX512 __attribute__((always_inline)) static inline void group8_records(const double *Q, const uint32_t *j,
                                                                       const int d, __m512d v[3])
{
    const __m512d q0 = _mm512_insertf64x4(_mm512_castpd256_pd512(_mm256_load_pd(Q + j[0])), _mm256_load_pd(Q + j[2]), 1);
    const __m512d q1 = _mm512_insertf64x4(_mm512_castpd256_pd512(_mm256_load_pd(Q + j[1])), _mm256_load_pd(Q + j[3]), 1);
    const __m512d q2 = _mm512_insertf64x4(_mm512_castpd256_pd512(_mm256_load_pd(Q + j[4])), _mm256_load_pd(Q + j[6]), 1);
    const __m512d q3 = _mm512_insertf64x4(_mm512_castpd256_pd512(_mm256_load_pd(Q + j[5])), _mm256_load_pd(Q + j[7]), 1);
    const __m512d u0 = _mm512_unpacklo_pd(q0, q1), u1 = _mm512_unpackhi_pd(q0, q1);
    const __m512d u2 = _mm512_unpacklo_pd(q2, q3), u3 = _mm512_unpackhi_pd(q2, q3);
    v[0] = _mm512_shuffle_f64x2(u0, u2, 0x88);
    v[1] = _mm512_shuffle_f64x2(u1, u3, 0x88);
    v[2] = d == 3 ? _mm512_shuffle_f64x2(u0, u2, 0xdd) : _mm512_setzero_pd();
}

/* Entry k of a group's lists (j: its eight partners' record offsets) added
 * into a; lanes outside live (lists that have ended) keep their sums. */
AVX512 __attribute__((always_inline)) static inline void group8_entry(const group8_consts *c, const int law,
                                                                     const int d, const int mode, const double *Q,
                                                                     const uint32_t *j, const __m512d xi[3],
                                                                     const __mmask8 live, __m512d a[3],
                                                                     __mmask8 *far)
{
    __m512d q[3];
    group8_records(Q, j, d, q);
    __m512d e0 = _mm512_sub_pd(xi[0], q[0]);
    __m512d e1 = _mm512_sub_pd(xi[1], q[1]);
    __m512d e2 = _mm512_setzero_pd();
    if (d == 3)
        e2 = _mm512_sub_pd(xi[2], q[2]);
    if (mode >= GROUP_IMAGE) {
        if (GROUP_IMAGES(mode, 0))
            e0 = group8_delta(c, 0, e0, far, mode == GROUP_IMAGE);
        if (GROUP_IMAGES(mode, 1))
            e1 = group8_delta(c, 1, e1, far, mode == GROUP_IMAGE);
        if (d == 3 && GROUP_IMAGES(mode, 2))
            e2 = group8_delta(c, 2, e2, far, mode == GROUP_IMAGE);
    } else if (mode == GROUP_CHECK) {
        *far |= _mm512_cmp_pd_mask(_mm512_andnot_pd(c->sign, e0), c->hl[0], _CMP_GT_OQ);
        *far |= _mm512_cmp_pd_mask(_mm512_andnot_pd(c->sign, e1), c->hl[1], _CMP_GT_OQ);
        if (d == 3)
            *far |= _mm512_cmp_pd_mask(_mm512_andnot_pd(c->sign, e2), c->hl[2], _CMP_GT_OQ);
    }
    /* pair_force_r2 and the fused sums of pair_row_forces; lanes outside
     * live keep their sums */
    __m512d r2 = _mm512_fmadd_pd(e1, e1, _mm512_mul_pd(e0, e0));
    if (d == 3)
        r2 = _mm512_fmadd_pd(e2, e2, r2);
    const __m512d gg = group8_kernel(c, law, r2);
    a[0] = _mm512_mask3_fmadd_pd(gg, e0, a[0], live);
    a[1] = _mm512_mask3_fmadd_pd(gg, e1, a[1], live);
    if (d == 3)
        a[2] = _mm512_mask3_fmadd_pd(gg, e2, a[2], live);
}

/* Rows i0..i0+7 into s (s[k][l]: component k of row i0+l); true if a
 * difference was flagged (the modes of group_rows). The entries every list
 * has first, then the rest with a mask. */
AVX512 __attribute__((always_inline)) static inline bool group8_rows(const group8_consts *c, const int law,
                                                                    const int d, const int mode, const group_in *in,
                                                                    double s[3][GROUP_MAX])
{
    const size_t i0 = in->i0;
    uint32_t own[GROUP8];
    for (int l = 0; l < GROUP8; l++)
        own[l] = (uint32_t)(4 * (in->row ? in->row[l] : i0 + (size_t)l));
    __m512d xi[3];
    group8_records(in->Q, own, d, xi);
    __m512d a[3] = {_mm512_setzero_pd(), _mm512_setzero_pd(), _mm512_setzero_pd()};
    __mmask8 far = 0;
    const uint32_t *n = in->num, len = in->len;
    uint32_t full = UINT32_MAX;
    for (int l = 0; l < GROUP8; l++)
        full = n[l] < full ? n[l] : full;
    const __m256i num = _mm256_loadu_si256((const __m256i *)n);
    if (in->lst) {
        /* rows anywhere: their lists interleaved here, a block at a time,
         * padded with the row's own record as the build's copy is */
        uint32_t buf[GROUP8_BLOCK * GROUP8];
        for (uint32_t k0 = 0; k0 < len; k0 += GROUP8_BLOCK) {
            const uint32_t kb = len - k0 < GROUP8_BLOCK ? len - k0 : GROUP8_BLOCK;
            for (int l = 0; l < GROUP8; l++) {
                const uint32_t *src = in->lst[l];
                for (uint32_t q = 0; q < kb; q++)
                    buf[q * GROUP8 + (uint32_t)l] = k0 + q < n[l] ? 4 * src[k0 + q] : own[l];
            }
            for (uint32_t q = 0; q < kb; q++) {
                const uint32_t k = k0 + q;
                const __mmask8 live = k < full ? (__mmask8)0xff : _mm256_cmpgt_epi32_mask(num, _mm256_set1_epi32((int)k));
                group8_entry(c, law, d, mode, in->Q, buf + (size_t)GROUP8 * q, xi, live, a, &far);
            }
        }
    } else {
        uint32_t k = 0;
        for (; k < full; k++)
            group8_entry(c, law, d, mode, in->Q, in->il + (size_t)GROUP8 * k, xi, (__mmask8)0xff, a, &far);
        for (; k < len; k++)
            group8_entry(c, law, d, mode, in->Q, in->il + (size_t)GROUP8 * k, xi,
                         _mm256_cmpgt_epi32_mask(num, _mm256_set1_epi32((int)k)), a, &far);
    }
    _mm512_storeu_pd(s[0], a[0]);
    _mm512_storeu_pd(s[1], a[1]);
    _mm512_storeu_pd(s[2], a[2]);
    return far != 0;
}

AVX512 static bool group8_rows_as(const group8_consts *c, int law, int d, int mode, const group_in *in,
                                  double s[3][GROUP_MAX])
{
    if (law == PSYS_PAIR_LENNARD_JONES && c->unit_sigma) {
        if (d == 3) {
            GROUP_MODES(group8_rows, GROUP8_LJ_UNIT, 3)
        }
        GROUP_MODES(group8_rows, GROUP8_LJ_UNIT, 2)
    }
    GROUP_DISPATCH(group8_rows)
}

/* The four-lane constants c4 (group_consts_of), each widened to eight lanes. */
AVX512 static void group8_consts_of(const group_consts *c4, group8_consts *c)
{
    for (int k = 0; k < GROUP_NCONST; k++)
        c->v[k] = _mm512_broadcast_f64x4(c4->v[k]);
}

/* The constants of both loops. */
typedef struct group_ctx {
    group_consts c4;
    group8_consts c8;
} group_ctx;

/* One group (rows i0.. or in->row) through its loop into out, the rows of
 * `rows` only (all when NULL); a group in which a difference was flagged
 * even with the image goes through the row loop one row at a time. */
static void group_run(const pair_force *p, const pair_image *m, const group_ctx *x, int width, const double *w,
                      const group_in *in, const unsigned char *rows, bool in_box, double *out)
{
    const int d = p->dim, law = p->law;
    /* groups away from the periodic faces first without the image: only
     * a flagged group pays for it; with every position in the box, a
     * group takes the image only on the axes whose faces it is near */
    int mode = GROUP_PLAIN;
    if (m->on) {
        const unsigned near = group_near(&x->c4, d, in->Q, in->i0, in->row, width);
        mode = near == 0 ? (in_box ? GROUP_PLAIN : GROUP_CHECK) : in_box ? GROUP_AXES + (int)near : GROUP_IMAGE;
    }
    double s[3][GROUP_MAX];
    bool far;
    for (;;) {
        far = width == GROUP8 ? group8_rows_as(&x->c8, law, d, mode, in, s) : group_rows_as(&x->c4, law, d, mode, in, s);
        if (!(far && mode == GROUP_CHECK))
            break;
        mode = GROUP_IMAGE;
    }
    for (int l = 0; l < width; l++) {
        const size_t i = in->row ? in->row[l] : in->i0 + (size_t)l;
        if (rows && !rows[i])
            continue;
        if (far) {
            group_row_alone(p, m, w, i, out);
        } else {
            for (int k = 0; k < d; k++)
                out[i * (size_t)d + (size_t)k] = s[k][l];
        }
    }
}

/* Groups [b0, b1) of `width` rows (GROUP or GROUP8) through their loop,
 * those with a row of `rows` only (all when NULL). */
static void group_chunk(const pair_force *p, const pair_image *m, const group_ctx *x, int width, const double *w,
                        size_t b0, size_t b1, const unsigned char *rows, bool in_box, double *out)
{
    const pair_grid *g = &p->grid;
    for (size_t b = b0; b < b1; b++) {
        const size_t s0 = b * (size_t)width; /* the group's first slot */
        const uint32_t *row = g->gl_cells ? g->cell_list + s0 : NULL;
        bool any = !rows;
        for (int l = 0; l < width && !any; l++)
            any = rows[row ? row[l] : s0 + (size_t)l] != 0;
        if (!any)
            continue;
        const group_in in = {g->xq, g->gl + g->gl_start[b], g->gl_num + s0,
                             (uint32_t)((g->gl_start[b + 1] - g->gl_start[b]) / (size_t)width), s0, row, NULL};
        group_run(p, m, x, width, w, &in, rows, in_box, out);
    }
}

/* The rows of `rows` in group slots [r0, r1) (group_row) eight at a time,
 * wherever they are (a partial evaluation: the moved particles and their
 * partners), so a group computes eight of them instead of the few that
 * fall in one group. The last group repeats its last row in its spare
 * lanes (the same result stored again). */
static void group8_sparse(const pair_force *p, const pair_image *m, const group_ctx *x, const double *w, size_t r0,
                          size_t r1, const unsigned char *rows, bool in_box, double *out)
{
    const pair_grid *g = &p->grid;
    /* where most rows of the groups touched are marked (an MPI rank's own
     * rows), the groups as they are: interleaving costs about a third of
     * the loop's time per entry */
    size_t marked = 0, touched = 0;
    for (size_t s0 = r0; s0 < r1; s0 += GROUP8) {
        size_t c = 0;
        for (int l = 0; l < GROUP8; l++)
            c += rows[group_row(g, s0 + (size_t)l)] != 0;
        marked += c;
        touched += c != 0;
    }
    if (4 * marked >= 3 * GROUP8 * touched) {
        group_chunk(p, m, x, GROUP8, w, r0 / GROUP8, r1 / GROUP8, rows, in_box, out);
        return;
    }
    uint32_t sel[GROUP8], num[GROUP8];
    const uint32_t *lst[GROUP8];
    int cnt = 0;
    for (size_t t = r0; t <= r1; t++) {
        const size_t i = t < r1 ? group_row(g, t) : 0;
        if (t < r1 && rows[i]) {
            sel[cnt] = (uint32_t)i;
            num[cnt] = g->nb_num[i];
            lst[cnt] = g->nb + g->nb_start[i];
            cnt++;
        }
        if (cnt == 0 || (cnt < GROUP8 && t < r1))
            continue;
        uint32_t len = 0;
        for (int l = 0; l < GROUP8; l++) {
            const int f = l < cnt ? l : cnt - 1;
            sel[l] = sel[f];
            num[l] = num[f];
            lst[l] = lst[f];
            len = num[l] > len ? num[l] : len;
        }
        const group_in in = {g->xq, NULL, num, len, 0, sel, lst};
        group_run(p, m, x, GROUP8, w, &in, NULL, in_box, out);
        cnt = 0;
    }
}
#endif

bool psys__pair_group_lists(pair_force *p, size_t n, int nt)
{
    pair_grid *g = &p->grid;
    g->gl_ok = false;
#if defined(PSYS_GROUP_AVX2)
    if (!group_wanted(p) || n > GROUP_N_MAX)
        return true;
    const size_t width = group8_wanted(p) ? GROUP8 : GROUP, ng = n / width;
    if (ng + 1 > g->gl_start_cap) {
        size_t *q = psys__realloc(g->gl_start, ng + 1, sizeof(size_t));
        if (!q)
            return false;
        g->gl_start = q;
        g->gl_start_cap = ng + 1;
    }
    /* Groups of consecutive particles where their numbering is local
     * already (a lattice, a data file written in order), else of
     * consecutive slots of the cell order: either way rows near each other
     * in space, whose partners are mostly the same particles, so the
     * records a group reads are in cache from the groups before it (the
     * cell order pays where the numbering is random and costs a little
     * where it is local already; bench/HISTORY.md). Each row's sum is the same however rows are
     * grouped: the bits do not depend on it. */
    /* consecutive particles at most two cells apart on every axis, in a
     * sample of every sixteenth pair (the divisions cost a few per cent
     * of an LJ melt's time when every pair is looked at) */
    size_t local = 0, seen = 0;
    const uint32_t nx = (uint32_t)g->ncell[0], nxy = nx * (uint32_t)g->ncell[1];
    for (size_t i = 0; i + 1 < n; i += 16, seen++) {
        const uint32_t a = g->cell_of[i], c = g->cell_of[i + 1];
        const uint32_t ax = a % nx, ay = a % nxy / nx, az = a / nxy, cx = c % nx, cy = c % nxy / nx, cz = c / nxy;
        local += (ax > cx ? ax - cx : cx - ax) <= 2 && (ay > cy ? ay - cy : cy - ay) <= 2 &&
                 (az > cz ? az - cz : cz - az) <= 2;
    }
    g->gl_cells = 2 * local < seen;
    size_t total = 0;
    for (size_t b = 0; b < ng; b++) {
        uint32_t len = 0;
        for (size_t l = 0; l < width; l++)
            len = g->nb_num[group_row(g, b * width + l)] > len ? g->nb_num[group_row(g, b * width + l)] : len;
        g->gl_start[b] = total;
        total += width * len;
    }
    g->gl_start[ng] = total;
    if (total > g->gl_cap || !g->gl) {
        const size_t c = total + total / 8 + 64;
        uint32_t *q = psys__realloc(g->gl, c, sizeof(uint32_t));
        if (!q)
            return false;
        g->gl = q;
        g->gl_cap = c;
    }
    (void)nt;
    PSYS_OMP(omp parallel for schedule(static) num_threads(nt) if (nt > 1 && n >= PSYS_PAR_MIN))
    for (size_t b = 0; b < ng; b++) {
        uint32_t *dst = g->gl + g->gl_start[b];
        const size_t len = (g->gl_start[b + 1] - g->gl_start[b]) / width;
        for (size_t l = 0; l < width; l++) {
            const size_t i = group_row(g, b * width + l);
            const uint32_t *src = g->nb + g->nb_start[i];
            g->gl_num[b * width + l] = g->nb_num[i];
            size_t k = 0;
            for (; k < g->nb_num[i]; k++)
                dst[k * width + l] = 4 * src[k];
            for (; k < len; k++)
                dst[k * width + l] = 4 * (uint32_t)i;
        }
    }
    g->gl_width = (int)width;
    g->gl_ok = true;
#else
    (void)n;
    (void)nt;
#endif
    return true;
}

bool psys__pair_group_forces(pair_force *p, const pair_image *m, const double *x_in, const double *w, size_t n,
                             const unsigned char *rows, const uint32_t *changed, size_t nchanged, double *xc,
                             double *out, int nt)
{
#if defined(PSYS_GROUP_AVX2)
    pair_grid *g = &p->grid;
    if (!group_wanted(p))
        return false;
    group_ctx x;
    group_consts_of(p, m, &x.c4);
    /* eight rows at a time where the CPU can, else four */
    const int width = group8_wanted(p) ? GROUP8 : GROUP;
    if (!g->gl_ok || g->gl_width != width)
        return false; /* no interleaved lists for this width (psys__pair_group_lists) */
    if (width == GROUP8) {
        group8_consts_of(&x.c4, &x.c8);
        x.c8.unit_sigma = p->sig2 == 1.0;
    }
    const size_t ng = n / (size_t)width, nchunks = (ng + GROUP_CHUNK - 1) / GROUP_CHUNK;
    const bool three = p->dim == 3;
    const size_t dd = three ? 3 : 2;
    double *Q = g->xq;
    /* the positions' bounds: if every one lies within half a skin of the
     * box, a listed partner of a row at least the list radius plus twice
     * the skin inside the faces of axis k (group_near) is at less than the
     * list radius plus the skin (the rebuild rule), so on axis k its raw
     * difference is its minimum image and less than half a box: there the
     * check of GROUP_CHECK cannot fire and the image changes nothing, so
     * both are skipped (GROUP_PLAIN, GROUP_AXES: the same bits) */
    double lo0 = INFINITY, lo1 = INFINITY, lo2 = INFINITY, hi0 = -INFINITY, hi1 = -INFINITY, hi2 = -INFINITY;
    /* a partial evaluation (velocity Verlet's first of a step: the particles
     * wrapped into the box) copies only the changed records; the bounds
     * then cover the cached positions and the new ones, a superset, which
     * can only make the image checks below more careful */
    const bool update = changed != NULL;
    if (update) {
        lo0 = g->xq_lo[0], lo1 = g->xq_lo[1], lo2 = g->xq_lo[2];
        hi0 = g->xq_hi[0], hi1 = g->xq_hi[1], hi2 = g->xq_hi[2];
    }
    const size_t ncopy = update ? nchanged : n;
    const bool xcopy = xc && !update;
    (void)nt;
    PSYS_OMP(omp parallel for schedule(static) num_threads(nt) if (nt > 1 && ncopy >= PSYS_PAR_MIN) \
             reduction(min: lo0, lo1, lo2) reduction(max: hi0, hi1, hi2))
    for (size_t t = 0; t < ncopy; t++) {
        const size_t i = update ? changed[t] : t;
        const double a = x_in[dd * i], b = x_in[dd * i + 1], z = three ? x_in[dd * i + 2] : 0.0;
        if (xcopy) {
            xc[dd * i] = a;
            xc[dd * i + 1] = b;
            if (three)
                xc[dd * i + 2] = z;
        }
        Q[4 * i] = a;
        Q[4 * i + 1] = b;
        Q[4 * i + 2] = z;
        Q[4 * i + 3] = 0.0;
        lo0 = a < lo0 ? a : lo0;
        hi0 = a > hi0 ? a : hi0;
        lo1 = b < lo1 ? b : lo1;
        hi1 = b > hi1 ? b : hi1;
        lo2 = z < lo2 ? z : lo2;
        hi2 = z > hi2 ? z : hi2;
    }
    /* (xq_cached: set by the caller, grid_eval, once x is the cache's) */
    g->xq_lo[0] = lo0, g->xq_lo[1] = lo1, g->xq_lo[2] = lo2;
    g->xq_hi[0] = hi0, g->xq_hi[1] = hi1, g->xq_hi[2] = hi2;
    bool in_box = m->on;
    {
        const psys__box *box = &p->sys->box;
        const double lo[3] = {lo0, lo1, lo2}, hi[3] = {hi0, hi1, hi2}, slack = 0.5 * p->def.skin;
        /* (and a skin under half the box, so no difference on an axis
         * reaches the 1.5 boxes that GROUP_IMAGE flags) */
        for (int k = 0; k < p->dim; k++)
            if (m->per[k])
                in_box = in_box && lo[k] >= box->lo[k] - slack && hi[k] <= box->hi[k] + slack
                         && 2 * slack < 0.5 * box->len[k];
    }
    /* the component-major copy for the rows that may go through the row
     * loop: the last n mod width, and any group flagged (only possible when
     * not every position lies in the box) */
    if ((m->on && !in_box) || n % (size_t)width != 0)
        pair_soa_positions(p, x_in, n, nt);
    if (rows && width == GROUP8) {
        /* a partial evaluation: the marked rows in groups of eight wherever
         * they lie (their lists interleaved on the fly) */
        const size_t nr = ng * (size_t)GROUP8, nspans = (nr + SPARSE_SPAN - 1) / SPARSE_SPAN;
        PSYS_OMP(omp parallel for schedule(dynamic, 1) num_threads(nt) if (nt > 1))
        for (size_t q = 0; q < nspans; q++) {
            const size_t r0 = q * SPARSE_SPAN, r1 = r0 + SPARSE_SPAN < nr ? r0 + SPARSE_SPAN : nr;
            group8_sparse(p, m, &x, w, r0, r1, rows, in_box, out);
        }
    } else {
        PSYS_OMP(omp parallel for schedule(dynamic, 1) num_threads(nt) if (nt > 1))
        for (size_t q = 0; q < nchunks; q++) {
            const size_t b0 = q * GROUP_CHUNK, b1 = b0 + GROUP_CHUNK < ng ? b0 + GROUP_CHUNK : ng;
            group_chunk(p, m, &x, width, w, b0, b1, rows, in_box, out);
        }
    }
    /* the rows of the last n mod width slots, one at a time */
    for (size_t t = ng * (size_t)width; t < n; t++) {
        const size_t i = group_row(g, t);
        if (!rows || rows[i])
            group_row_alone(p, m, w, i, out);
    }
    return true;
#else
    (void)p;
    (void)m;
    (void)w;
    (void)n;
    (void)rows;
    (void)changed;
    (void)nchanged;
    (void)xc;
    (void)out;
    (void)nt;
    return false;
#endif
}
