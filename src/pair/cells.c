/* Full neighbour lists cell by cell (AVX-512, every axis pruned): the
 * candidates around a home cell are loaded once for all its particles, in a
 * sliding window along each line of cells (fill_line) or run by run
 * (fill_cell). pair/grid.c's build uses it where it runs; the lists are
 * those of pair/scan.c's fill, particle by particle. */
#include "pair/grid.h"

#include <stdlib.h>
#include <string.h>

#ifdef PSYS_SCAN_AVX512
/* List a[0..n) sorted into nb's slot of particle i (n <= room), or only
 * counted if longer (tmp: SORT_MAX entries of scratch). */
__attribute__((target("avx512f"))) static void list_store(pair_grid *g, size_t i, uint32_t *a, size_t n, size_t room,
                                                           uint32_t *tmp)
{
    if (n <= room && !psys__pair_sort_avx512_to(a, n, g->nb + i * room)) {
        psys__pair_sort_indices(a, n, tmp);
        memcpy(g->nb + i * room, a, n * sizeof(uint32_t));
    }
    g->nb_num[i] = (uint32_t)n;
}

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
 * padding past the end takes what spills): masked stores made the fill
 * markedly slower (figures: bench/HISTORY.md). */
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
static win_mode win_float_limit(double rl2, double B, bool want_double)
{
    win_mode wm = {false, 0};
    const double u = 0x1p-24, rl = sqrt(rl2), E = (2 * B + rl) * u * 1.001;
    const double hi = (rl2 + 3.5 * rl * E + 3 * E * E) * (1 + 4 * u);
    if (!(hi - rl2 <= 1e-3 * rl2) || want_double)
        return wm;
    wm.f32 = true;
    wm.hi = nextafterf((float)hi, INFINITY);
    return wm;
}

size_t psys__pair_fill_by_cells(pair_force *p, const stencil *sc, const pair_image *m, size_t n, size_t room,
                            double rl2, double scale, int nt, int d)
{
    pair_grid *g = &p->grid;
    /* build coordinates lie within scale of 0, their images within 2·scale */
    const win_mode wm = win_float_limit(rl2, 2 * scale, p->sys->sw.window_double);
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
