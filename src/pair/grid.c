/* Grid method of pair forces (overview: pair/grid.h): the grid's storage,
 * the cells (a counting sort of the particles into buckets) and the build
 * that fills the neighbour lists through pair/scan.c or pair/cells.c and
 * sorts full lists by transposition where the AVX-512 sort does not run. */
#include "pair/grid.h"

#include <stdlib.h>
#include <string.h>

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

static inline int cell_coord(const pair_grid *g, int k, double t)
{
    double c = floor(t / g->cell_size[k]);
    if (!(c >= 0)) /* also NaN */
        c = 0;
    if (c > g->ncell[k] - 1)
        c = g->ncell[k] - 1;
    return (int)c;
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

bool psys__pair_grid_build(pair_force *p, const psys_force_eval *e, const pair_image *m, bool half)
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
    const bool transpose = !half && !p->sys->own_mark && !psys__pair_scan_has_avx512(p->sys);
    double per = g->per_particle * 1.2 + 4;
    if (!(per <= (double)n)) /* also NaN (a huge radius makes the density estimate inf·0) */
        per = (double)n;
    /* cell by cell where that runs (full lists, AVX-512, every axis pruned) */
    bool by_cells = !half && !p->sys->own_mark && psys__pair_scan_has_avx512(p->sys);
    for (int k = 0; k < d; k++)
        by_cells = by_cells && sc.prune[k];
#ifdef PSYS_SCAN_AVX512
    if (by_cells) {
        size_t room = (size_t)per + 8;
        room = room > g->longest + 8 ? room : g->longest + 8;
        for (;;) {
            if (!(room <= SIZE_MAX / 2 / (n ? n : 1)) || !grow_lists(&g->nb, &g->nb_cap, n * room))
                return false;
            const size_t longest = psys__pair_fill_by_cells(p, &sc, m, n, room, rls2, scale, ntf, d);
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
        bool ok = half ? (d == 2 ? psys__pair_fill_2h(p, &sc, m, x, n, nchunks, rls2, ntf, true)
                                 : psys__pair_fill_3h(p, &sc, m, x, n, nchunks, rls2, ntf, true))
                       : (d == 2 ? psys__pair_fill_2(p, &sc, m, x, n, nchunks, rls2, ntf, !transpose)
                                 : psys__pair_fill_3(p, &sc, m, x, n, nchunks, rls2, ntf, !transpose));
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
