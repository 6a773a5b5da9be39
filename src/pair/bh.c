/* Barnes–Hut method of pair forces (gravity, coulomb): a quadtree in 2-D,
 * an octree in 3-D, built from scratch at every evaluation.
 *
 * Each node keeps its total weight W (mass, or charge) and the centre c of
 * its |weight|. Particle i uses a node as one pseudo-particle of weight W at
 * c when the node does not contain x_i and side/|x_i - c| < theta; otherwise
 * the node is opened; leaves (at most BH_LEAF particles, or at depth
 * BH_MAXDEPTH) are summed exactly. theta = 0 opens everything: the exact
 * sum (in tree order, so equal to direct only to rounding). Monopoles only:
 * for coulomb with charges of both signs, nodes whose charges nearly cancel
 * carry their dipole error uncorrected (docs/scene-format.md, "Pair forces").
 * The tree depends only on the current positions, and each particle's walk
 * is its own, so results are the same for every thread count. */
#include "pair/pair.h"

#include <stdlib.h>
#include <string.h>

void psys__pair_bh_free(pair_bh *b)
{
    free(b->nodes);
    free(b->perm);
    free(b->tmp);
    free(b->oct);
    memset(b, 0, sizeof *b);
}

bool psys__pair_bh_reserve(pair_bh *b, size_t cap)
{
    void *q;
    if (!(q = psys__realloc(b->perm, cap, sizeof(uint32_t))))
        return false;
    b->perm = q;
    if (!(q = psys__realloc(b->tmp, cap, sizeof(uint32_t))))
        return false;
    b->tmp = q;
    if (!(q = psys__realloc(b->oct, cap, 1)))
        return false;
    b->oct = q;
    size_t nodes = cap / 2 + 64;
    if (nodes > b->nodes_cap) {
        if (!(q = psys__realloc(b->nodes, nodes, sizeof(bh_node))))
            return false;
        b->nodes = q;
        b->nodes_cap = nodes;
    }
    return true;
}

typedef struct bh_build {
    pair_bh *b;
    const double *x, *w;
    int d;
    bool ok;
} bh_build;

/* Sums of a leaf's particles (ascending slot order). */
static void leaf_sums(bh_build *bb, bh_node *nd)
{
    const int d = bb->d;
    double s[3] = {0, 0, 0}, w = 0, wa = 0;
    for (uint32_t t = nd->first; t < nd->first + nd->count; t++) {
        uint32_t j = bb->b->perm[t];
        double wj = bb->w ? bb->w[j] : 1.0, aj = fabs(wj);
        w += wj;
        wa += aj;
        for (int k = 0; k < d; k++)
            s[k] += aj * bb->x[(size_t)j * d + k];
    }
    nd->w = w;
    nd->wabs = wa;
    for (int k = 0; k < 3; k++)
        nd->com[k] = wa > 0 && k < d ? s[k] / wa : nd->ctr[k];
}

