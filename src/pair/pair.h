/* Internals shared by the pair-force files (forces/pair.c, the grid's files
 * of pair/grid.h, pair/bh.c): the force object, the law kernels and the
 * minimum image.
 *
 * Determinism. Every method computes the force on particle i as a sum over
 * its partners j in increasing index order, starting from zero, and adds the
 * sum into f[i] once: in parallel each particle gathers over its full list;
 * on one thread the grid's half lists are swept in increasing i, adding
 * each pair's force to i and its negation to j, which reaches every
 * particle's sum in the same order. A pair's forces are computed from the
 * same numbers at both ends (x_i - x_j is exactly -(x_j - x_i), also under
 * the minimum image; r² and the sums with the same fused multiply-adds on
 * every path, pair_force_r2), so f_ij = -f_ji exactly; pairs beyond the
 * cutoff add exactly nothing. So `direct` and `grid` give bit-identical forces, results
 * do not depend on the thread count, the skin or when lists were rebuilt (a
 * resumed run matches an uninterrupted one). Energies: per-particle sums in
 * the same order, then ½ Σ_i in index order. */
#ifndef PSYS_PAIR_H
#define PSYS_PAIR_H

#include "core/core.h"

#include <math.h>
#include <stdint.h>


#if defined(__GNUC__)
#define PAIR_INLINE static inline __attribute__((always_inline))
#else
#define PAIR_INLINE static inline
#endif

/* Loops with less work than this (pair evaluations, roughly) run on one
 * thread, unless the system asks for a thread count explicitly: then only
 * loops below PAIR_PARALLEL_TINY do. */
#define PAIR_PARALLEL_MIN 65536.0
#define PAIR_PARALLEL_TINY 1024.0

/* Barnes–Hut: particles per leaf and the deepest level (coincident points end there). */
#define BH_LEAF 8
#define BH_MAXDEPTH 48
#define BH_STACK (8 * (BH_MAXDEPTH + 2))

typedef struct bh_node {
    double ctr[3];   /* geometric centre */
    double half;     /* half the side */
    double com[3];   /* centre of |weight| (mass or |charge|) */
    double w;        /* total weight: mass or charge */
    double wabs;     /* total |weight| */
    uint32_t first;  /* leaf: first slot in perm; else first child node */
    uint32_t count;  /* leaf: particles; else children */
    uint32_t leaf;
    uint32_t pad_;
} bh_node;

