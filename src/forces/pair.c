/* Pair forces (notes §4.3, "spatial interaction"): one force object holding
 * a pair law (gravity, coulomb, lennard-jones, soft-repulsion or a user
 * callback) and a method for finding pairs (direct, grid, barnes-hut).
 *
 * Laws, with r = |x_i - x_j| and the force on i equal to g(r)·(x_i - x_j):
 *   gravity        U = -G m_i m_j / s,  s = sqrt(r² + softening²),  g = -G m_i m_j / s³
 *   coulomb        U = k q_i q_j / r,                                g = k q_i q_j / r³
 *   lennard-jones  U = 4ε[(σ/r)¹² - (σ/r)⁶] - shift for r < rc, else 0,
 *                  g = 24ε[2(σ/r)¹² - (σ/r)⁶] / r²,  shift = U(rc) if "shift" else 0
 *   soft-repulsion U = ½ k (R - r)² for r < R, else 0,               g = k (R - r) / r
 *   user           F(r) = -dU/dr from a callback,                     g = F(r) / r
 * A pair at r = 0 has no direction and exerts no force (see psys_pair_def).
 *
 * Methods: `direct` visits all pairs in cache blocks; `grid` (pair/grid.c)
 * keeps Verlet neighbour lists built from cell lists, rebuilt only when the
 * two largest displacements add up to the skin; `barnes-hut` (pair/bh.c) walks a
 * quadtree/octree with opening angle theta. See pair/pair.h for why results are
 * identical for every thread count and why grid equals direct bit for bit.
 * Storage is allocated when the force is created and grows only when an
 * evaluation finds more particles (or a rebuild needs more room); if it
 * cannot grow, that evaluation runs the direct method, which needs none and
 * gives the same forces. */
#include "forces/forces.h"
#include "pair/pair.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define DIRECT_IB 16   /* particles i per block */
#define DIRECT_JB 512  /* partners j per block */

/* The vectorised pair loops (pair_row_forces) are also built for AVX-512
 * and for x86-64-v3 (AVX2 with FMA) on x86-64 with GCC (8 or 4 pairs per
 * instruction), chosen at load time; the fused multiply-adds of
 * pair_force_r2 and the sums are single instructions there (libm's fma in
 * the default build), sqrt and division correctly rounded: the same bits on
 * every path. */
#if defined(__GNUC__) && !defined(__clang__) && defined(__x86_64__) && defined(__linux__)
#define PAIR_CLONES __attribute__((target_clones("avx512f", "arch=x86-64-v3", "default")))
/* The scalar force loops (user laws, the half-list sweep, fallbacks),
 * built again for x86-64-v3 so that their fused multiply-adds are
 * instructions rather than calls to libm's fma, which make the direct
 * method with a user law several times slower (bench/HISTORY.md). */
#define PAIR_FMA_CLONES __attribute__((target_clones("arch=x86-64-v3", "default")))
#else
#define PAIR_CLONES
#define PAIR_FMA_CLONES
#endif

psys_pair_def psys_pair_def_default(void)
{
    psys_pair_def d;
    memset(&d, 0, sizeof d);
    d.law = PSYS_PAIR_GRAVITY;
    d.method = PSYS_PAIR_AUTO;
    d.G = 1;
    d.softening = 0;
    d.k = 1;
    d.epsilon = 1;
    d.sigma = 1;
    d.cutoff = 0;
    d.shift = false;
    d.radius = 1;
    d.skin = -1;
    d.theta = 0.5;
    return d;
}

static const char *const law_names[] = {"gravity", "coulomb", "lennard-jones", "soft-repulsion"};
#define NLAWS 4

const char *psys_pair_law_name(psys_pair_law law)
{
    return (int)law >= 0 && (int)law < NLAWS ? law_names[law] : NULL;
}

const char *psys_pair_method_name(psys_pair_method m)
{
    switch (m) {
    case PSYS_PAIR_AUTO: return "auto";
    case PSYS_PAIR_DIRECT: return "direct";
    case PSYS_PAIR_GRID: return "grid";
    case PSYS_PAIR_BARNES_HUT: return "barnes-hut";
    }
    return NULL;
}

static bool law_has_cutoff(const psys_pair_def *d)
{
    return d->law == PSYS_PAIR_LENNARD_JONES || d->law == PSYS_PAIR_SOFT_REPULSION
           || (d->law == PSYS_PAIR_USER && d->cutoff > 0);
}

/* ---- storage ---- */

static void pair_destroy(void *data)
{
    pair_force *p = data;
    if (!p)
        return;
    free(p->epart);
    free(p->wbuf);
    free(p->xsoa);
    psys__pair_grid_free(&p->grid);
    psys__pair_bh_free(&p->bh);
    free(p);
}

/* Per-particle buffers for at least n particles (never shrinks). */
static bool pair_reserve(pair_force *p, size_t n)
{
    if (n <= p->cap)
        return true;
    size_t cap = p->cap ? p->cap : 16;
    while (cap < n)
        cap *= 2;
    if (cap > UINT32_MAX)
        return false;
    double *ep = psys__realloc(p->epart, cap, sizeof(double));
    if (!ep)
        return false;
    p->epart = ep;
    double *xs = psys__realloc(p->xsoa, cap * (size_t)p->dim, sizeof(double));
    if (!xs)
        return false;
    p->xsoa = xs;
    if (p->law == PSYS_PAIR_COULOMB) {
        double *wb = psys__realloc(p->wbuf, cap, sizeof(double));
        if (!wb)
            return false;
        p->wbuf = wb;
    }
    if (p->def.method == PSYS_PAIR_GRID && !psys__pair_grid_reserve(&p->grid, cap, p->dim))
        return false;
    if (p->def.method == PSYS_PAIR_BARNES_HUT && !psys__pair_bh_reserve(&p->bh, cap))
        return false;
    p->cap = cap;
    return true;
}

/* ---- evaluation ---- */

