/* Neighbour lists particle by particle: each particle scans the cells
 * around its own (scan_plain, or scan_avx512 eight candidates at a time)
 * and its list is sorted (sort_indices, or the AVX-512 bitonic sort); the
 * fill_* functions write every chunk's lists for pair/grid.c's build. The
 * scans stay in this file with visit_d, which inlines them. */
#include "pair/grid.h"

#include <stdlib.h>
#include <string.h>

static void insertion_sort(uint32_t *a, size_t n)
{
    for (size_t i = 1; i < n; i++) {
        uint32_t v = a[i];
        size_t j = i;
        while (j > 0 && a[j - 1] > v) {
            a[j] = a[j - 1];
            j--;
        }
        a[j] = v;
    }
}

/* Sort a list of particle indices in place: distribute into SORT_BUCKETS
 * buckets spanning the list's own range [min, max] (a particle's partners
 * are spread over far fewer indices than the system has), then
 * insertion-sort the nearly sorted result. tmp holds SORT_MAX entries. */
#define SORT_BUCKETS 128
void psys__pair_sort_indices(uint32_t *a, size_t n, uint32_t *tmp)
{
    if (n <= 16 || n > SORT_MAX) {
        insertion_sort(a, n);
        return;
    }
    uint32_t lo = a[0], hi = a[0];
    for (size_t i = 1; i < n; i++) {
        lo = a[i] < lo ? a[i] : lo;
        hi = a[i] > hi ? a[i] : hi;
    }
    int shift = 0;
    while ((hi - lo) >> shift >= SORT_BUCKETS)
        shift++;
    uint16_t count[SORT_BUCKETS + 1];
    memset(count, 0, sizeof count);
    for (size_t i = 0; i < n; i++)
        count[((a[i] - lo) >> shift) + 1]++;
    for (int b = 0; b < SORT_BUCKETS; b++)
        count[b + 1] = (uint16_t)(count[b + 1] + count[b]);
    for (size_t i = 0; i < n; i++)
        tmp[count[(a[i] - lo) >> shift]++] = a[i];
    memcpy(a, tmp, n * sizeof *a);
    insertion_sort(a, n);
}

/* Candidates t in [t0, t1) of cell_x/cell_list against the position xs:
 * those within rl2 (and j != i, or j > i for half lists) are written from
 * out[cnt] on while they fit in room, and counted past it; returns the new
 * count. slow (NULL: none) marks the axes whose distances go through the
 * minimum image m (periodic axes of fewer than five cells). The same test,
 * on the same numbers, in every variant. */
PAIR_INLINE size_t scan_plain(const pair_grid *g, const double *xs, size_t i, uint32_t t0, uint32_t t1,
                              uint32_t *out, size_t cnt, size_t room, double rl2, const bool half, const int d,
                              const pair_image *m, const bool *slow)
{
    for (uint32_t t = t0; t < t1; t++) {
        uint32_t j = g->cell_list[t];
        double r2 = 0;
        for (int k = 0; k < d; k++) {
            double dx = xs[k] - g->cell_x[(size_t)k * g->cx_stride + t];
            if (slow && slow[k])
                dx = pair_delta(m, k, dx);
            r2 += dx * dx;
        }
        if (cnt < room)
            out[cnt] = j;
        cnt += (r2 < rl2) & (half ? j > i : j != i);
    }
    return cnt;
}

#ifdef PSYS_SCAN_AVX512
/* scan_plain eight candidates at a time: the distances as 8-wide vectors,
 * the accepted indices packed with a compress (AVX-512F); the last vector
 * masked (a cell run holds a dozen candidates or so, and a scalar tail cost
 * as much as the vectors). While eight more fit in room; the rest through
 * scan_plain. */