typedef struct pair_grid {
    size_t built_n;        /* particles at the last build (0: never built) */
    psys__box box;         /* box at the last build */
    double *xref;          /* cap·dim positions at the last build */
    size_t cells_cap;      /* cells the cell arrays hold */
    uint32_t *cell_start;  /* cells_cap + 1 */
    uint32_t *cell_of;     /* cap: cell of each particle */
    uint32_t *cell_list;   /* cap: particles by cell, ascending within a cell */
    double *cell_x;        /* cap·dim: their positions in that order (streamed by builds),
                              component-major: coordinate k of slot t at cell_x[k·cx_stride + t] */
    size_t cx_stride;      /* cap */
    size_t *nb_start;      /* cap: where particle i's list starts in nb */
    uint32_t *nb_num;      /* cap: its length */
    uint32_t *nb;          /* nb_cap neighbour indices, ascending per particle */
    size_t nb_cap;
    uint32_t *nb2;         /* nb2_cap: the lists being sorted by transposition (then swapped with nb) */
    size_t nb2_cap;
    size_t *nb_start2;     /* cap: its row starts */
    uint32_t *tcnt;        /* tcnt_cap: the transposition's counts per part and list */
    size_t tcnt_cap;
    size_t *chunk_off;     /* chunks_cap + 1: region of each chunk of particles in nb */
    size_t chunks_cap;
    double per_particle;   /* list entries per particle at the last build (region sizing) */
    size_t longest;        /* the longest list of the last cell-by-cell build (its room per particle) */
    void *win;             /* win_n per-thread candidate windows of the cell-by-cell build (pair/cells.c) */
    size_t win_n;
    bool half;             /* lists hold only partners j > i (one thread evaluates), else all */
    bool want_full;        /* full lists from now on (a Jacobian was asked for) */
    int ncell[3];
    double cell_lo[3], cell_size[3];
    /* force cache (laws that depend on positions only): forces of the last
     * evaluation and the positions they were computed at */
    double *fcache, *xcache;   /* cap·dim each */
    unsigned char *mark;       /* cap: particles to recompute (all 0 between evaluations) */
    uint32_t *changed;         /* cap: particles whose position changed (between builds; a build uses it as scratch) */
    bool cache_ok;
    size_t cache_n, cache_rebuilds;
    /* displacement check (pair/moved.c): the two largest squared
     * displacements since the build at xcache's positions (disp_ok), and
     * those of the evaluation under way (disp_now); moved_n particles in
     * changed[] differ from xcache when moved_ready (set by the check for
     * the evaluation that follows it, n / 8 + 1: too many to list) */
    bool disp_ok, moved_ready;
    double disp[2], disp_now[2];
    size_t moved_n;
    double *xq_mem, *xq;   /* cap·4 positions as records (x, y, z or 0, 0) for pair/group.c,
                              xq 32-byte aligned in xq_mem */
    bool xq_cached;        /* xq holds xcache's positions, within the bounds xq_lo, xq_hi */
    double xq_lo[3], xq_hi[3];
    /* pair/group.c's copy of the full lists, interleaved by groups of
     * gl_width rows (one load stream instead of one per row): the rows of
     * consecutive group slots, slot t being particle t or, with gl_cells,
     * the particle in slot t of the cell order (cell_list, from the same
     * build); entry k of slot b·gl_width + l's row at gl[gl_start[b] +
     * k·gl_width + l], as 4·j (the offset of j's record in xq), each row
     * padded with its own index to its group's longest list; gl_num[t] the
     * length of slot t's row's list */
    uint32_t *gl;
    uint32_t *gl_num;      /* cap */
    bool gl_cells;
    size_t gl_cap;
    size_t *gl_start;      /* gl_start_cap: groups + 1 */
    size_t gl_start_cap;
    int gl_width;
    bool gl_ok;            /* gl matches the lists (a build clears it) */
} pair_grid;

typedef struct pair_bh {
    bh_node *nodes;
    size_t nodes_cap, nnodes;
    uint32_t *perm, *tmp;  /* cap each */
    unsigned char *oct;    /* cap */
} pair_bh;

typedef struct pair_force {
    psys_system *sys;      /* owner: box, charges, threads */
    psys_pair_def def;     /* as added, defaults and method resolved */
    int dim;
    int law;               /* def.law */
    /* kernel constants */
    double G, eps2, kc;    /* gravity; coulomb / soft-repulsion k */
    double lj4, lj24, sig2, ushift;
    double rc2;            /* squared cutoff (0: none) */
    double rlist2;         /* grid: (cutoff + skin)² */
    size_t cap;            /* particles the per-particle buffers hold */
    double *epart;         /* cap per-particle energies */
    double *wbuf;          /* coulomb: cap charges (0 past the system's charge array) */
    double *xsoa;          /* cap·dim: the positions by component (x_k of particle j at
                              xsoa[k·cap + j]) for the vectorised loops (pair_soa_positions) */
    pair_grid grid;
    pair_bh bh;
    psys_pair_stats stats;
    size_t grouped;        /* psys__system_pair_grouped */
} pair_force;

/* Minimum-image parameters of one evaluation. */
typedef struct pair_image {
    bool on;
    bool per[3];
    double len[3], half[3], inv[3]; /* inv: 1/len, so images need no division */
    double far[3];                  /* 1.5·len: below it the nearest image is one box away */
} pair_image;

