/* What moved, for the grid: the skin check that keeps the lists or has
 * them rebuilt (psys__pair_grid_update), the particles whose positions
 * changed since the cached evaluation and the owned particles near a ghost,
 * both for forces/pair.c's partial re-evaluation. */
#include "pair/grid.h"

#include <string.h>

static bool box_equal(const psys__box *a, const psys__box *b)
{
    if (a->on != b->on || a->any_periodic != b->any_periodic)
        return false;
    for (int k = 0; k < 3; k++)
        if (a->periodic[k] != b->periodic[k] || a->lo[k] != b->lo[k] || a->hi[k] != b->hi[k])
            return false;
    return true;
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
    return psys__pair_grid_build(p, e, &m, half);
}
