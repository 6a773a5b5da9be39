/* Grid method of pair forces: cell lists (spatial buckets) and Verlet
 * neighbour lists with a skin.
 *
 * A build sorts the particles into cells at least (cutoff + skin)/2 wide
 * (counting sort, so each cell lists its particles in increasing index) and
 * gives every particle the list of partners within cutoff + skin (all of
 * them, or only those of higher index: pair.h), sorted by index (the force
 * sum is then the direct method's, bit for bit). A particle scans the cells
 * within two cells of its own whose nearest point is within cutoff + skin of
 * it. The lists stay valid until the two largest displacements since the
 * build add up to the skin (no pair can have closed its gap by more), the
 * particle count, the box or the kind of list wanted changes; then they are
 * rebuilt. Periodic axes:
 * the cells tile the box exactly and wrap around; distances use the minimum
 * image. Free axes: the cells span the particles' bounding box. The number
 * of cells is capped at about twice the number of particles (cells grow
 * wider for sparse or far-flung clouds), so storage is O(n) and a build
 * O(n) at bounded density.
 *
 * Lists are written in one pass: particles are cut into chunks of
 * CHUNK consecutive indices, each chunk writes into its own region of the
 * list array, sized from the previous build's neighbours per particle; a
 * region that overflows makes the build resize the regions and run again
 * (this, and a growing system, are the only times the array grows). With
 * AVX-512, full lists are filled cell by cell instead (fill_by_cells):
 * each particle gets a slot as long as the last build's longest list plus
 * eight (or 1.2 times its mean plus twelve, if more), and a longer list
 * makes the build run again with slots that fit it. */
#include "pair/pair.h"

#include <stdlib.h>
#include <string.h>

#define CHUNK 128

void psys__pair_grid_free(pair_grid *g)
{
    free(g->xref);
    free(g->cell_start);
    free(g->cell_of);
    free(g->cell_list);
    free(g->cell_x);
    free(g->nb_start);
    free(g->nb_num);
    free(g->nb);
    free(g->chunk_off);
    free(g->fcache);
    free(g->xcache);
    free(g->mark);
    free(g->changed);
    free(g->nb2);
    free(g->nb_start2);
    free(g->tcnt);
    free(g->xq_mem);
    free(g->gl);
    free(g->gl_num);
    free(g->gl_start);
    free(g->win);
    memset(g, 0, sizeof *g);
}

bool psys__pair_grid_reserve(pair_grid *g, size_t cap, int dim)
{
    void *q;
    g->built_n = 0; /* storage changes: rebuild at the next evaluation */
    g->cache_ok = false;
    g->gl_ok = false;
    g->xq_cached = false;
#define GROW(field, count, type)                            \
    if (!(q = psys__realloc(g->field, (count), sizeof(type)))) \
        return false;                                       \
    g->field = q;
    GROW(xref, cap * (size_t)dim, double)
    GROW(fcache, cap * (size_t)dim, double)
    GROW(xcache, cap * (size_t)dim, double)
    GROW(cell_x, cap * (size_t)dim, double)
    g->cx_stride = cap;
    GROW(cell_of, cap, uint32_t)
    GROW(cell_list, cap, uint32_t)
    GROW(nb_start, cap, size_t)
    GROW(nb_start2, cap, size_t)
    GROW(nb_num, cap, uint32_t)
    GROW(gl_num, cap, uint32_t)
    GROW(changed, cap, uint32_t)
    GROW(xq_mem, cap * 4 + 4, double)
    g->xq = (double *)(((uintptr_t)g->xq_mem + 31) & ~(uintptr_t)31);
    GROW(mark, cap, unsigned char)
    size_t cells = 2 * cap + 64, chunks = cap / CHUNK + 2;
    GROW(cell_start, cells + 1, uint32_t)
    GROW(chunk_off, chunks + 1, size_t)
#undef GROW
    memset(g->mark, 0, cap);
    g->cells_cap = cells;
    g->chunks_cap = chunks;
    return true;
}

static bool box_equal(const psys__box *a, const psys__box *b)
{
    if (a->on != b->on || a->any_periodic != b->any_periodic)
        return false;
    for (int k = 0; k < 3; k++)
        if (a->periodic[k] != b->periodic[k] || a->lo[k] != b->lo[k] || a->hi[k] != b->hi[k])
            return false;
    return true;
}

/* Coordinate of x on axis k relative to the cell origin, wrapped on periodic axes. */
static inline double cell_rel(const pair_grid *g, const pair_image *m, int k, double x)
{
    double t = x - g->cell_lo[k];
    if (m->per[k] && !(t >= 0 && t < m->len[k]))
        t -= m->len[k] * floor(t / m->len[k]);
    return t;
}

static inline int cell_coord(const pair_grid *g, int k, double t)
{
    double c = floor(t / g->cell_size[k]);
    if (!(c >= 0)) /* also NaN */
        c = 0;
    if (c > g->ncell[k] - 1)
        c = g->ncell[k] - 1;
    return (int)c;
}

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
#define SORT_MAX 512
static void sort_indices(uint32_t *a, size_t n, uint32_t *tmp)
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

#if (defined(__GNUC__) || defined(__clang__)) && defined(__x86_64__)
#include <immintrin.h>
#define PSYS_SCAN_AVX512 1
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
 * is filled, in cache, beat sorting all of them by transposition (LJ melt,
 * 32,000 atoms: 251.8 against 272.4 ns per atom-step, bench/README). */
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
__attribute__((target("avx512f"))) static bool sort_avx512_to(const uint32_t *a, size_t n, uint32_t *dst)
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

__attribute__((target("avx512f"))) static bool sort_avx512(uint32_t *a, size_t n) { return sort_avx512_to(a, n, a); }

/* List a[0..n) sorted into nb's slot of particle i (n <= room), or only
 * counted if longer (tmp: SORT_MAX entries of scratch). */
__attribute__((target("avx512f"))) static void list_store(pair_grid *g, size_t i, uint32_t *a, size_t n, size_t room,
                                                           uint32_t *tmp)
{
    if (n <= room && !sort_avx512_to(a, n, g->nb + i * room)) {
        sort_indices(a, n, tmp);
        memcpy(g->nb + i * room, a, n * sizeof(uint32_t));
    }
    g->nb_num[i] = (uint32_t)n;
}
#endif

/* Whether scan_avx512 and sort_avx512 may run here (once per build).
 * PSYS_SCAN_PLAIN in the environment forces the portable scan and the
 * sorting by transposition, so the tests cover both paths on any machine
 * (the results are the same). */
static bool scan_has_avx512(void)
{
#ifdef PSYS_SCAN_AVX512
    return __builtin_cpu_supports("avx512f") && !getenv("PSYS_SCAN_PLAIN");
#else
    return false;
#endif
}

/* Cells around a particle's own, per axis: offsets -2..2 (pruned by the
 * particle's distance to them), or, on a periodic axis of fewer than five
 * cells, each cell once (offsets 0..n-1, not pruned). */
typedef struct stencil {
    int n[3];
    int off[3][5];
    bool prune[3];
} stencil;

/* Cell index v on axis k (possibly one box out) wrapped into the grid on a
 * periodic axis, with *sh the shift at which that cell's image lies (its
 * particles' coordinates + *sh); -1 outside a free axis. */