PAIR_INLINE void pair_image_of(const psys__box *b, pair_image *m)
{
    m->on = b->on && b->any_periodic;
    for (int k = 0; k < 3; k++) {
        m->per[k] = m->on && b->periodic[k];
        m->len[k] = b->len[k];
        m->half[k] = 0.5 * b->len[k];
        m->inv[k] = m->per[k] ? 1.0 / b->len[k] : 1.0;
        m->far[k] = 1.5 * b->len[k];
    }
}

/* nearbyint(y) in the default rounding mode, without a call or a rounding
 * instruction (so loops using it vectorise on any x86-64): below 2^52 in
 * magnitude, adding and removing 2^52 rounds to the nearest integer, ties to
 * even; from 2^52 on, y is already an integer (or inf, NaN). Odd in y. */
PAIR_INLINE double pair_rint(double y)
{
    const double a = fabs(y), r = (a + 0x1p52) - 0x1p52;
    return a < 0x1p52 ? copysign(r, y) : y;
}

/* x_i - x_j on one axis under the minimum image (odd in dx, so exact
 * antisymmetry holds): past half a box, one box length off while below 1.5
 * boxes (the usual case: particles are wrapped into the box after every
 * step), else the image index rounded from dx·(1/len) (no division). */
PAIR_INLINE double pair_delta(const pair_image *m, int k, double dx)
{
    if (m->on && m->per[k] && fabs(dx) > m->half[k])
        dx = fabs(dx) < m->far[k] ? dx - copysign(m->len[k], dx) : dx - m->len[k] * pair_rint(dx * m->inv[k]);
    return dx;
}

/* pair_delta with the image's tests folded into per-axis numbers, for
 * vectorised loops: hl[k] = half the box length on an active periodic axis,
 * +inf otherwise (never exceeded), ln[k] the length, il[k] its inverse (1
 * where unused), fr[k] 1.5 lengths (+inf where unused). With exact,
 * pair_delta_folded gives pair_delta's result for every dx, NaN included. */
PAIR_INLINE void pair_image_fold(const pair_image *m, double hl[3], double ln[3], double il[3], double fr[3])
{
    for (int k = 0; k < 3; k++) {
        const bool on = m->on && m->per[k];
        hl[k] = on ? m->half[k] : INFINITY;
        ln[k] = on ? m->len[k] : 1.0;
        il[k] = on ? m->inv[k] : 1.0;
        fr[k] = on ? m->far[k] : INFINITY;
    }
}

/* exact: pair_delta for every dx; else only for |dx| < fr (the caller checks). */
PAIR_INLINE double pair_delta_folded(double hl, double ln, double il, double fr, double dx, const bool exact)
{
    const double a = fabs(dx), near = dx - copysign(ln, dx);
    if (!exact)
        return a > hl ? near : dx;
    const double wrapped = dx - ln * pair_rint(dx * il);
    return a > hl ? (a < fr ? near : wrapped) : dx;
}

/* The law kernel: for squared distance r2 and pair coefficient c (m_i m_j
 * for gravity, q_i q_j for coulomb, 1 otherwise) return g such that the force
 * on i is g·(x_i - x_j); with want_u the pair energy goes to *u. Outside the
 * cutoff and at r2 = 0 (softened gravity: never) the result is 0. */