__attribute__((target("avx512f"))) static size_t scan_avx512(const pair_grid *g, const double *xs, size_t i,
                                                             uint32_t t0, uint32_t t1, uint32_t *out, size_t cnt,
                                                             size_t room, double rl2, bool half, int d)
{
    const double *c0 = g->cell_x, *c1 = c0 + g->cx_stride, *c2 = c1 + g->cx_stride;
    const __m512d x0 = _mm512_set1_pd(xs[0]), x1 = _mm512_set1_pd(xs[1]), x2 = _mm512_set1_pd(xs[2]);
    const __m512d lim = _mm512_set1_pd(rl2), zero = _mm512_setzero_pd();
    const __m512i vi = _mm512_set1_epi64((long long)i);
    uint32_t t = t0;
    for (; t < t1 && cnt + 8 <= room; t += 8) {
        const __mmask8 live = t1 - t >= 8 ? (__mmask8)0xff : (__mmask8)((1u << (t1 - t)) - 1);
        __m512d dx = _mm512_sub_pd(x0, _mm512_maskz_loadu_pd(live, c0 + t));
        __m512d r2 = _mm512_add_pd(zero, _mm512_mul_pd(dx, dx));
        dx = _mm512_sub_pd(x1, _mm512_maskz_loadu_pd(live, c1 + t));
        r2 = _mm512_add_pd(r2, _mm512_mul_pd(dx, dx));
        if (d == 3) {
            dx = _mm512_sub_pd(x2, _mm512_maskz_loadu_pd(live, c2 + t));
            r2 = _mm512_add_pd(r2, _mm512_mul_pd(dx, dx));
        }
        __m512i j = _mm512_cvtepu32_epi64(
            _mm512_castsi512_si256(_mm512_maskz_loadu_epi32((__mmask16)live, g->cell_list + t)));
        __mmask8 ok = live & _mm512_cmp_pd_mask(r2, lim, _CMP_LT_OQ)
                      & (half ? _mm512_cmpgt_epu64_mask(j, vi) : _mm512_cmpneq_epu64_mask(j, vi));
        _mm256_storeu_si256((__m256i *)(out + cnt), _mm512_cvtepi64_epi32(_mm512_maskz_compress_epi64(ok, j)));
        cnt += (size_t)__builtin_popcount((unsigned)ok);
    }
    return d == 3 ? scan_plain(g, xs, i, t, t1, out, cnt, room, rl2, half, 3, NULL, NULL)
                  : scan_plain(g, xs, i, t, t1, out, cnt, room, rl2, half, 2, NULL, NULL);
}

/* Sort a[0..n) (n <= 16·M) ascending: a bitonic network over M registers
 * of sixteen indices, in the form whose comparators all put the smaller
 * value first (each merge starts by comparing a block with its mirror
 * image). Positions from n on hold UINT32_MAX and keep it, so the registers
 * past the last loaded one are never touched: a list of 77 costs five
 * registers, not eight. No branches on the data; sorting each list as it
 * is filled, while it is in cache, is faster than sorting them all by
 * transposition afterwards (figures: bench/HISTORY.md). */
#define SORT512_REGS 8
/* v with lane l taking lane l ^ X: in-lane shuffles with an immediate and
 * 128-bit lane moves (one or two instructions of a cycle each) instead of
 * the general permute. */
#define XL1(v) _mm512_shuffle_epi32((v), (_MM_PERM_ENUM)0xB1)
#define XL2(v) _mm512_shuffle_epi32((v), (_MM_PERM_ENUM)0x4E)
#define XL3(v) _mm512_shuffle_epi32((v), (_MM_PERM_ENUM)0x1B)
#define XL4(v) _mm512_shuffle_i32x4((v), (v), 0xB1)
#define XL8(v) _mm512_shuffle_i32x4((v), (v), 0x4E)
__attribute__((target("avx512f"), always_inline)) static inline __m512i xl7(__m512i v)
{
    v = XL3(v);
    return XL4(v);
}
__attribute__((target("avx512f"), always_inline)) static inline __m512i xl15(__m512i v)
{
    v = XL3(v);
    return _mm512_shuffle_i32x4(v, v, 0x1B);
}
/* One in-register stage on registers 0..U-1: lane l against lane l ^ x
 * (XL: the exchange), the lanes of `upper` taking the larger. */
#define SORT_STAGE(XL, upper)                                                                              \
    for (int r = 0; r < U; r++) {                                                                      \
        const __m512i w_ = XL(v[r]);                                                                   \
        v[r] = _mm512_mask_blend_epi32((__mmask16)(upper), _mm512_min_epu32(v[r], w_), _mm512_max_epu32(v[r], w_)); \
    }