static void build_node(bh_build *bb, size_t ni, uint32_t b0, uint32_t e0, int depth)
{
    pair_bh *b = bb->b;
    const int d = bb->d, nch = 1 << d;
    bh_node *nd = &b->nodes[ni];
    if (e0 - b0 <= BH_LEAF || depth >= BH_MAXDEPTH || !(nd->half > 0)) {
        nd->leaf = 1;
        nd->first = b0;
        nd->count = e0 - b0;
        leaf_sums(bb, nd);
        return;
    }
    /* octants, counting sort of the slot range (stable) */
    uint32_t count[8] = {0}, start[8];
    for (uint32_t t = b0; t < e0; t++) {
        uint32_t j = b->perm[t];
        unsigned o = 0;
        for (int k = 0; k < d; k++)
            if (bb->x[(size_t)j * d + k] >= nd->ctr[k])
                o |= 1u << k;
        b->oct[t] = (unsigned char)o;
        count[o]++;
    }
    uint32_t pos = b0, used = 0;
    for (int o = 0; o < nch; o++) {
        start[o] = pos;
        pos += count[o];
        used += count[o] > 0;
    }
    for (uint32_t t = b0; t < e0; t++)
        b->tmp[start[b->oct[t]]++] = b->perm[t];
    memcpy(b->perm + b0, b->tmp + b0, (size_t)(e0 - b0) * sizeof(uint32_t));
    /* children, contiguous */
    if (b->nnodes + used > b->nodes_cap) {
        size_t cap = 2 * b->nodes_cap + used;
        bh_node *q = psys__realloc(b->nodes, cap, sizeof(bh_node));
        if (!q) {
            bb->ok = false;
            return;
        }
        b->nodes = q;
        b->nodes_cap = cap;
        nd = &b->nodes[ni];
    }
    uint32_t first = (uint32_t)b->nnodes;
    double h = 0.5 * nd->half;
    uint32_t s = b0, c = first;
    for (int o = 0; o < nch; o++) {
        uint32_t e1 = s + count[o];
        if (count[o]) {
            bh_node *ch = &b->nodes[c++];
            memset(ch, 0, sizeof *ch);
            for (int k = 0; k < 3; k++)
                ch->ctr[k] = k < d ? nd->ctr[k] + ((o >> k) & 1 ? h : -h) : 0;
            ch->half = h;
            ch->first = s; /* slot range until built */
            ch->count = count[o];
        }
        s = e1;
    }
    b->nnodes += used;
    nd->leaf = 0;
    nd->first = first;
    nd->count = used;
    for (uint32_t k = 0; k < used && bb->ok; k++) {
        bh_node *ch = &b->nodes[first + k];
        build_node(bb, first + k, ch->first, ch->first + ch->count, depth + 1);
    }
    if (!bb->ok)
        return;
    nd = &b->nodes[ni];
    double sum[3] = {0, 0, 0}, w = 0, wa = 0;
    for (uint32_t k = 0; k < used; k++) {
        const bh_node *ch = &b->nodes[first + k];
        w += ch->w;
        wa += ch->wabs;
        for (int q = 0; q < d; q++)
            sum[q] += ch->wabs * ch->com[q];
    }
    nd->w = w;
    nd->wabs = wa;
    for (int k = 0; k < 3; k++)
        nd->com[k] = wa > 0 && k < d ? sum[k] / wa : nd->ctr[k];
}

bool psys__pair_bh_build(pair_force *p, const double *x, const double *w, size_t n)
{
    pair_bh *b = &p->bh;
    const int d = p->dim;
    for (size_t i = 0; i < n; i++)
        b->perm[i] = (uint32_t)i;
    double lo[3] = {0, 0, 0}, hi[3] = {0, 0, 0};
    for (int k = 0; k < d; k++) {
        double l = INFINITY, h = -INFINITY;
        for (size_t i = 0; i < n; i++) {
            double v = x[i * d + k];
            if (isfinite(v)) {
                if (v < l) l = v;
                if (v > h) h = v;
            }
        }
        if (!(l <= h))
            l = h = 0;
        lo[k] = l;
        hi[k] = h;
    }
    double half = 0;
    bh_node *root = &b->nodes[0];
    memset(root, 0, sizeof *root);
    for (int k = 0; k < d; k++) {
        root->ctr[k] = 0.5 * (lo[k] + hi[k]);
        double hk = 0.5 * (hi[k] - lo[k]);
        if (hk > half)
            half = hk;
    }
    root->half = isfinite(half) ? half * (1.0 + 1e-12) + 1e-300 : 0;
    b->nnodes = 1;
    bh_build bb = {b, x, w, d, true};
    build_node(&bb, 0, 0, (uint32_t)n, 0);
    p->stats.rebuilds++;
    p->stats.nodes = b->nnodes;
    return bb.ok;
}