PAIR_INLINE double pair_kernel(const pair_force *p, const int law, double r2, double c, const bool want_u, double *u)
{
    /* Built-in laws compute on a safe argument and select the result (no
     * branches), so loops over pairs vectorise; the same bits as branching. */
    switch (law) {
    case PSYS_PAIR_GRAVITY: {
        double s2 = r2 + p->eps2;
        const bool ok = s2 > 0;
        double inv = 1.0 / sqrt(ok ? s2 : 1.0), a = p->G * c;
        if (want_u) *u = ok ? -a * inv : 0.0;
        double g = -a * (inv * inv * inv);
        return ok ? g : 0.0;
    }
    case PSYS_PAIR_COULOMB: {
        const bool ok = r2 > 0;
        double inv = 1.0 / sqrt(ok ? r2 : 1.0), a = p->kc * c;
        if (want_u) *u = ok ? a * inv : 0.0;
        double g = a * (inv * inv * inv);
        return ok ? g : 0.0;
    }
    case PSYS_PAIR_LENNARD_JONES: {
        /* evaluated unconditionally, then selected: neighbour lists hold many
         * pairs just beyond the cutoff, where a branch would mispredict */
        const bool in = (r2 < p->rc2) & (r2 > 0);
        double ir2 = 1.0 / (in ? r2 : 1.0), s2 = p->sig2 * ir2, s6 = s2 * s2 * s2;
        if (want_u) *u = in ? p->lj4 * s6 * (s6 - 1.0) - p->ushift : 0.0;
        double g = p->lj24 * s6 * (2.0 * s6 - 1.0) * ir2;
        return in ? g : 0.0;
    }
    case PSYS_PAIR_SOFT_REPULSION: {
        const bool in = (r2 < p->rc2) & (r2 > 0);
        double r = sqrt(in ? r2 : 1.0), dr = p->def.radius - r;
        if (want_u) *u = in ? 0.5 * p->kc * dr * dr : 0.0;
        double g = p->kc * dr / r;
        return in ? g : 0.0;
    }
    default: { /* PSYS_PAIR_USER */
        if ((p->rc2 > 0 && !(r2 < p->rc2)) || !(r2 > 0)) {
            if (want_u) *u = 0;
            return 0;
        }
        double r = sqrt(r2);
        double f = p->def.fn(p->def.ctx, r, want_u ? u : NULL);
        return f / r;
    }
    }
}

/* A pair's force terms, formed the same way on every path (the scalar
 * loops here, the row loops built for x86-64-v3 and AVX-512, pair/group.c's
 * four- and eight-lane loops): r² is dx0², then dx1² and dx2² each fused into the
 * sum, and each term g·dx_k is fused into its running sum. A fused
 * multiply-add rounds once where a product and a sum round twice; it is
 * correctly rounded wherever it runs (one instruction where the CPU has FMA,
 * libm's fma elsewhere), so every path keeps giving the same bits, and the
 * vector loops spend five instructions fewer per pair. Energies, Barnes–Hut
 * and the Jacobian keep plain products and sums: nothing compares them bit
 * for bit with the forces. */
PAIR_INLINE double pair_force_r2(const int d, double dx0, double dx1, double dx2)
{
    const double r2 = fma(dx1, dx1, dx0 * dx0);
    return d == 3 ? fma(dx2, dx2, r2) : r2;
}

/* r² for energies (and the other plain paths): the sum of the products. */
PAIR_INLINE double pair_plain_r2(const int d, double dx0, double dx1, double dx2)
{
    double r2 = 0;
    r2 += dx0 * dx0;
    r2 += dx1 * dx1;
    if (d == 3)
        r2 += dx2 * dx2;
    return r2;
}

/* Gather for particle i over its partners, js[0..nj) (ascending) when
 * `list`, else the index range [j0, j0 + nj) without i: force sum into acc
 * (dim numbers, not cleared) and energy sum into *uacc. w: per-particle
 * weights (NULL = 1). */
PAIR_INLINE void pair_gather(const pair_force *p, const int law, const int d, const pair_image *m,
                             const double *restrict x, const double *restrict w, size_t i,
                             const uint32_t *restrict js, size_t j0, size_t nj, const bool list, const bool want_f,
                             double *acc, const bool want_u, double *uacc)
{
    double xi[3] = {0, 0, 0}, a[3] = {acc[0], acc[1], d == 3 ? acc[2] : 0}, us = *uacc;
    for (int k = 0; k < d; k++)
        xi[k] = x[i * d + k];
    const double wi = w ? w[i] : 1.0;
    for (size_t t = 0; t < nj; t++) {
        const size_t j = list ? js[t] : j0 + t;
        if (!list && j == i)
            continue;
        double dx[3] = {0, 0, 0};
        for (int k = 0; k < d; k++)
            dx[k] = pair_delta(m, k, xi[k] - x[j * d + k]);
        const double r2 = want_f ? pair_force_r2(d, dx[0], dx[1], dx[2]) : pair_plain_r2(d, dx[0], dx[1], dx[2]);
        double u = 0;
        double g = pair_kernel(p, law, r2, w ? wi * w[j] : 1.0, want_u, &u);
        if (want_f)
            for (int k = 0; k < d; k++)
                a[k] = fma(g, dx[k], a[k]);
        if (want_u)
            us += u;
    }
    for (int k = 0; k < d; k++)
        acc[k] = a[k];
    *uacc = us;
}