__attribute__((target("avx512f"), always_inline)) static inline void sort512_regs(const uint32_t *a, size_t n,
                                                                                   uint32_t *dst, const int M)
{
    __m512i v[SORT512_REGS];
    const __m512i pad = _mm512_set1_epi32(-1);
    const int U = (int)((n + 15) / 16); /* registers holding data */
    for (int r = 0; r < M; r++) {
        const size_t at = 16 * (size_t)r, left = n > at ? n - at : 0;
        const __mmask16 live = left >= 16 ? (__mmask16)0xffff : (__mmask16)((1u << left) - 1);
        v[r] = r < U ? _mm512_mask_loadu_epi32(pad, live, a + at) : pad;
    }
    /* blocks of 2, 4, 8, 16 within each register: the mirror (lane l
     * against l ^ (k - 1)), then halves, quarters, ... */
    SORT_STAGE(XL1, 0xAAAA)
    SORT_STAGE(XL3, 0xCCCC)
    SORT_STAGE(XL1, 0xAAAA)
    SORT_STAGE(xl7, 0xF0F0)
    SORT_STAGE(XL2, 0xCCCC)
    SORT_STAGE(XL1, 0xAAAA)
    SORT_STAGE(xl15, 0xFF00)
    SORT_STAGE(XL4, 0xF0F0)
    SORT_STAGE(XL2, 0xCCCC)
    SORT_STAGE(XL1, 0xAAAA)
    for (int k = 32; k <= 16 * M; k <<= 1) {
        /* mirror across the registers of each block of k/16 */
        const int q = k >> 4;
        for (int r = 0; r < M; r++) {
            const int r2 = r ^ (q - 1);
            if ((r & (q >> 1)) || r2 >= U)
                continue;
            const __m512i w = xl15(v[r2]);
            const __m512i hi = _mm512_max_epu32(v[r], w);
            v[r] = _mm512_min_epu32(v[r], w);
            v[r2] = xl15(hi);
        }
        for (int j = k >> 2; j >= 16; j >>= 1) {
            const int qj = j >> 4;
            for (int r = 0; r < M; r++) {
                if ((r & qj) || (r | qj) >= U)
                    continue;
                const __m512i lo = _mm512_min_epu32(v[r], v[r | qj]);
                v[r | qj] = _mm512_max_epu32(v[r], v[r | qj]);
                v[r] = lo;
            }
        }
        SORT_STAGE(XL8, 0xFF00)
        SORT_STAGE(XL4, 0xF0F0)
        SORT_STAGE(XL2, 0xCCCC)
        SORT_STAGE(XL1, 0xAAAA)
    }
    for (int r = 0; r < U; r++) {
        const size_t at = 16 * (size_t)r, left = n - at;
        const __mmask16 live = left >= 16 ? (__mmask16)0xffff : (__mmask16)((1u << left) - 1);
        _mm512_mask_storeu_epi32(dst + at, live, v[r]);
    }
}

/* a[0..n) sorted into dst[0..n) (dst may be a) by sort512_regs with the
 * fewest registers that hold n (n <= 128); false, touching nothing, if n
 * is larger. */
__attribute__((target("avx512f"))) bool psys__pair_sort_avx512_to(const uint32_t *a, size_t n, uint32_t *dst)
{
    if (n <= 16)
        sort512_regs(a, n, dst, 1);
    else if (n <= 32)
        sort512_regs(a, n, dst, 2);
    else if (n <= 64)
        sort512_regs(a, n, dst, 4);
    else if (n <= 16 * SORT512_REGS)
        sort512_regs(a, n, dst, SORT512_REGS);
    else
        return false;
    return true;
}

__attribute__((target("avx512f"))) static bool sort_avx512(uint32_t *a, size_t n) { return psys__pair_sort_avx512_to(a, n, a); }
#endif

/* Whether scan_avx512 and sort_avx512 may run here (once per build).
 * PSYS_SCAN_PLAIN in the environment forces the portable scan and the
 * sorting by transposition, so the tests cover both paths on any machine
 * (the results are the same). */