/* Weights of the particles: masses (gravity), charges (coulomb), none. */
static const double *pair_weights(pair_force *p, const psys_force_eval *e, bool have_storage)
{
    if (p->law == PSYS_PAIR_GRAVITY)
        return e->mass;
    if (p->law != PSYS_PAIR_COULOMB)
        return NULL;
    const psys_system *s = p->sys;
    if (s->ncharge >= e->n)
        return s->charge;
    if (!have_storage)
        return NULL; /* no buffer: the fallback evaluates the charged prefix only */
    size_t nq = s->ncharge;
    if (nq)
        memcpy(p->wbuf, s->charge, nq * sizeof(double));
    for (size_t i = nq; i < e->n; i++)
        p->wbuf[i] = 0.0;
    return p->wbuf;
}

/* The evaluation loops are instantiated for every law, dimension and mode
 * (forces or energies) by macros, so that each parallel loop body sees them
 * as constants (OpenMP outlines the body before inlining could propagate
 * them). */

/* Direct method, one block of DIRECT_IB particles i: forces added into f
 * (want_f), per-particle energies into ep (want_u; ep NULL: added to *total
 * in ascending i, serial callers only). */
PAIR_INLINE void direct_block(const pair_force *p, const int law, const int d, const pair_image *m,
                              const double *x, const double *w, size_t n, size_t b, const bool want_f, double *f,
                              const bool want_u, double *ep, double *total, const unsigned char *mark,
                              const bool vec)
{
    size_t i0 = b * DIRECT_IB, i1 = i0 + DIRECT_IB < n ? i0 + DIRECT_IB : n;
    if (mark) { /* MPI (core/comm_mpi.c): only the rows this rank owns */
        size_t i = i0;
        while (i < i1 && !mark[i])
            i++;
        if (i == i1)
            return;
    }
    double acc[DIRECT_IB][3], us[DIRECT_IB];
    memset(acc, 0, sizeof acc);
    memset(us, 0, sizeof us);
    for (size_t j0 = 0; j0 < n; j0 += DIRECT_JB) {
        size_t j1 = j0 + DIRECT_JB < n ? j0 + DIRECT_JB : n;
        for (size_t i = i0; i < i1; i++) {
            if (mark && !mark[i])
                continue;
            if (vec) /* forces only, pair_can_vectorise held */
                pair_row_forces(p, law, d, m, w, i, NULL, j0, j1 - j0, false, acc[i - i0]);
            else
                pair_gather(p, law, d, m, x, w, i, NULL, j0, j1 - j0, false, want_f, acc[i - i0], want_u,
                            &us[i - i0]);
        }
    }
    for (size_t i = i0; i < i1; i++) {
        if (mark && !mark[i])
            continue;
        if (want_f)
            for (int k = 0; k < d; k++)
                f[i * d + k] += acc[i - i0][k];
        if (want_u) {
            if (ep)
                ep[i] = us[i - i0];
            else
                *total += us[i - i0];
        }
    }
}

/* vec: pair_can_vectorise held and p->xsoa holds the positions
 * (pair_soa_positions), so forces may go through the vectorised loop. */
typedef void (*direct_fn)(const pair_force *p, const pair_image *m, const double *x, const double *w, size_t n,
                          double *f, double *ep, double *total, int nt, const unsigned char *mark, bool vec);

/* One block through the vectorised path (PAIR_CLONES): forces only. */
#define DBLOCK_FN(name, LAW, D)                                                                              \
    PAIR_CLONES static void name(const pair_force *p, const pair_image *m, const double *x, const double *w, \
                                 size_t n, size_t b, double *f, const unsigned char *mark)                   \
    {                                                                                                        \
        direct_block(p, LAW, D, m, x, w, n, b, true, f, false, NULL, NULL, mark, true);                      \
    }
typedef void (*dblock_fn)(const pair_force *p, const pair_image *m, const double *x, const double *w, size_t n,
                          size_t b, double *f, const unsigned char *mark);
/* The vectorised functions of every built-in law in 2-D and 3-D, and their
 * table indexed by law (not the user law), then [2-D, 3-D]. */