#define ROW_BLOCK 128 /* partners per pass of pair_row_forces */

/* Pass one of pair_row_forces over partners t < nb: cg[t] = g, c_k[t] = dx_k. With
 * exact false the minimum image takes the one-box shortcut, and the return
 * value says whether some |dx| reached 1.5 boxes (then the caller runs the
 * block again with exact: the shortcut is pair_delta wherever it is used). */
PAIR_INLINE bool pair_row_terms(const pair_force *pk, const int law, const int d, const double *restrict X0,
                                const double *restrict X1, const double *restrict X2, const double *restrict w,
                                size_t i, const uint32_t *restrict jb, size_t jr, size_t nb, const bool list,
                                const double *hl, const double *ln, const double *il, const double *fr,
                                double *restrict cg, double *restrict c0, double *restrict c1, double *restrict c2,
                                const bool exact)
{
    const double xi0 = X0[i], xi1 = X1[i], xi2 = d == 3 ? X2[i] : 0;
    const bool weighted = law == PSYS_PAIR_GRAVITY || law == PSYS_PAIR_COULOMB;
    const double wi = weighted ? w[i] : 1.0;
    int far = 0;
    for (size_t t = 0; t < nb; t++) {
        const size_t j = list ? jb[t] : jr + t;
        const double e0 = xi0 - X0[j], e1 = xi1 - X1[j], e2 = d == 3 ? xi2 - X2[j] : 0;
        if (!exact)
            far |= (fabs(e0) >= fr[0]) | (fabs(e1) >= fr[1]) | (d == 3 && fabs(e2) >= fr[2]);
        double dx0 = pair_delta_folded(hl[0], ln[0], il[0], fr[0], e0, exact);
        double dx1 = pair_delta_folded(hl[1], ln[1], il[1], fr[1], e1, exact), dx2 = 0;
        if (d == 3)
            dx2 = pair_delta_folded(hl[2], ln[2], il[2], fr[2], e2, exact);
        const double r2 = pair_force_r2(d, dx0, dx1, dx2);
        double u;
        cg[t] = pair_kernel(pk, law, r2, weighted ? wi * w[j] : 1.0, false, &u);
        c0[t] = dx0;
        c1[t] = dx1;
        if (d == 3)
            c2[t] = dx2;
    }
    return far != 0;
}

/* pair_gather for forces only, in two passes per block of ROW_BLOCK
 * partners: each pair's g and dx, computed independently (the loop
 * vectorises), then the terms g·dx fused into the sums in list order. The
 * operations per pair and the order of the sum are those of
 * pair_gather, so the bits are the same; acc starts the sum as there. Partners as in
 * pair_gather.
 * Weights: w[i]·w[j] for gravity and coulomb (w must not be NULL then),
 * none for the other laws. */