bool psys__pair_scan_has_avx512(const psys_system *sys)
{
#ifdef PSYS_SCAN_AVX512
    return __builtin_cpu_supports("avx512f") && !sys->sw.scan_plain;
#else
    return false;
#endif
}

/* Partners of i within the list radius (half lists: only those with j > i):
 * all counted, the first `room` written to out and, if all fitted, sorted.
 * Candidates come from cell_x (build coordinates, streamed); on a periodic
 * axis each neighbouring cell is reached through the image its offset
 * names, so no per-candidate minimum image is needed, except on periodic
 * axes of fewer than five cells (each cell visited once, any image may be
 * the nearest). The radius carries a slack for the rounding of wrapped
 * coordinates (a list may hold a pair slightly beyond cutoff + skin; the
 * kernel cuts at the cutoff exactly). */
PAIR_INLINE size_t visit_d(const pair_force *p, const stencil *sc, const pair_image *m, const double *x, size_t i,
                           uint32_t *out, size_t room, uint32_t *tmp, double rl2, const bool half,
                           const int d, const bool use512, const bool sort)
{
    const pair_grid *g = &p->grid;
    const double lim = rl2 * (1 + 1e-6);
    uint32_t c = g->cell_of[i];
    int cc[3] = {(int)(c % (uint32_t)g->ncell[0]), (int)((c / (uint32_t)g->ncell[0]) % (uint32_t)g->ncell[1]), 0};
    if (d == 3)
        cc[2] = (int)(c / ((uint32_t)g->ncell[0] * (uint32_t)g->ncell[1]));
    double xi[3] = {0, 0, 0}, ad2[3][5], img[3][5];
    int wc[3][5]; /* the neighbouring cells' coordinates, wrapped; -1: outside a free axis */
    bool slow[3] = {false, false, false}, any_slow = false;
    for (int k = 0; k < 3; k++) {
        slow[k] = k < d && m->per[k] && !sc->prune[k];
        any_slow |= slow[k];
        for (int a = 0; a < sc->n[k]; a++) {
            double sh;
            wc[k][a] = wrap_cell(g, m, k, cc[k] + sc->off[k][a], &sh);
            img[k][a] = slow[k] ? 0 : sh; /* a slow axis: every candidate through the minimum image */
            ad2[k][a] = 0;
        }
    }
    for (int k = 0; k < d; k++) {
        xi[k] = build_coord(g, m, k, x[i * d + k]);
        double cs = g->cell_size[k], t = cell_rel(g, m, k, x[i * d + k]) - cs * cc[k];
        t = t < 0 ? 0 : t > cs ? cs : t;
        if (sc->prune[k])
            for (int a = 0; a < sc->n[k]; a++) {
                int o = sc->off[k][a];
                double dist = o == 0 ? 0 : o > 0 ? o * cs - t : t + (-o - 1) * cs;
                ad2[k][a] = dist * dist;
            }
    }
    size_t cnt = 0;
    const int nz = d == 3 ? sc->n[2] : 1;
    for (int a2 = 0; a2 < nz; a2++) {
        const double dz2 = ad2[2][a2];
        const int z = wc[2][a2];
        if (dz2 > lim || z < 0)
            continue;
        for (int a1 = 0; a1 < sc->n[1]; a1++) {
            const double dyz2 = dz2 + ad2[1][a1];
            const int y = wc[1][a1];
            if (dyz2 > lim || y < 0)
                continue;
            const size_t row = (size_t)g->ncell[0] * ((size_t)y + (size_t)g->ncell[1] * (size_t)z);
            if (any_slow) { /* each candidate through the minimum image */
                for (int a0 = 0; a0 < sc->n[0]; a0++) {
                    const int xx = wc[0][a0];
                    if (dyz2 + ad2[0][a0] > lim || xx < 0)
                        continue;
                    const size_t cell = row + (size_t)xx;
                    const double xs[3] = {xi[0] - img[0][a0], xi[1] - img[1][a1], d == 3 ? xi[2] - img[2][a2] : 0};
                    cnt = scan_plain(g, xs, i, g->cell_start[cell], g->cell_start[cell + 1], out, cnt, room, rl2,
                                     half, d, m, slow);
                }
                continue;
            }
            /* cells next to each other in memory with the same image form
             * one run of candidates */
            for (int a0 = 0; a0 < sc->n[0];) {
                const int xx = wc[0][a0];
                if (dyz2 + ad2[0][a0] > lim || xx < 0) {
                    a0++;
                    continue;
                }
                int e0 = a0 + 1;
                while (e0 < sc->n[0] && wc[0][e0] == wc[0][e0 - 1] + 1 && img[0][e0] == img[0][a0]
                       && !(dyz2 + ad2[0][e0] > lim))
                    e0++;
                const double xs[3] = {xi[0] - img[0][a0], xi[1] - img[1][a1], d == 3 ? xi[2] - img[2][a2] : 0};
                const uint32_t t0 = g->cell_start[row + (size_t)xx], t1 = g->cell_start[row + (size_t)wc[0][e0 - 1] + 1];
#ifdef PSYS_SCAN_AVX512
                if (use512)
                    cnt = scan_avx512(g, xs, i, t0, t1, out, cnt, room, rl2, half, d);
                else
#endif
                    cnt = scan_plain(g, xs, i, t0, t1, out, cnt, room, rl2, half, d, NULL, NULL);
                a0 = e0;
            }
        }
    }
    if (cnt <= room && sort) {
#ifdef PSYS_SCAN_AVX512
        if (!use512 || !sort_avx512(out, cnt))
#endif
            psys__pair_sort_indices(out, cnt, tmp);
    }
    return cnt;
}