#define VEC_VARIANTS(MAKE, PFX)                                                                              \
    MAKE(PFX##_gravity_2, PSYS_PAIR_GRAVITY, 2)                                                              \
    MAKE(PFX##_gravity_3, PSYS_PAIR_GRAVITY, 3)                                                              \
    MAKE(PFX##_coulomb_2, PSYS_PAIR_COULOMB, 2)                                                              \
    MAKE(PFX##_coulomb_3, PSYS_PAIR_COULOMB, 3)                                                              \
    MAKE(PFX##_lj_2, PSYS_PAIR_LENNARD_JONES, 2)                                                             \
    MAKE(PFX##_lj_3, PSYS_PAIR_LENNARD_JONES, 3)                                                             \
    MAKE(PFX##_soft_2, PSYS_PAIR_SOFT_REPULSION, 2)                                                          \
    MAKE(PFX##_soft_3, PSYS_PAIR_SOFT_REPULSION, 3)
#define VEC_TABLE(PFX)                                                                                       \
    {{PFX##_gravity_2, PFX##_gravity_3}, {PFX##_coulomb_2, PFX##_coulomb_3}, {PFX##_lj_2, PFX##_lj_3},      \
     {PFX##_soft_2, PFX##_soft_3}}
VEC_VARIANTS(DBLOCK_FN, dblock)
static const dblock_fn dblock_fns[4][2] = VEC_TABLE(dblock);

#define DIRECT_FN(name, LAW, D, WF, WU)                                                                      \
    PAIR_FMA_CLONES static void name##_block(const pair_force *p, const pair_image *m, const double *x,      \
                                             const double *w, size_t n, size_t b, double *f, double *ep,     \
                                             double *total, const unsigned char *mark)                       \
    {                                                                                                        \
        direct_block(p, LAW, D, m, x, w, n, b, WF, f, WU, ep, total, mark, false);                           \
    }                                                                                                        \
    static void name(const pair_force *p, const pair_image *m, const double *x, const double *w, size_t n,   \
                     double *f, double *ep, double *total, int nt, const unsigned char *mark, bool vec)      \
    {                                                                                                        \
        size_t nblocks = (n + DIRECT_IB - 1) / DIRECT_IB;                                                    \
        const dblock_fn fast = vec && WF && !WU && LAW != PSYS_PAIR_USER ? dblock_fns[LAW][D == 3] : NULL;  \
        (void)nt;                                                                                            \
        PSYS_OMP(omp parallel for schedule(dynamic, 1) num_threads(nt) if (nt > 1))                          \
        for (size_t b = 0; b < nblocks; b++) {                                                               \
            if (fast)                                                                                        \
                fast(p, m, x, w, n, b, f, mark);                                                             \
            else                                                                                             \
                name##_block(p, m, x, w, n, b, f, ep, total, mark);                                          \
        }                                                                                                    \
    }

/* Grid method: gather over the neighbour lists, for every particle or only
 * the marked ones; forces (or energies) are stored into out, not added. */
typedef void (*grid_fn)(const pair_force *p, const pair_image *m, const double *x, const double *w, size_t n,
                        const unsigned char *mark, double *out, int nt);

#define GRID_CHUNK 64 /* rows per parallel task */
#define GRID_FN(name, LAW, D, WF, WU)                                                                        \
    PAIR_FMA_CLONES static void name##_rows(const pair_force *p, const pair_image *m, const double *x,       \
                                            const double *w, size_t i0, size_t i1, const unsigned char *mark, \
                                            double *out)                                                     \
    {                                                                                                        \
        const size_t *st = p->grid.nb_start;                                                                 \
        const uint32_t *num = p->grid.nb_num, *nb = p->grid.nb;                                              \
        for (size_t i = i0; i < i1; i++) {                                                                   \
            if (mark && !mark[i])                                                                            \
                continue;                                                                                    \
            double acc[3] = {0, 0, 0}, us = 0;                                                               \
            pair_gather(p, LAW, D, m, x, w, i, nb + st[i], 0, num[i], true, WF, acc, WU, &us);                 \
            if (WF)                                                                                          \
                for (int k = 0; k < D; k++)                                                                  \
                    out[i * D + k] = acc[k];                                                                 \
            if (WU)                                                                                          \
                out[i] = us;                                                                                 \
        }                                                                                                    \
    }                                                                                                        \
    static void name(const pair_force *p, const pair_image *m, const double *x, const double *w, size_t n,   \
                     const unsigned char *mark, double *out, int nt)                                         \
    {                                                                                                        \
        const size_t nchunks = (n + GRID_CHUNK - 1) / GRID_CHUNK;                                            \
        (void)nt;                                                                                            \
        PSYS_OMP(omp parallel for schedule(dynamic, 1) num_threads(nt) if (nt > 1))                          \
        for (size_t c = 0; c < nchunks; c++) {                                                               \
            const size_t i0 = c * GRID_CHUNK, i1 = i0 + GRID_CHUNK < n ? i0 + GRID_CHUNK : n;                 \
            name##_rows(p, m, x, w, i0, i1, mark, out);                                                      \
        }                                                                                                    \
    }

/* Grid forces of rows [i0, i1) (all, or the marked ones) through
 * pair_row_forces: the same bits as GRID_FN's gather. */
#define ROWS_FN(name, LAW, D)                                                                                \
    PAIR_CLONES static void name(const pair_force *p, const pair_image *m, const double *w, size_t i0,       \
                                 size_t i1, const unsigned char *mark, double *out)                          \
    {                                                                                                        \
        const size_t *st = p->grid.nb_start;                                                                 \
        const uint32_t *num = p->grid.nb_num, *nb = p->grid.nb;                                              \
        for (size_t i = i0; i < i1; i++) {                                                                   \
            if (mark && !mark[i])                                                                            \
                continue;                                                                                    \
            double acc[3] = {0, 0, 0};                                                                       \
            pair_row_forces(p, LAW, D, m, w, i, nb + st[i], 0, num[i], true, acc);                           \
            for (int k = 0; k < D; k++)                                                                      \
                out[i * D + k] = acc[k];                                                                     \
        }                                                                                                    \
    }
typedef void (*rows_fn)(const pair_force *p, const pair_image *m, const double *w, size_t i0, size_t i1,
                        const unsigned char *mark, double *out);
VEC_VARIANTS(ROWS_FN, rows)
static const rows_fn rows_fns[4][2] = VEC_TABLE(rows);
#define ROWS_CHUNK 64

/* Grid forces over full lists: four rows at a time where that runs
 * (pair/group.c; true, and x copied into xc too where xc is not NULL),
 * else through rows_fns, in parallel by chunks of rows. changed, xc: see
 * psys__pair_group_forces. */
static bool grid_rows(pair_force *p, const pair_image *m, const double *x, const double *w, size_t n,
                      const unsigned char *mark, const uint32_t *changed, size_t nchanged, double *xc, double *out,
                      int nt)
{
    if (psys__pair_group_forces(p, m, x, w, n, mark, changed, nchanged, xc, out, nt)) {
        p->grouped++;
        return true;
    }
    pair_soa_positions(p, x, n, nt);
    const rows_fn fn = rows_fns[p->law][p->dim == 3];
    const size_t nchunks = (n + ROWS_CHUNK - 1) / ROWS_CHUNK;
    (void)nt;
    PSYS_OMP(omp parallel for schedule(dynamic, 1) num_threads(nt) if (nt > 1))
    for (size_t c = 0; c < nchunks; c++) {
        size_t i0 = c * ROWS_CHUNK, i1 = i0 + ROWS_CHUNK < n ? i0 + ROWS_CHUNK : n;
        fn(p, m, w, i0, i1, mark, out);
    }
    return false;
}

/* Grid method with half lists (one thread): a sweep over i in increasing
 * order evaluates each pair once and adds its force to i and its opposite
 * to j. Particle j thus receives its contributions in increasing partner
 * order (partners below j while the sweep passes them, then its own list),
 * exactly as the full-list gather adds them, so the results are the same
 * bits. With mark, only marked particles' entries of out are recomputed
 * (pairs with no marked end are skipped); the others are left as they are. */
#define HALF_FN(name, LAW, D, WF, WU)                                                                        \
    PAIR_FMA_CLONES static void name(const pair_force *p, const pair_image *m, const double *x,              \
                                     const double *w, size_t n, const unsigned char *mark, double *out,      \
                                     int nt)                                                                 \
    {                                                                                                        \
        if (mark)                                                                                            \
            half_sweep(p, LAW, D, m, x, w, n, mark, out, WF, WU);                                            \
        else                                                                                                 \
            half_sweep(p, LAW, D, m, x, w, n, NULL, out, WF, WU);                                            \
        (void)nt;                                                                                            \
    }

PAIR_INLINE void half_sweep(const pair_force *p, const int LAW, const int D, const pair_image *m, const double *x,
                            const double *w, size_t n, const unsigned char *mark, double *out, const bool WF,
                            const bool WU)
{
    const size_t *st = p->grid.nb_start;
    const uint32_t *num = p->grid.nb_num, *nb = p->grid.nb;
    const size_t stride = WF ? (size_t)D : 1;
    for (size_t i = 0; i < n; i++)
        if (!mark || mark[i])
            for (size_t k = 0; k < stride; k++)
                out[i * stride + k] = 0.0;
    for (size_t i = 0; i < n; i++) {
        const bool mi = !mark || mark[i];
        const uint32_t *js = nb + st[i];
        const size_t nj = num[i];
        double xi[3] = {0, 0, 0}, a[3] = {0, 0, 0}, us = 0;
        for (int k = 0; k < D; k++)
            xi[k] = x[i * D + k];
        if (mi) {
            if (WF)
                for (int k = 0; k < D; k++)
                    a[k] = out[i * D + k];
            if (WU)
                us = out[i];
        }
        const double wi = w ? w[i] : 1.0;
        for (size_t t = 0; t < nj; t++) {
            const size_t j = js[t];
            const bool mj = !mark || mark[j];
            if (!mi && !mj)
                continue;
            double dx[3] = {0, 0, 0}, u = 0;
            for (int k = 0; k < D; k++)
                dx[k] = pair_delta(m, k, xi[k] - x[j * D + k]);
            const double r2 = WF ? pair_force_r2(D, dx[0], dx[1], dx[2]) : pair_plain_r2(D, dx[0], dx[1], dx[2]);
            double g = pair_kernel(p, LAW, r2, w ? wi * w[j] : 1.0, WU, &u);
            if (WF)
                for (int k = 0; k < D; k++) {
                    /* j's term is g·(-dx), fused as the gather over j's
                     * own list fuses it */
                    if (mi)
                        a[k] = fma(g, dx[k], a[k]);
                    if (mj)
                        out[j * D + k] = fma(-g, dx[k], out[j * D + k]);
                }
            if (WU) {
                if (mi)
                    us += u;
                if (mj)
                    out[j] += u;
            }
        }
        if (mi) {
            if (WF)
                for (int k = 0; k < D; k++)
                    out[i * D + k] = a[k];
            if (WU)
                out[i] = us;
        }
    }
}

/* Four variants (2-D/3-D × forces/energies) of one law. */
#define PAIR_VARIANTS(MAKE, PFX, LAW)                                                                        \
    MAKE(PFX##_2f, LAW, 2, true, false)                                                                      \
    MAKE(PFX##_2u, LAW, 2, false, true)                                                                      \
    MAKE(PFX##_3f, LAW, 3, true, false)                                                                      \
    MAKE(PFX##_3u, LAW, 3, false, true)
#define PAIR_TABLE(PFX) {PFX##_2f, PFX##_2u, PFX##_3f, PFX##_3u}

PAIR_VARIANTS(DIRECT_FN, direct_gravity, PSYS_PAIR_GRAVITY)
PAIR_VARIANTS(DIRECT_FN, direct_coulomb, PSYS_PAIR_COULOMB)
PAIR_VARIANTS(DIRECT_FN, direct_lj, PSYS_PAIR_LENNARD_JONES)
PAIR_VARIANTS(DIRECT_FN, direct_soft, PSYS_PAIR_SOFT_REPULSION)
PAIR_VARIANTS(DIRECT_FN, direct_user, PSYS_PAIR_USER)
PAIR_VARIANTS(GRID_FN, grid_gravity, PSYS_PAIR_GRAVITY)
PAIR_VARIANTS(GRID_FN, grid_coulomb, PSYS_PAIR_COULOMB)
PAIR_VARIANTS(GRID_FN, grid_lj, PSYS_PAIR_LENNARD_JONES)
PAIR_VARIANTS(GRID_FN, grid_soft, PSYS_PAIR_SOFT_REPULSION)
PAIR_VARIANTS(GRID_FN, grid_user, PSYS_PAIR_USER)
PAIR_VARIANTS(HALF_FN, half_gravity, PSYS_PAIR_GRAVITY)
PAIR_VARIANTS(HALF_FN, half_coulomb, PSYS_PAIR_COULOMB)
PAIR_VARIANTS(HALF_FN, half_lj, PSYS_PAIR_LENNARD_JONES)
PAIR_VARIANTS(HALF_FN, half_soft, PSYS_PAIR_SOFT_REPULSION)
PAIR_VARIANTS(HALF_FN, half_user, PSYS_PAIR_USER)

/* Indexed by law (psys_pair_law order), then [2f, 2u, 3f, 3u]. */
static const direct_fn direct_fns[5][4] = {PAIR_TABLE(direct_gravity), PAIR_TABLE(direct_coulomb),
                                           PAIR_TABLE(direct_lj), PAIR_TABLE(direct_soft), PAIR_TABLE(direct_user)};
static const grid_fn grid_fns[5][4] = {PAIR_TABLE(grid_gravity), PAIR_TABLE(grid_coulomb), PAIR_TABLE(grid_lj),
                                       PAIR_TABLE(grid_soft), PAIR_TABLE(grid_user)};
static const grid_fn half_fns[5][4] = {PAIR_TABLE(half_gravity), PAIR_TABLE(half_coulomb), PAIR_TABLE(half_lj),
                                       PAIR_TABLE(half_soft), PAIR_TABLE(half_user)};

static int variant(int dim, bool want_u) { return (dim == 3 ? 2 : 0) + (want_u ? 1 : 0); }

/* Direct method: forces (want_u false) or energies (ep, or *total when ep is NULL: then serial). */
static void direct_eval(const pair_force *p, const pair_image *m, const double *x, const double *w, size_t n,
                        bool want_u, double *f, double *ep, double *total)
{
    int nt = ep || !want_u ? pair_threads(p, (double)n * (double)n) : 1;
    const unsigned char *mark = want_u ? NULL : psys__dist_mark(p->sys);
    const bool vec = !want_u && pair_can_vectorise(p, w, n);
    if (vec)
        pair_soa_positions(p, x, n, nt);
    direct_fns[p->law][variant(p->dim, want_u)](p, m, x, w, n, f, ep, total, nt, mark, vec);
}

/* Grid method. Forces go through a cache: a particle's force depends only
 * on its position and those of its partners, so when the lists have not
 * been rebuilt since the last evaluation and only a few particles moved
 * (velocity Verlet's second evaluation of a step and the first of the next
 * differ only by the particles wrapped into the box), only those particles
 * and their partners are recomputed; the others keep their forces, which a
 * full evaluation would reproduce bit for bit. User laws may depend on
 * more than positions (their ctx) and are always recomputed. */
static void grid_eval(pair_force *p, const pair_image *m, const double *x, const double *w, size_t n, bool want_u,
                      double *f, double *ep)
{
    pair_grid *g = &p->grid;
    const int d = p->dim;
    const size_t nd = n * (size_t)d;
    int nt = g->half ? 1 : pair_threads(p, 2.0 * (double)p->stats.pairs);
    const int ntv = pair_threads(p, (double)nd); /* elementwise passes */
    (void)ntv;
    grid_fn fn = (g->half ? half_fns : grid_fns)[p->law][variant(d, want_u)];
    if (want_u) {
        g->moved_ready = false;
        fn(p, m, x, w, n, NULL, ep, nt);
        return;
    }
    /* the position records of pair/group.c match xcache only if this
     * evaluation says so below */
    const bool xq_cached = g->xq_cached, moved_ready = g->moved_ready;
    g->xq_cached = false;
    g->moved_ready = false;
    g->disp_ok = false;
    const unsigned char *own = psys__dist_mark(p->sys);
    if (own && own != p->sys->own_mark) {
        /* MPI, replicated state (core/comm_mpi.c): this rank's rows only, which change
         * at every evaluation, past the cache; the others are not read */
        if (!g->half && pair_can_vectorise(p, w, n)) {
            grid_rows(p, m, x, w, n, own, NULL, 0, NULL, g->fcache, nt);
        } else {
            fn(p, m, x, w, n, own, g->fcache, nt);
        }
        g->cache_ok = false;
        for (size_t k = 0; k < nd; k++)
            f[k] += g->fcache[k];
        return;
    }
    const bool cacheable = p->law != PSYS_PAIR_USER;
    const unsigned char *mark = NULL;
    size_t nc = 0;
    bool compute = true;
    if (cacheable && g->cache_ok && g->cache_n == n && g->cache_rebuilds == p->stats.rebuilds) {
        /* the moved particles (listed by the displacement check where it could) */
        nc = moved_ready ? g->moved_n : psys__pair_grid_moved(p, x, n);
        if (nc == 0) {
            compute = false;
        } else if (nc <= n / 8) {
            /* mark: bit 1 moved, bit 0 recompute (the moved and their
             * partners; without a domain, only the rows whose terms change) */
            if (g->half || own)
                for (size_t t = 0; t < nc; t++)
                    g->mark[g->changed[t]] = 3;
            if (!g->half && !own) {
                /* A row's force is its terms g(r²)·Δ summed in list order,
                 * with Δ = x_i - x_j under the minimum image: a row none of
                 * whose Δ changed in any bit keeps its cached force. A
                 * particle wrapped into the box moves by one box length, and
                 * its Δ to the partners it left behind the face are often
                 * the same bits (the new difference is exact where the old
                 * one was), so neither they nor it need recomputing. pair_delta
                 * is odd, so Δ_cj = -Δ_jc, bit for bit, and one test covers
                 * the pair's two rows. */
                const double *xo = g->xcache;
                for (size_t t = 0; t < nc; t++) {
                    const uint32_t c = g->changed[t];
                    const double *xc = x + (size_t)c * d, *oc = xo + (size_t)c * d;
                    bool any = false;
                    for (uint32_t q = 0; q < g->nb_num[c]; q++) {
                        const uint32_t j = g->nb[g->nb_start[c] + q];
                        bool same = true;
                        for (int k = 0; k < d; k++) {
                            const double a = pair_delta(m, k, x[(size_t)j * d + k] - xc[k]);
                            const double b = pair_delta(m, k, xo[(size_t)j * d + k] - oc[k]);
                            same = same && memcmp(&a, &b, sizeof a) == 0;
                        }
                        if (!same) {
                            g->mark[j] |= 1;
                            any = true;
                        }
                    }
                    if (any)
                        g->mark[c] |= 1;
                }
            } else if (g->half) {
                for (size_t i = 0; i < n; i++)
                    for (uint32_t q = 0; q < g->nb_num[i]; q++) {
                        uint32_t j = g->nb[g->nb_start[i] + q];
                        if (g->mark[i] & 2)
                            g->mark[j] |= 1;
                        if (g->mark[j] & 2)
                            g->mark[i] |= 1;
                    }
            } else {
                for (size_t t = 0; t < nc; t++) {
                    uint32_t c = g->changed[t];
                    if (own && !own[c]) { /* a domain's ghost: the owned rows near it */
                        psys__pair_grid_mark_near(g, m, d, c, own, g->mark);
                        continue;
                    }
                    for (uint32_t q = 0; q < g->nb_num[c]; q++)
                        g->mark[g->nb[g->nb_start[c] + q]] |= 1;
                }
            }
            if (own) /* a domain's ghosts: their rows are never used */
                for (size_t i = 0; i < n; i++)
                    g->mark[i] = own[i] ? g->mark[i] : 0;
            mark = g->mark;
            p->stats.partial++;
            size_t rows = 0;
            for (size_t i = 0; i < n; i++)
                rows += g->mark[i] != 0;
            p->stats.partial_rows += rows;
        }
    }
    /* own (MPI domain decomposition, mpi/domain.c): only the owned rows, a
     * set fixed between redistributions (which invalidate the cache); the
     * ghosts' rows of the cache are zero */
    const unsigned char *rows = mark ? mark : own;
    if (compute && own && !mark)
        for (size_t i = 0; i < n; i++)
            if (!own[i])
                memset(g->fcache + i * (size_t)d, 0, (size_t)d * sizeof(double));
    bool records = false; /* pair/group.c's records now hold x */
    /* with every row computed, the copy of x into the records also fills
     * the forces' cache of positions, and the copy below is skipped */
    double *xc = rows ? NULL : g->xcache;
    if (compute && !g->half && pair_can_vectorise(p, w, n))
        records = grid_rows(p, m, x, w, n, rows, mark && xq_cached ? g->changed : NULL, nc, xc, g->fcache, nt);
    else if (compute)
        fn(p, m, x, w, n, rows, g->fcache, nt);
    if (mark) {
        for (size_t t = 0; t < nc; t++) {
            uint32_t c = g->changed[t];
            memcpy(g->xcache + (size_t)c * d, x + (size_t)c * d, (size_t)d * sizeof(double));
        }
        memset(g->mark, 0, n);
    } else if (compute && !(records && xc)) {
        PSYS_PAR_FOR(ntv, nd)
        for (size_t k = 0; k < nd; k++)
            g->xcache[k] = x[k];
    }
    g->cache_ok = cacheable;
    g->xq_cached = cacheable && (records || (!compute && xq_cached));
    g->disp_ok = cacheable;
    g->disp[0] = g->disp_now[0];
    g->disp[1] = g->disp_now[1];
    g->cache_n = n;
    g->cache_rebuilds = p->stats.rebuilds;
    PSYS_PAR_FOR(ntv, nd)
    for (size_t k = 0; k < nd; k++)
        f[k] += g->fcache[k];
}

/* Direct evaluation needing no storage (fallback when buffers could not
 * grow): the same sums in the same order, so the same results. Coulomb with
 * a charge array shorter than n: the uncharged tail adds exactly nothing,
 * so only the charged prefix is evaluated. */
static double fallback_eval(pair_force *p, const psys_force_eval *e, const pair_image *m, bool want_u, double *f)
{
    const double *w = pair_weights(p, e, false);
    size_t n = e->n;
    double t = 0;
    p->stats.fallbacks++;
    if (p->law == PSYS_PAIR_COULOMB && !w) {
        w = p->sys->charge;
        n = p->sys->ncharge;
    }
    direct_eval(p, m, e->x, w, n, want_u, f, NULL, &t);
    return 0.5 * t;
}

/* One evaluation: forces added into f, or (want_u) the energy returned. */
static double pair_eval(pair_force *p, const psys_force_eval *e, bool want_u, double *f)
{
    size_t n = e->n;
    p->stats.evaluations++;
    if (n < 2)
        return 0;
    pair_image m;
    pair_image_of(&p->sys->box, &m);
    if (!pair_reserve(p, n))
        return fallback_eval(p, e, &m, want_u, f);
    const double *w = pair_weights(p, e, true);
    switch (p->def.method) {
    case PSYS_PAIR_GRID:
        if (!psys__pair_grid_update(p, e))
            return fallback_eval(p, e, &m, want_u, f);
        grid_eval(p, &m, e->x, w, n, want_u, f, p->epart);
        break;
    case PSYS_PAIR_BARNES_HUT:
        if (!psys__pair_bh_build(p, e->x, w, n))
            return fallback_eval(p, e, &m, want_u, f);
        psys__pair_bh_eval(p, e, w, want_u, f);
        break;
    default:
        direct_eval(p, &m, e->x, w, n, want_u, f, p->epart, NULL);
        break;
    }
    if (!want_u)
        return 0;
    double u = 0;
    for (size_t i = 0; i < n; i++)
        u += p->epart[i];
    return 0.5 * u;
}

static void pair_apply(void *data, const psys_force_eval *e, double *f) { pair_eval(data, e, false, f); }

void psys__pair_invalidate(void *data)
{
    pair_force *p = data;
    p->grid.built_n = 0;
    p->grid.cache_ok = false;
}

static double pair_energy(void *data, const psys_force_eval *e) { return pair_eval(data, e, true, NULL); }

/* ---- Jacobian ----
 * With dx = x_i - x_j and f_i = g(r) dx: ∂f_i/∂x_j = -K, ∂f_i/∂x_i = Σ_j K,
 * K = g I + h dx dxᵀ, h = g'(r)/r. Its eigenvalues are F'(r) along dx and
 * g across; a sink that wants a definite matrix gets both clamped to <= 0. */
static double kernel_h(const pair_force *p, double r2, double c, double *g)
{
    double u;
    *g = pair_kernel(p, p->law, r2, c, false, &u);
    switch (p->law) {
    case PSYS_PAIR_GRAVITY: {
        double s2 = r2 + p->eps2;
        if (!(s2 > 0))
            return 0;
        double inv = 1.0 / sqrt(s2), i2 = inv * inv;
        return 3.0 * p->G * c * i2 * i2 * inv;
    }
    case PSYS_PAIR_COULOMB: {
        if (!(r2 > 0))
            return 0;
        double inv = 1.0 / sqrt(r2), i2 = inv * inv;
        return -3.0 * p->kc * c * i2 * i2 * inv;
    }
    case PSYS_PAIR_LENNARD_JONES: {
        if (!(r2 < p->rc2) || !(r2 > 0))
            return 0;
        double ir2 = 1.0 / r2, s2 = p->sig2 * ir2, s6 = s2 * s2 * s2;
        return p->lj24 * (8.0 * s6 - 28.0 * s6 * s6) * ir2 * ir2;
    }
    case PSYS_PAIR_SOFT_REPULSION: {
        if (!(r2 < p->rc2) || !(r2 > 0))
            return 0;
        double r = sqrt(r2);
        return -p->kc * p->def.radius / (r2 * r);
    }
    default: {
        if ((p->rc2 > 0 && !(r2 < p->rc2)) || !(r2 > 0))
            return 0;
        double r = sqrt(r2), hstep = 1e-6 * r;
        double fp = p->def.fn(p->def.ctx, r + hstep, NULL), fm = p->def.fn(p->def.ctx, r - hstep, NULL);
        double dF = (fp - fm) / (2 * hstep);
        return (dF - *g) / r2;
    }
    }
}

static void pair_jacobian(void *data, const psys_force_eval *e, psys_jacobian *J)
{
    pair_force *p = data;
    size_t n = e->n;
    int d = e->dim;
    p->stats.evaluations++;
    /* Barnes–Hut's point is to avoid the n² pairs, which an exact Jacobian
     * would need: implicit solvers treat it explicitly (no blocks). */
    if (n < 2 || p->def.method == PSYS_PAIR_BARNES_HUT)
        return;
    pair_image m;
    pair_image_of(&p->sys->box, &m);
    bool storage = pair_reserve(p, n);
    const double *w = pair_weights(p, e, storage);
    if (p->def.method == PSYS_PAIR_GRID)
        p->grid.want_full = true; /* the blocks go out in full-list order, whatever the thread count */
    bool lists = storage && p->def.method == PSYS_PAIR_GRID && psys__pair_grid_update(p, e);
    bool definite = psys_jacobian_wants_definite(J);
    for (size_t i = 0; i < n; i++) {
        double diag[9] = {0}, K[9];
        size_t t0 = lists ? p->grid.nb_start[i] : 0, t1 = lists ? t0 + p->grid.nb_num[i] : n;
        for (size_t t = t0; t < t1; t++) {
            size_t j = lists ? p->grid.nb[t] : t;
            if (j == i)
                continue;
            double dx[3], r2 = 0;
            for (int k = 0; k < d; k++) {
                dx[k] = pair_delta(&m, k, e->x[i * d + k] - e->x[j * d + k]);
                r2 += dx[k] * dx[k];
            }
            double c = p->law == PSYS_PAIR_COULOMB ? psys_system_charge(p->sys, i) * psys_system_charge(p->sys, j)
                                                   : w ? w[i] * w[j] : 1.0;
            double g, h = kernel_h(p, r2, c, &g);
            if (g == 0 && h == 0)
                continue;
            if (definite) {
                double along = g + h * r2, across = g;
                along = along < 0 ? along : 0;
                across = across < 0 ? across : 0;
                g = across;
                h = r2 > 0 ? (along - across) / r2 : 0;
            }
            for (int r = 0; r < d; r++)
                for (int c2 = 0; c2 < d; c2++) {
                    double kv = (r == c2 ? g : 0.0) + h * dx[r] * dx[c2];
                    K[r * d + c2] = -kv;
                    diag[r * d + c2] += kv;
                }
            psys_jacobian_add(J, i, j, K, NULL);
        }
        psys_jacobian_add(J, i, i, diag, NULL);
    }
}

/* Functions of the distances alone, user laws included. */
const psys_force_class psys_pair_class = {.name = "pair",
                                          .apply = pair_apply,
                                          .energy = pair_energy,
                                          .jacobian = pair_jacobian,
                                          .destroy = pair_destroy,
                                          .traits = PSYS_FORCE_VELOCITY_FREE};
const psys_force_class psys_pair_user_class = {.name = "user-pair",
                                               .apply = pair_apply,
                                               .energy = pair_energy,
                                               .jacobian = pair_jacobian,
                                               .destroy = pair_destroy,
                                               .traits = PSYS_FORCE_VELOCITY_FREE};

/* ---- C API ---- */

psys_status psys__pair_check_box(const void *data, const psys__box *box, char *msg, size_t cap)
{
    const pair_force *p = data;
    if (!box->on || !box->any_periodic)
        return PSYS_OK;
    if (!law_has_cutoff(&p->def)) {
        snprintf(msg, cap, "the %s law has no cutoff, so it cannot be used with a periodic box (no Ewald sums)",
                 p->law == PSYS_PAIR_USER ? "user" : psys_pair_law_name(p->def.law));
        return PSYS_ERR_INVALID;
    }
    for (int k = 0; k < p->dim; k++)
        if (box->periodic[k] && !(p->def.cutoff < 0.5 * box->len[k])) {
            snprintf(msg, cap, "the cutoff (%.17g) must be less than half the periodic box (box length %.17g on axis %d)",
                     p->def.cutoff, box->len[k], k);
            return PSYS_ERR_INVALID;
        }
    return PSYS_OK;
}

static bool fin(double x) { return isfinite(x); }

/* Validate def and resolve its defaults into out; message into msg. */
static psys_status resolve_def(const psys_pair_def *def, psys_pair_def *out, char *msg, size_t cap)
{
    *out = *def;
    switch (def->law) {
    case PSYS_PAIR_GRAVITY:
        if (!fin(def->G) || def->G < 0)
            return snprintf(msg, cap, "gravity G must be finite and >= 0 (got %g)", def->G), PSYS_ERR_INVALID;
        if (!fin(def->softening) || def->softening < 0)
            return snprintf(msg, cap, "gravity softening must be finite and >= 0 (got %g)", def->softening),
                   PSYS_ERR_INVALID;
        out->cutoff = 0;
        break;
    case PSYS_PAIR_COULOMB:
        if (!fin(def->k) || def->k < 0)
            return snprintf(msg, cap, "coulomb k must be finite and >= 0 (got %g)", def->k), PSYS_ERR_INVALID;
        out->cutoff = 0;
        break;
    case PSYS_PAIR_LENNARD_JONES:
        if (!fin(def->epsilon) || def->epsilon < 0)
            return snprintf(msg, cap, "lennard-jones epsilon must be finite and >= 0 (got %g)", def->epsilon),
                   PSYS_ERR_INVALID;
        if (!fin(def->sigma) || !(def->sigma > 0))
            return snprintf(msg, cap, "lennard-jones sigma must be finite and > 0 (got %g)", def->sigma),
                   PSYS_ERR_INVALID;
        if (!fin(def->cutoff))
            return snprintf(msg, cap, "lennard-jones cutoff must be finite (got %g)", def->cutoff), PSYS_ERR_INVALID;
        if (!(def->cutoff > 0))
            out->cutoff = 2.5 * def->sigma;
        break;
    case PSYS_PAIR_SOFT_REPULSION:
        if (!fin(def->k) || def->k < 0)
            return snprintf(msg, cap, "soft-repulsion k must be finite and >= 0 (got %g)", def->k), PSYS_ERR_INVALID;
        if (!fin(def->radius) || !(def->radius > 0))
            return snprintf(msg, cap, "soft-repulsion radius must be finite and > 0 (got %g)", def->radius),
                   PSYS_ERR_INVALID;
        out->cutoff = def->radius;
        break;
    case PSYS_PAIR_USER:
        if (!def->fn)
            return snprintf(msg, cap, "a user pair law needs a function (fn)"), PSYS_ERR_INVALID;
        if (!fin(def->cutoff) || def->cutoff < 0)
            return snprintf(msg, cap, "user pair law cutoff must be finite and >= 0 (got %g)", def->cutoff),
                   PSYS_ERR_INVALID;
        break;
    default:
        return snprintf(msg, cap, "unknown pair law %d", (int)def->law), PSYS_ERR_INVALID;
    }
    bool cut = law_has_cutoff(out);
    switch (def->method) {
    case PSYS_PAIR_AUTO:
        out->method = cut ? PSYS_PAIR_GRID : PSYS_PAIR_DIRECT;
        break;
    case PSYS_PAIR_DIRECT:
        break;
    case PSYS_PAIR_GRID:
        if (!cut)
            return snprintf(msg, cap, "method grid needs a law with a cutoff (lennard-jones, soft-repulsion, "
                                      "or a user law with cutoff > 0)"),
                   PSYS_ERR_INVALID;
        break;
    case PSYS_PAIR_BARNES_HUT:
        if (def->law != PSYS_PAIR_GRAVITY && def->law != PSYS_PAIR_COULOMB)
            return snprintf(msg, cap, "method barnes-hut is only for the long-range laws gravity and coulomb"),
                   PSYS_ERR_INVALID;
        break;
    default:
        return snprintf(msg, cap, "unknown pair method %d", (int)def->method), PSYS_ERR_INVALID;
    }
    if (out->method == PSYS_PAIR_GRID) {
        if (!fin(def->skin))
            return snprintf(msg, cap, "grid skin must be finite (got %g)", def->skin), PSYS_ERR_INVALID;
        if (def->skin < 0)
            out->skin = 0.1 * out->cutoff;
    }
    if (out->method == PSYS_PAIR_BARNES_HUT && (!fin(def->theta) || def->theta < 0))
        return snprintf(msg, cap, "barnes-hut theta must be finite and >= 0 (got %g)", def->theta), PSYS_ERR_INVALID;
    return PSYS_OK;
}

psys_status psys_system_add_pair(psys_system *sys, const psys_pair_def *def, size_t *force_index)
{
    char msg[300];
    psys_pair_def r;
    if (!def)
        return psys__fail(&sys->err, PSYS_ERR_INVALID, "no pair definition given");
    if (resolve_def(def, &r, msg, sizeof msg) != PSYS_OK)
        return psys__fail(&sys->err, PSYS_ERR_INVALID, "%s", msg);
    pair_force *p = calloc(1, sizeof *p);
    if (!p)
        return psys__fail(&sys->err, PSYS_ERR_NOMEM, "out of memory adding a pair force");
    p->sys = sys;
    p->def = r;
    p->dim = sys->dim;
    p->law = r.law;
    p->G = r.G;
    p->eps2 = r.softening * r.softening;
    p->kc = r.k;
    p->lj4 = 4.0 * r.epsilon;
    p->lj24 = 24.0 * r.epsilon;
    p->sig2 = r.sigma * r.sigma;
    p->rc2 = law_has_cutoff(&r) ? r.cutoff * r.cutoff : 0;
    if (r.law == PSYS_PAIR_LENNARD_JONES && r.shift) {
        double s2 = p->sig2 / p->rc2, s6 = s2 * s2 * s2;
        p->ushift = p->lj4 * s6 * (s6 - 1.0);
    }
    if (r.method == PSYS_PAIR_GRID) {
        double rl = r.cutoff + r.skin;
        p->rlist2 = rl * rl;
    }
    if (psys__pair_check_box(p, &sys->box, msg, sizeof msg) != PSYS_OK) {
        pair_destroy(p);
        return psys__fail(&sys->err, PSYS_ERR_INVALID, "%s", msg);
    }
    if (!pair_reserve(p, sys->n)) {
        pair_destroy(p);
        return psys__fail(&sys->err, PSYS_ERR_NOMEM, "out of memory for the pair force's storage");
    }
    const psys_force_class *cls = r.law == PSYS_PAIR_USER ? &psys_pair_user_class : &psys_pair_class;
    psys_status st = psys_system_add_force(sys, cls, p);
    if (st == PSYS_OK && force_index)
        *force_index = sys->nforces - 1;
    return st;
}

static const pair_force *pair_at(const psys_system *sys, size_t i)
{
    const psys_force_class *cls = psys_system_force_class(sys, i);
    if (cls != &psys_pair_class && cls != &psys_pair_user_class)
        return NULL;
    return psys_system_force_data(sys, i);
}

const psys_pair_def *psys__pair_def(const void *data) { return &((const pair_force *)data)->def; }

psys_status psys_system_pair(const psys_system *sys, size_t i, psys_pair_def *def)
{
    const pair_force *p = pair_at(sys, i);
    if (!p)
        return PSYS_ERR_INVALID;
    if (def)
        *def = p->def;
    return PSYS_OK;
}

psys_status psys_system_pair_stats(const psys_system *sys, size_t i, psys_pair_stats *stats)
{
    const pair_force *p = pair_at(sys, i);
    if (!p)
        return PSYS_ERR_INVALID;
    if (stats)
        *stats = p->stats;
    return PSYS_OK;
}

psys_status psys__system_pair_grouped(const psys_system *sys, size_t i, size_t *grouped)
{
    const pair_force *p = pair_at(sys, i);
    if (!p)
        return PSYS_ERR_INVALID;
    *grouped = p->grouped;
    return PSYS_OK;
}