PAIR_INLINE void pair_row_forces(const pair_force *p, const int law, const int d, const pair_image *m,
                                 const double *restrict w, size_t i, const uint32_t *restrict js, size_t j0,
                                 size_t nj, const bool list, double *acc)
{
    /* positions from the SoA copy (pair_soa_positions): a partner's three
     * coordinates are three plain indexed loads, no index arithmetic */
    const double *restrict X0 = p->xsoa, *restrict X1 = X0 + p->cap, *restrict X2 = X1 + p->cap;
    double cg[ROW_BLOCK], c0[ROW_BLOCK], c1[ROW_BLOCK], c2[ROW_BLOCK];
    /* The kernel's constants in a local object: always safe to load, so the
     * compiler may evaluate both sides of the kernel's selects. */
    pair_force pk;
    pk.G = p->G;
    pk.eps2 = p->eps2;
    pk.kc = p->kc;
    pk.lj4 = p->lj4;
    pk.lj24 = p->lj24;
    pk.sig2 = p->sig2;
    pk.ushift = p->ushift;
    pk.rc2 = p->rc2;
    pk.def.radius = p->def.radius;
    double a0 = acc[0], a1 = acc[1], a2 = d == 3 ? acc[2] : 0, hl[3], ln[3], il[3], fr[3];
    pair_image_fold(m, hl, ln, il, fr);
    for (size_t t0 = 0; t0 < nj; t0 += ROW_BLOCK) {
        const size_t nb = nj - t0 < ROW_BLOCK ? nj - t0 : ROW_BLOCK;
        const uint32_t *restrict jb = list ? js + t0 : NULL;
        const size_t jr = j0 + t0;
        if (pair_row_terms(&pk, law, d, X0, X1, X2, w, i, jb, jr, nb, list, hl, ln, il, fr, cg, c0, c1, c2, false))
            pair_row_terms(&pk, law, d, X0, X1, X2, w, i, jb, jr, nb, list, hl, ln, il, fr, cg, c0, c1, c2, true);
        /* a range holding i sums around it, as pair_gather skips it */
        const size_t skip = !list && i >= jr && i < jr + nb ? i - jr : nb;
        for (size_t t = 0; t < skip; t++) {
            a0 = fma(cg[t], c0[t], a0);
            a1 = fma(cg[t], c1[t], a1);
            if (d == 3)
                a2 = fma(cg[t], c2[t], a2);
        }
        for (size_t t = skip + 1; t < nb; t++) {
            a0 = fma(cg[t], c0[t], a0);
            a1 = fma(cg[t], c1[t], a1);
            if (d == 3)
                a2 = fma(cg[t], c2[t], a2);
        }
    }
    acc[0] = a0;
    acc[1] = a1;
    if (d == 3)
        acc[2] = a2;
}

/* Whether forces of n particles may go through pair_row_forces: a built-in
 * law, its weights present, and the SoA copy of the positions big enough
 * (not so in the fallback after storage failed to grow). */
PAIR_INLINE bool pair_can_vectorise(const pair_force *p, const double *w, size_t n)
{
    const bool weighted = p->law == PSYS_PAIR_GRAVITY || p->law == PSYS_PAIR_COULOMB;
    return p->law != PSYS_PAIR_USER && (w || !weighted) && p->xsoa && n <= p->cap;
}

/* Fill p->xsoa from the particle-major positions x (n particles). */
PAIR_INLINE void pair_soa_positions(const pair_force *p, const double *restrict x, size_t n, int nt)
{
    const int d = p->dim;
    double *restrict X = p->xsoa;
    const size_t cs = p->cap;
    (void)nt;
    PSYS_OMP(omp parallel for schedule(static) num_threads(nt) if (nt > 1 && n >= PSYS_PAR_MIN))
    for (size_t i = 0; i < n; i++)
        for (int k = 0; k < d; k++)
            X[(size_t)k * cs + i] = x[i * (size_t)d + (size_t)k];
}

/* Threads for a loop of about `work` pair evaluations. */
static inline int pair_threads(const pair_force *p, double work)
{
#ifdef _OPENMP
    if (p->sys->threads > 0)
        return work < PAIR_PARALLEL_TINY ? 1 : p->sys->threads;
    return work < PAIR_PARALLEL_MIN ? 1 : omp_get_max_threads();
#else
    (void)p;
    (void)work;
    return 1;
#endif
}