static inline int wrap_cell(const pair_grid *g, const pair_image *m, int k, int v, double *sh)
{
    const int nk = g->ncell[k];
    *sh = 0;
    if (m->per[k]) {
        if (v < 0) {
            *sh = -m->len[k];
            return v + nk;
        }
        if (v >= nk) {
            *sh = m->len[k];
            return v - nk;
        }
        return v;
    }
    return v < 0 || v >= nk ? -1 : v;
}

/* Coordinate k of particle i as the builds see it: wrapped into the box on
 * periodic axes (lo + t), the position itself on free axes. */
static inline double build_coord(const pair_grid *g, const pair_image *m, int k, double x)
{
    return m->per[k] ? g->cell_lo[k] + cell_rel(g, m, k, x) : x;
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
            sort_indices(out, cnt, tmp);
    }
    return cnt;
}

/* Fill the lists of every chunk into its region; true if none overflowed. */
#define FILL_FN(name, D, HALF)                                                                               \
    static bool name(pair_force *p, const stencil *sc, const pair_image *m, const double *x, size_t n,       \
                     size_t nchunks, double rl2, int nt, bool sort)                                          \
    {                                                                                                        \
        pair_grid *g = &p->grid;                                                                             \
        int over = 0;                                                                                        \
        const bool use512 = scan_has_avx512();                                                               \
        const unsigned char *own = p->sys->own_mark; /* MPI domain (mpi_domain.c): owned rows only */          \
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
FILL_FN(fill_2, 2, false)
FILL_FN(fill_3, 3, false)
FILL_FN(fill_2h, 2, true)
FILL_FN(fill_3h, 3, true)

#ifdef PSYS_SCAN_AVX512
/* Full lists cell by cell (AVX-512, no periodic axis of fewer than five
 * cells): the candidates around each home cell are loaded once for all its
 * particles (fill_line's sliding window; run by run, CELL_HOME particles
 * at a time, in fill_cell where the window does not fit) instead of once
 * per particle, each particle's partners collected in a scratch list,
 * sorted and written to its slot, nb[i·room ...]. Cells are pruned by their distance
 * to the home cell, which keeps every cell a particle's own pruning
 * (visit_d) keeps; the test per pair is scan_avx512's on the same numbers,
 * so the lists are the same. Returns the longest list (the caller grows
 * room and runs it again if that is more), or SIZE_MAX if some list passed
 * CELL_LIST (the caller uses fill_* then). */
#define CELL_HOME 16
#define CELL_LIST SORT_MAX

/* The candidates of a line of home cells (fill_line): the cells of up to
 * five slabs (one y index each) around the current home cell, each slab's
 * runs of cells appended as its cells' coordinates, their image shifts and
 * indices; sliding to the next home cell drops the first slab and appends
 * one, so each candidate is copied once per line instead of once per home
 * cell. Entries [start, end) are live; sixteen past end are padding. */
#define WIN_CAP 2048
typedef struct cand_win {
    double x[3][WIN_CAP + 16], s[3][WIN_CAP + 16];
    float xf[3][WIN_CAP + 16]; /* single precision: the candidates' images x + s */
    uint32_t j[WIN_CAP + 16];
    size_t start, end;
} cand_win;

/* The single-precision window (window_list_f): each candidate stored as
 * its image x_j + s rounded to float, tested against one threshold hi above
 * the list radius that no pair within the radius can reach through the
 * roundings (win_float_limit), so the lists hold every pair they must and
 * at most a few more just outside the radius (which the kernels cut at the
 * cutoff, as they cut the skin's pairs). Sixteen candidates per instruction
 * instead of eight, half the bytes; used when that margin is small, i.e.
 * coordinates are not too large against the radius. */
typedef struct win_mode {
    bool f32;
    float hi;
} win_mode;

/* Home slot sl's list from the window's nu entries at x/s/j (each pointing
 * at the first live one), into out (CELL_LIST + 16 entries); returns its
 * length (past CELL_LIST: counted, not stored). The test is scan_avx512's
 * on the same numbers, (x_i − shift) − x_j, except that a window without
 * shifts skips the exact subtraction of 0. */
__attribute__((target("avx512f"), always_inline)) static inline size_t
window_list(const pair_grid *g, size_t sl, const double *const x[3], const double *const sh[3], const uint32_t *uj,
            size_t nu, double rl2, uint32_t *out, const int d, const bool shifted)
{
    const size_t stride = g->cx_stride;
    const __m512d X0 = _mm512_set1_pd(g->cell_x[sl]), X1 = _mm512_set1_pd(g->cell_x[stride + sl]);
    const __m512d X2 = _mm512_set1_pd(d == 3 ? g->cell_x[2 * stride + sl] : 0);
    const __m512d vlim = _mm512_set1_pd(rl2), zero = _mm512_setzero_pd();
    const __m512i vi = _mm512_set1_epi32((int)g->cell_list[sl]);
    size_t cnt = 0;
    for (size_t t = 0; t < nu; t += 16) {
        __mmask16 ok = 0;
        for (int half = 0; half < 2; half++) {
            const size_t q = t + 8 * (size_t)half;
            __m512d a = shifted ? _mm512_sub_pd(X0, _mm512_loadu_pd(sh[0] + q)) : X0;
            __m512d dx = _mm512_sub_pd(a, _mm512_loadu_pd(x[0] + q));
            __m512d r2 = _mm512_add_pd(zero, _mm512_mul_pd(dx, dx));
            a = shifted ? _mm512_sub_pd(X1, _mm512_loadu_pd(sh[1] + q)) : X1;
            dx = _mm512_sub_pd(a, _mm512_loadu_pd(x[1] + q));
            r2 = _mm512_add_pd(r2, _mm512_mul_pd(dx, dx));
            if (d == 3) {
                a = shifted ? _mm512_sub_pd(X2, _mm512_loadu_pd(sh[2] + q)) : X2;
                dx = _mm512_sub_pd(a, _mm512_loadu_pd(x[2] + q));
                r2 = _mm512_add_pd(r2, _mm512_mul_pd(dx, dx));
            }
            ok |= (__mmask16)((unsigned)_mm512_cmp_pd_mask(r2, vlim, _CMP_LT_OQ) << (8 * half));
        }
        const __m512i j = _mm512_loadu_si512(uj + t);
        ok &= _mm512_cmpneq_epu32_mask(j, vi);
        if (cnt <= CELL_LIST)
            _mm512_storeu_si512(out + cnt, _mm512_maskz_compress_epi32(ok, j));
        cnt += (size_t)__builtin_popcount((unsigned)ok);
    }
    return cnt;
}

/* window_list on the single-precision window (win_mode): the images'
 * squared distances in float, ((dx² + dy²) + dz²), below hi. */
__attribute__((target("avx512f"), always_inline)) static inline size_t
window_list_f(const pair_grid *g, size_t sl, const float *const x[3], const uint32_t *uj, size_t nu, float hi,
              uint32_t *out, const int d)
{
    const size_t stride = g->cx_stride;
    const __m512 X0 = _mm512_set1_ps((float)g->cell_x[sl]), X1 = _mm512_set1_ps((float)g->cell_x[stride + sl]);
    const __m512 X2 = _mm512_set1_ps(d == 3 ? (float)g->cell_x[2 * stride + sl] : 0.0f);
    const __m512 vlim = _mm512_set1_ps(hi);
    const __m512i vi = _mm512_set1_epi32((int)g->cell_list[sl]);
    size_t cnt = 0;
    for (size_t t = 0; t < nu; t += 16) {
        __m512 dx = _mm512_sub_ps(X0, _mm512_loadu_ps(x[0] + t));
        __m512 r2 = _mm512_mul_ps(dx, dx);
        dx = _mm512_sub_ps(X1, _mm512_loadu_ps(x[1] + t));
        r2 = _mm512_add_ps(r2, _mm512_mul_ps(dx, dx));
        if (d == 3) {
            dx = _mm512_sub_ps(X2, _mm512_loadu_ps(x[2] + t));
            r2 = _mm512_add_ps(r2, _mm512_mul_ps(dx, dx));
        }
        const __m512i j = _mm512_loadu_si512(uj + t);
        const __mmask16 ok = _mm512_cmp_ps_mask(r2, vlim, _CMP_LT_OQ) & _mm512_cmpneq_epu32_mask(j, vi);
        if (cnt <= CELL_LIST)
            _mm512_storeu_si512(out + cnt, _mm512_maskz_compress_epi32(ok, j));
        cnt += (size_t)__builtin_popcount((unsigned)ok);
    }
    return cnt;
}

/* Append candidates [t0, t1) of cell_x/cell_list with image shift sh[] to
 * the window, moving the live entries to the front when the end is reached;
 * false if they do not fit even then. Whole vectors are stored (the
 * padding past the end takes what spills): masked stores were a fifth of
 * the fill's time. */
__attribute__((target("avx512f"), always_inline)) static inline bool
window_add(const pair_grid *g, cand_win *w, uint32_t t0, uint32_t t1, const double sh[3], const int d,
           const bool f32)
{
    const size_t len = t1 - t0;
    if (len > WIN_CAP - w->end) {
        const size_t live = w->end - w->start;
        if (len > WIN_CAP - live)
            return false;
        for (int k = 0; k < 3; k++) {
            if (f32) {
                memmove(w->xf[k], w->xf[k] + w->start, live * sizeof(float));
                continue;
            }
            memmove(w->x[k], w->x[k] + w->start, live * sizeof(double));
            memmove(w->s[k], w->s[k] + w->start, live * sizeof(double));
        }
        memmove(w->j, w->j + w->start, live * sizeof(uint32_t));
        w->start = 0;
        w->end = live;
    }
    const size_t at = w->end;
    for (size_t q = 0; q < len; q += 8) {
        const __mmask8 live = len - q >= 8 ? (__mmask8)0xff : (__mmask8)((1u << (len - q)) - 1);
        for (int k = 0; k < d; k++) {
            const __m512d c = _mm512_maskz_loadu_pd(live, g->cell_x + (size_t)k * g->cx_stride + t0 + q);
            if (f32) {
                _mm256_storeu_ps(w->xf[k] + at + q, _mm512_cvtpd_ps(_mm512_add_pd(c, _mm512_set1_pd(sh[k]))));
                continue;
            }
            _mm512_storeu_pd(w->x[k] + at + q, c);
            _mm512_storeu_pd(w->s[k] + at + q, _mm512_set1_pd(sh[k]));
        }
        _mm256_storeu_si256((__m256i *)(w->j + at + q),
                            _mm512_castsi512_si256(_mm512_maskz_loadu_epi32((__mmask16)live, g->cell_list + t0 + q)));
    }
    w->end = at + len;
    return true;
}

/* The neighbours of cell coordinate c on axis k, for offsets sc->off[k]:
 * wrapped cell (-1 outside a free axis), image shift, squared gap. */
static void cell_offsets(const pair_grid *g, const stencil *sc, const pair_image *m, int k, int c, int d, int wc[5],
                         double img[5], double gap2[5])
{
    for (int a = 0; a < sc->n[k]; a++) {
        const int o = sc->off[k][a];
        const double gap = o == 0 ? 0 : (double)(abs(o) - 1) * g->cell_size[k];
        wc[a] = wrap_cell(g, m, k, c + o, &img[a]);
        gap2[a] = k < d ? gap * gap : 0;
    }
}

/* The end of the run of x cells from a0 on: cells next to each other in
 * memory (wrapped indices consecutive), with the same image shift, none
 * pruned (gap2 past lim with the other axes' squared gaps g). */
static inline int run_end(const int wc[5], const double img[5], const double gap2[5], int n, int a0, double g,
                          double lim)
{
    int e0 = a0 + 1;
    while (e0 < n && wc[e0] == wc[e0 - 1] + 1 && img[e0] == img[a0] && !(g + gap2[e0] > lim))
        e0++;
    return e0;
}

/* fill_by_cells for home cell c, run by run (where fill_line's window
 * would not fit): the longest of its lists, or SIZE_MAX if some list passed
 * CELL_LIST. */
__attribute__((target("avx512f"))) static size_t fill_cell(pair_grid *g, const stencil *sc, const pair_image *m,
                                                            size_t c, size_t room, double rl2, const int d)
{
    const size_t stride = g->cx_stride;
    const double lim = rl2 * (1 + 1e-6);
    size_t longest = 0;
    const uint32_t s0 = g->cell_start[c], s1 = g->cell_start[c + 1];
    if (s0 == s1)
        return 0;
    uint32_t buf[CELL_HOME][CELL_LIST + 8], tmp[SORT_MAX];
    int cc[3] = {(int)(c % (size_t)g->ncell[0]), (int)(c / (size_t)g->ncell[0] % (size_t)g->ncell[1]),
                 (int)(c / ((size_t)g->ncell[0] * (size_t)g->ncell[1]))};
    int wc[3][5];
    double img[3][5], gap2[3][5];
    for (int k = 0; k < 3; k++)
        cell_offsets(g, sc, m, k, cc[k], d, wc[k], img[k], gap2[k]);
    for (uint32_t h0 = s0; h0 < s1; h0 += CELL_HOME) {
        const int nh = s1 - h0 < CELL_HOME ? (int)(s1 - h0) : CELL_HOME;
        size_t cnt[CELL_HOME];
        for (int h = 0; h < nh; h++)
            cnt[h] = 0;
        const int nz = d == 3 ? sc->n[2] : 1;
        for (int a2 = 0; a2 < nz; a2++) {
            const int z = wc[2][a2];
            if (gap2[2][a2] > lim || z < 0)
                continue;
            for (int a1 = 0; a1 < sc->n[1]; a1++) {
                const double gyz = gap2[2][a2] + gap2[1][a1];
                const int y = wc[1][a1];
                if (gyz > lim || y < 0)
                    continue;
                const size_t row = (size_t)g->ncell[0] * ((size_t)y + (size_t)g->ncell[1] * (size_t)z);
                for (int a0 = 0; a0 < sc->n[0];) {
                    const int xx = wc[0][a0];
                    if (gyz + gap2[0][a0] > lim || xx < 0) {
                        a0++;
                        continue;
                    }
                    const int e0 = run_end(wc[0], img[0], gap2[0], sc->n[0], a0, gyz, lim);
                    const uint32_t t0 = g->cell_start[row + (size_t)xx];
                    const uint32_t t1 = g->cell_start[row + (size_t)wc[0][e0 - 1] + 1];
                    /* the home particles' build coordinates less the run's image shift */
                    __m512d hx[CELL_HOME][3];
                    __m512i hi[CELL_HOME];
                    for (int h = 0; h < nh; h++) {
                        const size_t sl = (size_t)h0 + (size_t)h;
                        hx[h][0] = _mm512_set1_pd(g->cell_x[sl] - img[0][a0]);
                        hx[h][1] = _mm512_set1_pd(g->cell_x[stride + sl] - img[1][a1]);
                        hx[h][2] = _mm512_set1_pd(d == 3 ? g->cell_x[2 * stride + sl] - img[2][a2] : 0);
                        hi[h] = _mm512_set1_epi64((long long)g->cell_list[sl]);
                    }
                    const __m512d vlim = _mm512_set1_pd(rl2), zero = _mm512_setzero_pd();
                    for (uint32_t t = t0; t < t1; t += 8) {
                        const __mmask8 live = t1 - t >= 8 ? (__mmask8)0xff : (__mmask8)((1u << (t1 - t)) - 1);
                        const __m512d c0 = _mm512_maskz_loadu_pd(live, g->cell_x + t);
                        const __m512d c1 = _mm512_maskz_loadu_pd(live, g->cell_x + stride + t);
                        const __m512d c2 = d == 3 ? _mm512_maskz_loadu_pd(live, g->cell_x + 2 * stride + t) : zero;
                        const __m512i j = _mm512_cvtepu32_epi64(
                            _mm512_castsi512_si256(_mm512_maskz_loadu_epi32((__mmask16)live, g->cell_list + t)));
                        for (int h = 0; h < nh; h++) {
                            __m512d dx = _mm512_sub_pd(hx[h][0], c0);
                            __m512d r2 = _mm512_add_pd(zero, _mm512_mul_pd(dx, dx));
                            dx = _mm512_sub_pd(hx[h][1], c1);
                            r2 = _mm512_add_pd(r2, _mm512_mul_pd(dx, dx));
                            if (d == 3) {
                                dx = _mm512_sub_pd(hx[h][2], c2);
                                r2 = _mm512_add_pd(r2, _mm512_mul_pd(dx, dx));
                            }
                            const __mmask8 ok = live & _mm512_cmp_pd_mask(r2, vlim, _CMP_LT_OQ)
                                                & _mm512_cmpneq_epu64_mask(j, hi[h]);
                            if (cnt[h] <= CELL_LIST)
                                _mm256_storeu_si256((__m256i *)(buf[h] + cnt[h]),
                                                    _mm512_cvtepi64_epi32(_mm512_maskz_compress_epi64(ok, j)));
                            cnt[h] += (size_t)__builtin_popcount((unsigned)ok);
                        }
                    }
                    a0 = e0;
                }
            }
        }
        for (int h = 0; h < nh; h++) {
            const size_t i = g->cell_list[h0 + (uint32_t)h];
            if (cnt[h] > CELL_LIST)
                return SIZE_MAX;
            list_store(g, i, buf[h], cnt[h], room, tmp);
            longest = cnt[h] > longest ? cnt[h] : longest;
        }
    }
    return longest;
}

/* fill_by_cells for the line of home cells (cx, 0..ny-1, cz), sliding a
 * window of slabs along y (the stencil's five y offsets; cells pruned by
 * their gap in x and z only, a superset of what each home cell keeps): the
 * longest list, or SIZE_MAX if some list passed CELL_LIST. Where the window
 * would pass WIN_CAP, the rest of the line goes cell by cell (fill_cell). */
__attribute__((target("avx512f"))) static size_t fill_line(pair_grid *g, const stencil *sc, const pair_image *m,
                                                            int cx, int cz, size_t room, double rl2, const int d,
                                                            cand_win *w, const win_mode wm)
{
    const double lim = rl2 * (1 + 1e-6);
    const int nx = g->ncell[0], ny = g->ncell[1];
    int wc0[5], wc2[5] = {0};
    double img0[5], gap0[5], img2[5] = {0}, gap2z[5] = {0};
    cell_offsets(g, sc, m, 0, cx, d, wc0, img0, gap0);
    if (d == 3)
        cell_offsets(g, sc, m, 2, cz, d, wc2, img2, gap2z);
    const int nzo = d == 3 ? sc->n[2] : 1;
    size_t blk[8] = {0}, longest = 0;
    bool bsh[8] = {false}, broken = false;
    uint32_t out[CELL_LIST + 16], tmp[SORT_MAX];
    w->start = w->end = 0;
    /* slab `add` (unwrapped y) enters at slot add & 7; then home cell add - 2 */
    for (int add = -2; add < ny + 2; add++) {
        if (!broken) {
            const size_t before = w->end - w->start; /* live entries before the slab */
            double sy;
            const int wy = wrap_cell(g, m, 1, add, &sy);
            const bool valid = wy >= 0;
            bool any = false;
            for (int a2 = 0; a2 < nzo && valid && !broken; a2++) {
                const int z = d == 3 ? wc2[a2] : 0;
                if (gap2z[a2] > lim || z < 0)
                    continue;
                const size_t row = (size_t)nx * ((size_t)wy + (size_t)ny * (size_t)z);
                for (int a0 = 0; a0 < sc->n[0] && !broken;) {
                    const int xx = wc0[a0];
                    if (gap2z[a2] + gap0[a0] > lim || xx < 0) {
                        a0++;
                        continue;
                    }
                    const int e0 = run_end(wc0, img0, gap0, sc->n[0], a0, gap2z[a2], lim);
                    const double sh[3] = {img0[a0], sy, img2[a2]};
                    any |= sh[0] != 0 || sh[1] != 0 || sh[2] != 0;
                    broken = !window_add(g, w, g->cell_start[row + (size_t)xx],
                                         g->cell_start[row + (size_t)wc0[e0 - 1] + 1], sh, d, wm.f32);
                    a0 = e0;
                }
            }
            blk[add & 7] = w->end - w->start - before;
            bsh[add & 7] = any;
        }
        if (add < 2)
            continue;
        const int cy = add - 2;
        const size_t c = (size_t)cx + (size_t)nx * ((size_t)cy + (size_t)ny * (size_t)cz);
        const uint32_t s0 = g->cell_start[c], s1 = g->cell_start[c + 1];
        if (broken) {
            const size_t l = fill_cell(g, sc, m, c, room, rl2, d);
            if (l == SIZE_MAX)
                return SIZE_MAX;
            longest = l > longest ? l : longest;
            continue;
        }
        const size_t nu = w->end - w->start;
        bool shifted = false;
        for (int o = cy - 2; o <= cy + 2; o++)
            shifted |= bsh[(o + 8) & 7];
        if (s0 < s1) {
            /* padding past the end, in the arrays this window reads */
            for (size_t q = w->end; q < w->end + 16; q++) {
                for (int k = 0; k < 3; k++) {
                    if (wm.f32) {
                        w->xf[k][q] = NAN;
                        continue;
                    }
                    w->x[k][q] = NAN;
                    w->s[k][q] = 0;
                }
                w->j[q] = 0;
            }
            const double *const xs[3] = {w->x[0] + w->start, w->x[1] + w->start, w->x[2] + w->start};
            const double *const ss[3] = {w->s[0] + w->start, w->s[1] + w->start, w->s[2] + w->start};
            const uint32_t *js = w->j + w->start;
            const float *const xf[3] = {w->xf[0] + w->start, w->xf[1] + w->start, w->xf[2] + w->start};
            for (uint32_t sl = s0; sl < s1; sl++) {
                const size_t cnt = wm.f32 ? (d == 3 ? window_list_f(g, sl, xf, js, nu, wm.hi, out, 3)
                                                    : window_list_f(g, sl, xf, js, nu, wm.hi, out, 2))
                                   : d == 3 ? (shifted ? window_list(g, sl, xs, ss, js, nu, rl2, out, 3, true)
                                                     : window_list(g, sl, xs, ss, js, nu, rl2, out, 3, false))
                                          : (shifted ? window_list(g, sl, xs, ss, js, nu, rl2, out, 2, true)
                                                     : window_list(g, sl, xs, ss, js, nu, rl2, out, 2, false));
                if (cnt > CELL_LIST)
                    return SIZE_MAX;
                list_store(g, g->cell_list[sl], out, cnt, room, tmp);
                longest = cnt > longest ? cnt : longest;
            }
        }
        w->start += blk[(cy - 2 + 8) & 7]; /* the slab cy - 2 leaves */
    }
    return longest;
}

/* The single-precision window's threshold for list radius² rl2 when every
 * build coordinate and image x + s is at most B in size (u = 2⁻²⁴): each of
 * x_i and x_j + s is off by at most B·u as a float, their difference by
 * |d_k|·u more, so |δ_k − d_k| ≤ E = (2B + rl)·u (with a margin) for
 * |d_k| ≤ rl; then Σ δ_k² ≤ d² + 2√3·rl·E + 3E², and the three products and
 * two sums add at most (1 + u)³. No float window where that margin passes a
 * thousandth of rl2 (huge coordinates against the radius) or with
 * PSYS_WINDOW_DOUBLE set (so the tests reach the double window). */
static win_mode win_float_limit(double rl2, double B)
{
    win_mode wm = {false, 0};
    const double u = 0x1p-24, rl = sqrt(rl2), E = (2 * B + rl) * u * 1.001;
    const double hi = (rl2 + 3.5 * rl * E + 3 * E * E) * (1 + 4 * u);
    if (!(hi - rl2 <= 1e-3 * rl2) || getenv("PSYS_WINDOW_DOUBLE"))
        return wm;
    wm.f32 = true;
    wm.hi = nextafterf((float)hi, INFINITY);
    return wm;
}

static size_t fill_by_cells(pair_force *p, const stencil *sc, const pair_image *m, size_t n, size_t room,
                            double rl2, double scale, int nt, int d)
{
    pair_grid *g = &p->grid;
    /* build coordinates lie within scale of 0, their images within 2·scale */
    const win_mode wm = win_float_limit(rl2, 2 * scale);
    const size_t nlines = (size_t)g->ncell[0] * (size_t)g->ncell[2];
    size_t longest = 0;
    if (nt < 1)
        nt = 1;
    if ((size_t)nt > g->win_n) {
        free(g->win);
        g->win = psys__realloc(NULL, (size_t)nt, sizeof(cand_win));
        g->win_n = g->win ? (size_t)nt : 0;
        if (!g->win)
            return SIZE_MAX; /* the fill below instead */
    }
    cand_win *wins = g->win;
    (void)nt;
    PSYS_OMP(omp parallel for schedule(static) num_threads(nt) if (nt > 1 && n >= PSYS_PAR_MIN))
    for (size_t i = 0; i < n; i++) {
        g->nb_start[i] = i * room;
        g->nb_num[i] = 0;
    }
    PSYS_OMP(omp parallel num_threads(nt) if (nt > 1))
    {
#ifdef _OPENMP
        cand_win *w = wins + omp_get_thread_num();
#else
        cand_win *w = wins;
#endif
        PSYS_OMP(omp for schedule(dynamic, 2) reduction(max: longest))
        for (size_t L = 0; L < nlines; L++) {
            const int cx = (int)(L % (size_t)g->ncell[0]), cz = (int)(L / (size_t)g->ncell[0]);
            const size_t l = d == 3 ? fill_line(g, sc, m, cx, cz, room, rl2, 3, w, wm)
                                    : fill_line(g, sc, m, cx, cz, room, rl2, 2, w, wm);
            longest = l > longest ? l : longest; /* SIZE_MAX stays */
        }
    }
    return longest;
}
#endif

void psys__pair_sort_list(uint32_t *a, size_t n)
{
    uint32_t tmp[SORT_MAX];
#ifdef PSYS_SCAN_AVX512
    if (scan_has_avx512() && sort_avx512(a, n))
        return;
#endif
    sort_indices(a, n, tmp);
}

void psys__pair_grid_mark_near(const pair_grid *g, const pair_image *m, int d, uint32_t c, const unsigned char *own,
                               unsigned char *mark)
{
    uint32_t cell = g->cell_of[c];
    int cc[3] = {0, 0, 0}, lo[3] = {0, 0, 0}, hi[3] = {0, 0, 0};
    cc[0] = (int)(cell % (uint32_t)g->ncell[0]);
    cc[1] = (int)(cell / (uint32_t)g->ncell[0] % (uint32_t)g->ncell[1]);
    cc[2] = (int)(cell / ((uint32_t)g->ncell[0] * (uint32_t)g->ncell[1]));
    for (int k = 0; k < 3; k++) {
        if (k >= d) {
            lo[k] = hi[k] = 0;
        } else if (m->per[k] && g->ncell[k] < 5) {
            lo[k] = -cc[k];
            hi[k] = g->ncell[k] - 1 - cc[k];
        } else {
            lo[k] = -2;
            hi[k] = 2;
        }
    }
    for (int a2 = lo[2]; a2 <= hi[2]; a2++)
        for (int a1 = lo[1]; a1 <= hi[1]; a1++)
            for (int a0 = lo[0]; a0 <= hi[0]; a0++) {
                int w[3] = {cc[0] + a0, cc[1] + a1, cc[2] + a2}, skip = 0;
                for (int k = 0; k < d; k++) {
                    if (m->per[k])
                        w[k] = (w[k] % g->ncell[k] + g->ncell[k]) % g->ncell[k];
                    else if (w[k] < 0 || w[k] >= g->ncell[k])
                        skip = 1;
                }
                if (skip)
                    continue;
                size_t q = (size_t)w[0] + (size_t)g->ncell[0] * ((size_t)w[1] + (size_t)g->ncell[1] * (size_t)w[2]);
                for (uint32_t t = g->cell_start[q]; t < g->cell_start[q + 1]; t++) {
                    uint32_t i = g->cell_list[t];
                    if (own[i])
                        mark[i] |= 1;
                }
            }
}

/* A list array for at least `need` entries (never NULL: rows index into it
 * even when every list is empty); it grows by an eighth beyond the need, and
 * is left as it was if it cannot. */
static bool grow_lists(uint32_t **a, size_t *cap, size_t need)
{
    if (need <= *cap && *a)
        return true;
    size_t c = need + need / 8 + 64;
    uint32_t *q = psys__realloc(*a, c, sizeof(uint32_t));
    if (!q)
        return false;
    *a = q;
    *cap = c;
    return true;
}

/* Sort full lists by transposing them (where sort_avx512 does not run: no
 * AVX-512, or PSYS_SCAN_PLAIN set): j is in i's list exactly when i is in
 * j's (the scan's test is symmetric up to the rounding of periodic images,
 * which can only touch pairs at the list radius, beyond the cutoff), so
 * walking the lists in increasing j and appending j to the list of each i
 * found there writes every list in increasing order, in O(pairs) and with no
 * comparisons. In parallel, each of `parts` threads walks its own range of
 * j; a list receives the first range's entries first, so the order is the
 * same. The result goes to nb2, which then becomes nb. */
#define TRANSPOSE_PARTS_MAX 8
static bool transpose_lists(pair_grid *g, size_t n, int nt)
{
    size_t parts = nt > 1 && n >= 4096 ? (size_t)nt : 1;
    parts = parts > TRANSPOSE_PARTS_MAX ? TRANSPOSE_PARTS_MAX : parts;
    if (parts * n > g->tcnt_cap) { /* per part: its entries per list, then their offsets in the list */
        uint32_t *q = psys__realloc(g->tcnt, parts * n, sizeof(uint32_t));
        if (!q)
            return false;
        g->tcnt = q;
        g->tcnt_cap = parts * n;
    }
    uint32_t *cnt = g->tcnt, *newnum = g->changed; /* scratch: the cache is invalid after a build */
    PSYS_OMP(omp parallel for schedule(static, 1) num_threads((int)parts) if (parts > 1))
    for (size_t t = 0; t < parts; t++) {
        uint32_t *c = cnt + t * n;
        memset(c, 0, n * sizeof *c);
        for (size_t j = n * t / parts; j < n * (t + 1) / parts; j++) {
            const uint32_t *js = g->nb + g->nb_start[j];
            for (uint32_t q = 0; q < g->nb_num[j]; q++)
                c[js[q]]++;
        }
    }
    size_t total = 0;
    for (size_t i = 0; i < n; i++) {
        g->nb_start2[i] = total;
        uint32_t in = 0;
        for (size_t t = 0; t < parts; t++) {
            uint32_t c = cnt[t * n + i];
            cnt[t * n + i] = in;
            in += c;
        }
        newnum[i] = in;
        total += in;
    }
    if (!grow_lists(&g->nb2, &g->nb2_cap, total))
        return false;
    PSYS_OMP(omp parallel for schedule(static, 1) num_threads((int)parts) if (parts > 1))
    for (size_t t = 0; t < parts; t++) {
        uint32_t *off = cnt + t * n;
        for (size_t j = n * t / parts; j < n * (t + 1) / parts; j++) {
            const uint32_t *js = g->nb + g->nb_start[j];
            for (uint32_t q = 0; q < g->nb_num[j]; q++) {
                const uint32_t i = js[q];
                g->nb2[g->nb_start2[i] + off[i]++] = (uint32_t)j;
            }
        }
    }
    memcpy(g->nb_num, newnum, n * sizeof *newnum);
    size_t *st = g->nb_start;
    g->nb_start = g->nb_start2;
    g->nb_start2 = st;
    uint32_t *t = g->nb;
    g->nb = g->nb2;
    g->nb2 = t;
    size_t c = g->nb_cap;
    g->nb_cap = g->nb2_cap;
    g->nb2_cap = c;
    return true;
}

static bool build(pair_force *p, const psys_force_eval *e, const pair_image *m, bool half)
{
    pair_grid *g = &p->grid;
    const psys__box *box = &p->sys->box;
    const size_t n = e->n;
    const int d = p->dim;
    const double *x = e->x;
    g->built_n = 0;
    g->cache_ok = false;
    g->gl_ok = false;

    /* geometry: cells at least half the list radius wide (times 1 + 1e-9), at most cells_cap of them */
    const double rl = sqrt(p->rlist2), hcell = 0.5 * rl * (1.0 + 1e-9);
    double ext[3] = {0, 0, 0}, prod = 1;
    for (int k = 0; k < d; k++) {
        if (m->per[k]) {
            g->cell_lo[k] = box->lo[k];
            ext[k] = box->len[k];
        } else {
            double lo = INFINITY, hi = -INFINITY;
            for (size_t i = 0; i < n; i++) {
                double v = x[i * d + k];
                if (v < lo) lo = v;
                if (v > hi) hi = v;
            }
            if (!(lo <= hi) || !isfinite(hi - lo)) {
                lo = isfinite(lo) ? lo : 0;
                hi = lo;
            }
            g->cell_lo[k] = lo;
            ext[k] = hi - lo;
        }
        double want = floor(ext[k] / hcell);
        if (!(want >= 1))
            want = 1;
        if (want > (double)(1 << 20))
            want = (double)(1 << 20);
        g->ncell[k] = (int)want;
        prod *= want;
    }
    for (int k = d; k < 3; k++) {
        g->ncell[k] = 1;
        g->cell_lo[k] = 0;
    }
    while (prod > (double)g->cells_cap) {
        int big = 0;
        for (int k = 1; k < d; k++)
            if (g->ncell[k] > g->ncell[big])
                big = k;
        prod /= g->ncell[big];
        g->ncell[big] = g->ncell[big] / 2 > 1 ? g->ncell[big] / 2 : 1;
        prod *= g->ncell[big];
    }
    double vol = 1;
    for (int k = 0; k < 3; k++) {
        g->cell_size[k] = k < d && ext[k] > 0 ? ext[k] / g->ncell[k] : 1.0;
        if (k < d)
            vol *= ext[k] > 0 ? ext[k] : rl;
    }
    size_t ncells = (size_t)g->ncell[0] * (size_t)g->ncell[1] * (size_t)g->ncell[2];

    /* cells: counting sort, stable, so ascending indices within a cell */
    int nt = pair_threads(p, 4.0 * (double)n);
    (void)nt;
    PSYS_OMP(omp parallel for schedule(static) num_threads(nt) if (nt > 1))
    for (size_t i = 0; i < n; i++) {
        size_t c = 0, mul = 1;
        for (int k = 0; k < d; k++) {
            c += mul * (size_t)cell_coord(g, k, cell_rel(g, m, k, x[i * d + k]));
            mul *= (size_t)g->ncell[k];
        }
        g->cell_of[i] = (uint32_t)c;
    }
    memset(g->cell_start, 0, (ncells + 1) * sizeof(uint32_t));
    for (size_t i = 0; i < n; i++)
        g->cell_start[g->cell_of[i] + 1]++;
    for (size_t c = 0; c < ncells; c++)
        g->cell_start[c + 1] += g->cell_start[c];
    for (size_t i = 0; i < n; i++)
        g->cell_list[g->cell_start[g->cell_of[i]]++] = (uint32_t)i;
    for (size_t c = ncells; c > 0; c--)
        g->cell_start[c] = g->cell_start[c - 1];
    g->cell_start[0] = 0;
    PSYS_OMP(omp parallel for schedule(static) num_threads(nt) if (nt > 1))
    for (size_t t = 0; t < n; t++)
        for (int k = 0; k < d; k++)
            g->cell_x[(size_t)k * g->cx_stride + t] = build_coord(g, m, k, x[(size_t)g->cell_list[t] * d + k]);
    /* list radius with a slack for the rounding of build coordinates */
    double scale = 0;
    for (int k = 0; k < d; k++)
        scale = fmax(scale, fabs(g->cell_lo[k]) + ext[k]);
    const double rls = rl + 1e-13 * scale, rls2 = rls * rls;

    stencil sc;
    for (int k = 0; k < 3; k++) {
        if (k >= d) {
            sc.n[k] = 1;
            sc.off[k][0] = 0;
            sc.prune[k] = false;
        } else if (m->per[k] && g->ncell[k] < 5) {
            sc.n[k] = g->ncell[k];
            for (int a = 0; a < g->ncell[k]; a++)
                sc.off[k][a] = a;
            sc.prune[k] = false;
        } else {
            sc.n[k] = 5;
            for (int a = 0; a < 5; a++)
                sc.off[k][a] = a - 2;
            sc.prune[k] = true;
        }
    }

    /* neighbour lists: regions per chunk sized from the last build (or the
     * density), filled in one pass; on overflow sized exactly from the counts
     * the pass made, and filled again */
    if (!(g->per_particle > 0)) {
        double ball = d == 3 ? 4.18879020478639098 * rl * rl * rl : 3.14159265358979324 * rl * rl;
        g->per_particle = (double)n / vol * ball;
    }
    size_t nchunks = (n + CHUNK - 1) / CHUNK;
    int ntf = pair_threads(p, 64.0 * (double)n);
    /* full lists of every particle are sorted by transposing them (below),
     * not one by one, unless the AVX-512 sort does it as they are filled; a
     * domain's ghosts have no lists, so there they are sorted */
    const bool transpose = !half && !p->sys->own_mark && !scan_has_avx512();
    double per = g->per_particle * 1.2 + 4;
    if (!(per <= (double)n)) /* also NaN (a huge radius makes the density estimate inf·0) */
        per = (double)n;
    /* cell by cell where that runs (full lists, AVX-512, every axis pruned) */
    bool by_cells = !half && !p->sys->own_mark && scan_has_avx512();
    for (int k = 0; k < d; k++)
        by_cells = by_cells && sc.prune[k];
#ifdef PSYS_SCAN_AVX512
    if (by_cells) {
        size_t room = (size_t)per + 8;
        room = room > g->longest + 8 ? room : g->longest + 8;
        for (;;) {
            if (!(room <= SIZE_MAX / 2 / (n ? n : 1)) || !grow_lists(&g->nb, &g->nb_cap, n * room))
                return false;
            const size_t longest = fill_by_cells(p, &sc, m, n, room, rls2, scale, ntf, d);
            if (longest == SIZE_MAX) {
                by_cells = false; /* a list too long for the scratch: the fill below */
                break;
            }
            g->longest = longest;
            if (longest <= room)
                break;
            room = longest;
        }
    }
#else
    by_cells = false;
#endif
    for (int exact = 0; !by_cells; exact++) {
        g->chunk_off[0] = 0;
        for (size_t c = 0; c < nchunks; c++) {
            size_t i0 = c * CHUNK, i1 = i0 + CHUNK < n ? i0 + CHUNK : n, len = 0;
            if (exact)
                for (size_t i = i0; i < i1; i++)
                    len += g->nb_num[i];
            else
                len = (size_t)(per * (double)(i1 - i0)) + 16;
            g->chunk_off[c + 1] = g->chunk_off[c] + len;
        }
        if (!grow_lists(&g->nb, &g->nb_cap, g->chunk_off[nchunks]))
            return false;
        bool ok = half ? (d == 2 ? fill_2h(p, &sc, m, x, n, nchunks, rls2, ntf, true)
                                 : fill_3h(p, &sc, m, x, n, nchunks, rls2, ntf, true))
                       : (d == 2 ? fill_2(p, &sc, m, x, n, nchunks, rls2, ntf, !transpose)
                                 : fill_3(p, &sc, m, x, n, nchunks, rls2, ntf, !transpose));
        if (ok)
            break;
        if (exact)
            return false; /* cannot happen: the counts do not change */
    }
    if (transpose && !transpose_lists(g, n, ntf))
        return false;
    if (!half && !psys__pair_group_lists(p, n, ntf))
        return false;
    size_t total = 0, listed = 0;
    const unsigned char *own = p->sys->own_mark;
    for (size_t i = 0; i < n; i++) {
        total += g->nb_num[i];
        listed += !own || own[i];
    }
    g->per_particle = (double)total / (double)(listed ? listed : 1);
    p->stats.pairs = half ? total : total / 2;

    memcpy(g->xref, x, n * (size_t)d * sizeof(double));
    g->box = *box;
    g->built_n = n;
    g->half = half;
    p->stats.rebuilds++;
    p->stats.cells = ncells;
    return true;
}

/* Squared displacement of particle i since the last build (minimum image). */
static inline double moved2(const pair_image *m, const double *x, const double *xr, size_t i, int d)
{
    double r2 = 0;
    for (int k = 0; k < d; k++) {
        double dx = pair_delta(m, k, x[i * d + k] - xr[i * d + k]);
        r2 += dx * dx;
    }
    return r2;
}

/* Particle i's position differs (bitwise, up to NaN payloads) from the cached one. */
static inline bool moved_since(const double *x, const double *xc, size_t i, int d)
{
    for (int k = 0; k < d; k++) {
        double a = x[i * d + k], b = xc[i * d + k];
        if (a != b || signbit(a) != signbit(b))
            return true;
    }
    return false;
}

/* At most this many threads look for the moved particles of a cached evaluation. */
#define PAIR_MOVED_THREADS 64
/* Particles per block of the scans below: a block with nothing to report
 * is passed by one vectorised test. */
#define SCAN_BLOCK 64

/* Whether moved_since holds for any particle of components [k0, k1) of x
 * and xc (a != b, NaN included, or the signs differ), in a form the
 * vectoriser takes. */
PSYS_CLONES static bool block_moved(const double *x, const double *xc, size_t k0, size_t k1)
{
    uint64_t any = 0;
    for (size_t k = k0; k < k1; k++) {
        uint64_t a, b;
        memcpy(&a, x + k, sizeof a);
        memcpy(&b, xc + k, sizeof b);
        any |= (uint64_t)(x[k] != xc[k]) | ((a ^ b) >> 63);
    }
    return any != 0;
}

size_t psys__pair_grid_moved(pair_force *p, const double *x, size_t n)
{
    pair_grid *g = &p->grid;
    const int d = p->dim;
    /* each thread lists those of its static range at the range's start,
     * then the lists are joined */
    const int ntm = pair_threads(p, 2.0 * (double)n * (double)d);
    size_t at[PAIR_MOVED_THREADS + 1] = {0}, cnt[PAIR_MOVED_THREADS] = {0}, nc = 0;
    const int nm = ntm < PAIR_MOVED_THREADS ? ntm : PAIR_MOVED_THREADS;
    for (int t = 0; t <= nm; t++)
        at[t] = n * (size_t)t / (size_t)nm;
    PSYS_OMP(omp parallel for schedule(static, 1) num_threads(nm) if (nm > 1))
    for (int t = 0; t < nm; t++) {
        size_t c = 0;
        for (size_t i = at[t]; i < at[t + 1] && c <= n / 8;) {
            const size_t e = at[t + 1] - i > SCAN_BLOCK ? i + SCAN_BLOCK : at[t + 1];
            if (!block_moved(x, g->xcache, i * (size_t)d, e * (size_t)d)) {
                i = e;
                continue;
            }
            for (; i < e && c <= n / 8; i++)
                if (moved_since(x, g->xcache, i, d))
                    g->changed[at[t] + c++] = (uint32_t)i;
        }
        cnt[t] = c;
    }
    for (int t = 0; t < nm; t++) {
        if (nc + cnt[t] > n / 8) /* too many for a partial evaluation */
            return n / 8 + 1;
        memmove(g->changed + nc, g->changed + at[t], cnt[t] * sizeof(uint32_t));
        nc += cnt[t];
    }
    return nc;
}

/* The two largest of (*m1, *m2) and r2 (NaN: flagged in *bad). */
static inline void top_two(double r2, double *m1, double *m2, int *bad)
{
    const double lo = r2 < *m1 ? r2 : *m1;
    *bad |= !(r2 == r2);
    *m2 = lo > *m2 ? lo : *m2;
    *m1 = r2 > *m1 ? r2 : *m1;
}

/* top_two over the squared displacements (moved2) of particles [i0, i1),
 * eight lanes at a time, each lane keeping its own two largest, then
 * merged: the two largest of a set do not depend on the order, so the
 * same as one lane in index order. pair_delta_folded (exact) is
 * pair_delta, in a form the vectoriser takes. */
#define TOP_LANES 8
__attribute__((always_inline)) static inline void top_two_lanes(const pair_image *m, const double *x,
                                                                const double *xr, size_t i0, size_t i1, const int d,
                                                                double *m1, double *m2, int *bad)
{
    double hl[3], ln[3], il[3], fr[3];
    pair_image_fold(m, hl, ln, il, fr);
    double t1[TOP_LANES] = {0}, t2[TOP_LANES] = {0};
    int tb[TOP_LANES] = {0};
    size_t i = i0;
    for (; i1 - i >= TOP_LANES; i += TOP_LANES) {
        double r2[TOP_LANES];
        for (int l = 0; l < TOP_LANES; l++) {
            const size_t q = (i + (size_t)l) * (size_t)d;
            double s = 0;
            for (int k = 0; k < d; k++) {
                const double dx = pair_delta_folded(hl[k], ln[k], il[k], fr[k], x[q + (size_t)k] - xr[q + (size_t)k], true);
                s += dx * dx;
            }
            r2[l] = s;
        }
        for (int l = 0; l < TOP_LANES; l++)
            top_two(r2[l], &t1[l], &t2[l], &tb[l]);
    }
    for (int l = 0; l < TOP_LANES; l++) {
        top_two(t1[l], m1, m2, bad);
        top_two(t2[l], m1, m2, bad);
        *bad |= tb[l];
    }
    for (; i < i1; i++)
        top_two(moved2(m, x, xr, i, d), m1, m2, bad);
}

PSYS_CLONES static void top_two_range(const pair_image *m, const double *x, const double *xr, size_t i0, size_t i1,
                                      int d, double *m1, double *m2, int *bad)
{
    if (d == 3)
        top_two_lanes(m, x, xr, i0, i1, 3, m1, m2, bad);
    else
        top_two_lanes(m, x, xr, i0, i1, 2, m1, m2, bad);
}

/* The lists stay valid while the two largest displacements since the build
 * add up to less than the skin: no pair can then have closed its gap by the
 * skin (max > skin/2, the usual test, is more conservative). NaN forces a
 * rebuild. Two order-independent reductions, so the same for every thread
 * count (and the lists never affect results anyway). */
bool psys__pair_grid_update(pair_force *p, const psys_force_eval *e)
{
    pair_grid *g = &p->grid;
    const size_t n = e->n;
    const int d = p->dim;
    pair_image m;
    pair_image_of(&p->sys->box, &m);
    const bool half = pair_grid_wants_half(p, n);
    g->moved_ready = false;
    if (g->built_n == n && g->half == half && box_equal(&g->box, &p->sys->box)) {
        const double *x = e->x, *xr = g->xref, skin = p->def.skin;
        const double lim = skin - 1e-12 * (skin + sqrt(p->rc2));
        double m1 = 0, m2 = 0;
        int bad = 0;
        /* the forces' cache holds the last evaluation and the two largest
         * displacements there (velocity Verlet's first evaluation of a step
         * finds those positions but for the particles wrapped into the box):
         * only the moved particles are looked at, their displacements taken
         * with the two cached ones, an upper bound on the two largest */
        size_t nc = n / 8 + 1;
        const bool scanned = g->disp_ok && g->cache_ok && g->cache_n == n && g->cache_rebuilds == p->stats.rebuilds;
        if (scanned)
            nc = psys__pair_grid_moved(p, x, n);
        if (nc <= n / 8) {
            m1 = g->disp[0];
            m2 = g->disp[1];
            for (size_t t = 0; t < nc; t++)
                top_two(moved2(&m, x, xr, g->changed[t], d), &m1, &m2, &bad);
        } else {
            /* the two largest in one pass (m2 = m1 when two reach it); max
             * and min are exact, so any split over threads gives the same pair */
            int nt = pair_threads(p, 4.0 * (double)n);
            (void)nt;
            PSYS_OMP(omp parallel num_threads(nt) if (nt > 1))
            {
                double t1 = 0, t2 = 0;
                int tb = 0;
                size_t r0 = 0, r1 = n; /* this thread's range (any split gives the same two) */
#ifdef _OPENMP
                const size_t T = (size_t)omp_get_num_threads(), id = (size_t)omp_get_thread_num();
                r0 = n * id / T;
                r1 = n * (id + 1) / T;
#endif
                top_two_range(&m, x, xr, r0, r1, d, &t1, &t2, &tb); /* NaN: flagged, and no effect */
                PSYS_OMP(omp critical(psys_grid_moved))
                {
                    m2 = fmax(fmax(m2, t2), fmin(m1, t1));
                    m1 = fmax(m1, t1);
                    bad |= tb;
                }
            }
        }
        if (!bad && (m1 == 0 || sqrt(m1) + sqrt(m2) < lim)) {
            /* nothing moved, or no pair can have closed the skin */
            g->disp_now[0] = m1;
            g->disp_now[1] = m2;
            g->moved_ready = scanned; /* the evaluation need not look again, even for "too many" */
            g->moved_n = nc;
            return true;
        }
    }
    g->disp_now[0] = g->disp_now[1] = 0;
    return build(p, e, &m, half);
}