/* Fill the lists of every chunk into its region; true if none overflowed. */
#define FILL_FN(name, D, HALF)                                                                               \
    bool name(pair_force *p, const stencil *sc, const pair_image *m, const double *x, size_t n,       \
                     size_t nchunks, double rl2, int nt, bool sort)                                          \
    {                                                                                                        \
        pair_grid *g = &p->grid;                                                                             \
        int over = 0;                                                                                        \
        const bool use512 = psys__pair_scan_has_avx512(p->sys);                                                               \
        const unsigned char *own = p->sys->own_mark; /* MPI domain (mpi/domain.c): owned rows only */          \
        (void)nt;                                                                                            \
        PSYS_OMP(omp parallel for schedule(dynamic, 1) num_threads(nt) if (nt > 1) reduction(|: over))        \
        for (size_t c = 0; c < nchunks; c++) {                                                               \
            uint32_t tmp[SORT_MAX];                                                                          \
            size_t pos = g->chunk_off[c], end = g->chunk_off[c + 1];                                         \
            size_t i1 = (c + 1) * CHUNK < n ? (c + 1) * CHUNK : n;                                           \
            for (size_t i = c * CHUNK; i < i1; i++) {                                                        \
                if (own && !own[i]) { /* a domain's ghost: its row is never evaluated */                     \
                    g->nb_start[i] = pos;                                                                    \
                    g->nb_num[i] = 0;                                                                        \
                    continue;                                                                                \
                }                                                                                            \
                size_t room = end - pos;                                                                     \
                size_t k = visit_d(p, sc, m, x, i, g->nb + pos, room, tmp, rl2, HALF, D, use512, sort);      \
                g->nb_start[i] = pos;                                                                        \
                g->nb_num[i] = (uint32_t)k;                                                                  \
                if (k <= room)                                                                               \
                    pos += k;                                                                                \
                else {                                                                                       \
                    pos = end;                                                                               \
                    over |= 1;                                                                               \
                }                                                                                            \
            }                                                                                                \
        }                                                                                                    \
        return !over;                                                                                        \
    }
FILL_FN(psys__pair_fill_2, 2, false)
FILL_FN(psys__pair_fill_3, 3, false)
FILL_FN(psys__pair_fill_2h, 2, true)
FILL_FN(psys__pair_fill_3h, 3, true)

void psys__pair_sort_list(const psys_system *sys, uint32_t *a, size_t n)
{
    uint32_t tmp[SORT_MAX];
#ifdef PSYS_SCAN_AVX512
    if (psys__pair_scan_has_avx512(sys) && sort_avx512(a, n))
        return;
#endif
    psys__pair_sort_indices(a, n, tmp);
}