/* Walk of the tree for particle i. */
PAIR_INLINE void bh_walk(const pair_force *p, const int law, const int d, const double *restrict x,
                         const double *restrict w, size_t i, double theta2, const bool want_f, double *acc,
                         const bool want_u, double *uacc)
{
    const pair_bh *b = &p->bh;
    const bh_node *nodes = b->nodes;
    double xi[3] = {0, 0, 0}, a[3] = {0, 0, 0}, us = 0;
    for (int k = 0; k < d; k++)
        xi[k] = x[i * d + k];
    const double wi = w ? w[i] : 1.0;
    uint32_t stack[BH_STACK];
    int sp = 0;
    stack[sp++] = 0;
    while (sp > 0) {
        const bh_node *nd = &nodes[stack[--sp]];
        if (nd->leaf) {
            for (uint32_t t = nd->first; t < nd->first + nd->count; t++) {
                size_t j = b->perm[t];
                if (j == i)
                    continue;
                double dx[3], r2 = 0;
                for (int k = 0; k < d; k++) {
                    dx[k] = xi[k] - x[j * d + k];
                    r2 += dx[k] * dx[k];
                }
                double u = 0, g = pair_kernel(p, law, r2, w ? wi * w[j] : 1.0, want_u, &u);
                if (want_f)
                    for (int k = 0; k < d; k++)
                        a[k] += g * dx[k];
                if (want_u)
                    us += u;
            }
            continue;
        }
        double dx[3], r2 = 0;
        bool inside = true;
        for (int k = 0; k < d; k++) {
            dx[k] = xi[k] - nd->com[k];
            r2 += dx[k] * dx[k];
            if (fabs(xi[k] - nd->ctr[k]) > nd->half)
                inside = false;
        }
        double side = 2.0 * nd->half;
        if (!inside && side * side < theta2 * r2) {
            if (nd->wabs > 0) {
                double u = 0, g = pair_kernel(p, law, r2, wi * nd->w, want_u, &u);
                if (want_f)
                    for (int k = 0; k < d; k++)
                        a[k] += g * dx[k];
                if (want_u)
                    us += u;
            }
            continue;
        }
        for (uint32_t c = nd->count; c > 0; c--)
            stack[sp++] = nd->first + c - 1;
    }
    for (int k = 0; k < d; k++)
        acc[k] = a[k];
    *uacc = us;
}

/* Instantiated per law, dimension and mode (see forces/pair.c). Particles in
 * tree order: neighbours walk the same nodes. */
#define BH_FN(name, LAW, D, WF, WU)                                                                          \
    static void name(pair_force *p, const psys_force_eval *e, const double *w, double *f, int nt)            \
    {                                                                                                        \
        const size_t n = e->n;                                                                               \
        const double theta2 = p->def.theta * p->def.theta;                                                   \
        const uint32_t *perm = p->bh.perm;                                                                   \
        double *ep = p->epart;                                                                               \
        const unsigned char *mk = WF ? psys__dist_mark(p->sys) : NULL; /* MPI: own rows only */             \
        (void)nt;                                                                                            \
        PSYS_OMP(omp parallel for schedule(dynamic, 32) num_threads(nt) if (nt > 1))                         \
        for (size_t t = 0; t < n; t++) {                                                                     \
            size_t i = perm[t];                                                                              \
            if (mk && !mk[i])                                                                                \
                continue;                                                                                    \
            double acc[3] = {0, 0, 0}, us = 0;                                                               \
            bh_walk(p, LAW, D, e->x, w, i, theta2, WF, acc, WU, &us);                                        \
            if (WF)                                                                                          \
                for (int k = 0; k < D; k++)                                                                  \
                    f[i * D + k] += acc[k];                                                                  \
            if (WU)                                                                                          \
                ep[i] = us;                                                                                  \
        }                                                                                                    \
    }

typedef void (*bh_fn)(pair_force *p, const psys_force_eval *e, const double *w, double *f, int nt);

BH_FN(bh_gravity_2f, PSYS_PAIR_GRAVITY, 2, true, false)
BH_FN(bh_gravity_2u, PSYS_PAIR_GRAVITY, 2, false, true)
BH_FN(bh_gravity_3f, PSYS_PAIR_GRAVITY, 3, true, false)
BH_FN(bh_gravity_3u, PSYS_PAIR_GRAVITY, 3, false, true)
BH_FN(bh_coulomb_2f, PSYS_PAIR_COULOMB, 2, true, false)
BH_FN(bh_coulomb_2u, PSYS_PAIR_COULOMB, 2, false, true)
BH_FN(bh_coulomb_3f, PSYS_PAIR_COULOMB, 3, true, false)
BH_FN(bh_coulomb_3u, PSYS_PAIR_COULOMB, 3, false, true)

static const bh_fn bh_fns[2][4] = {{bh_gravity_2f, bh_gravity_2u, bh_gravity_3f, bh_gravity_3u},
                                   {bh_coulomb_2f, bh_coulomb_2u, bh_coulomb_3f, bh_coulomb_3u}};

void psys__pair_bh_eval(pair_force *p, const psys_force_eval *e, const double *w, bool want_u, double *f)
{
    int nt = pair_threads(p, 256.0 * (double)e->n);
    int v = (p->dim == 3 ? 2 : 0) + (want_u ? 1 : 0);
    bh_fns[p->law == PSYS_PAIR_GRAVITY ? 0 : 1][v](p, e, w, f, nt);
}