/* Built-in laws always use full lists: each particle gathers from all its
 * partners (pair_row_forces, vectorised; each pair is evaluated twice, in
 * parallel on any thread count). User laws call back per pair, which does
 * not vectorise: for them the grid keeps half lists (partners j > i, each
 * pair evaluated once, in a serial sweep) up to two threads and full lists
 * from three on. Every variant adds each particle's contributions in
 * increasing partner order, so they all give the same bits (forces/pair.c). */
static inline bool pair_grid_wants_half(const pair_force *p, size_t n)
{
    if (p->grid.want_full || p->law != PSYS_PAIR_USER)
        return false;
    double per = p->grid.per_particle > 0 ? p->grid.per_particle : 32.0;
    return pair_threads(p, per * (double)n) <= 2;
}

/* ---- pair/grid.c, pair/moved.c, pair/scan.c ---- */
/** Make the neighbour lists valid for positions x (rebuild if the two largest
 *  displacements add up to the skin, the particle count, the box or the
 *  wanted kind of list (half, full) changed).
 *  False if storage could not grow (the caller falls back to direct). */
bool psys__pair_grid_update(pair_force *p, const psys_force_eval *e);
/** Free grid storage. */
void psys__pair_grid_free(pair_grid *g);
/** The particles whose positions x differ from xcache, in index order, into
 *  pair_grid.changed; their count, or n / 8 + 1 if more than n / 8. */
size_t psys__pair_grid_moved(pair_force *p, const double *x, size_t n);
/** MPI domain (ghosts have no lists): mark (|= 1) every owned particle in the
 *  cells around ghost c's cell at the last build, the cells a list build
 *  scans: a superset of the owned particles whose lists hold c. */
void psys__pair_grid_mark_near(const pair_grid *g, const pair_image *m, int d, uint32_t c, const unsigned char *own,
                               unsigned char *mark);
/** Sort a list of indices ascending the way the list builds of sys do (exposed for the tests). */
void psys__pair_sort_list(const psys_system *sys, uint32_t *a, size_t n);
/** Grow grid per-particle storage to cap particles. */
bool psys__pair_grid_reserve(pair_grid *g, size_t cap, int dim);

/* ---- pair/group.c ---- */
/** Grid forces over the full lists of every row (or the marked ones) stored
 *  into out, four or eight rows at a time, from the positions x (particle
 *  major; copied as records, and into p->xsoa only where some row may go
 *  through pair_row_forces): the same bits as pair_row_forces. changed: when
 *  not NULL, the records (pair_grid.xq, xq_cached) hold xcache, from which
 *  x differs only in particles changed[0..nchanged): only theirs are
 *  copied. xc (may be NULL; with changed NULL): x is copied there too.
 *  False if that path does not run here (a law it does not
 *  support, no AVX2, PSYS_GROUP_OFF set, no interleaved lists for its
 *  width); nothing was written. */
bool psys__pair_group_forces(pair_force *p, const pair_image *m, const double *x, const double *w, size_t n,
                             const unsigned char *rows, const uint32_t *changed, size_t nchanged, double *xc,
                             double *out, int nt);
/** After a build of full lists: the interleaved copy psys__pair_group_forces
 *  reads (pair_grid.gl), where that path runs. False if storage could not grow. */
bool psys__pair_group_lists(pair_force *p, size_t n, int nt);

/* ---- pair/bh.c ---- */
/** Build the tree for positions x and weights w (n particles). False if storage could not grow. */
bool psys__pair_bh_build(pair_force *p, const double *x, const double *w, size_t n);
/** Forces added into f, or (want_u) per-particle energies into p->epart, from the tree. */
void psys__pair_bh_eval(pair_force *p, const psys_force_eval *e, const double *w, bool want_u, double *f);
/** Free tree storage. */
void psys__pair_bh_free(pair_bh *b);
/** Grow tree per-particle storage to cap particles. */
bool psys__pair_bh_reserve(pair_bh *b, size_t cap);

#endif
