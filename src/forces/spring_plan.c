/* The spring set's run plan: springs regrouped into runs of equal offset
 * (plan_build), an internal Cuthill-McKee order for sets numbered out of
 * order, the windows and scratch the loops need, the order of additions and
 * the threads' shares of the runs. Apart from the physics (forces/spring.c)
 * because it is bookkeeping built once per spring set, not a loop. */
#include "forces/springs.h"

#include <stdint.h>
#include <stdlib.h>
#include <string.h>

void psys__springs_plan_free(springs *s)
{
    free(s->run_lo);
    free(s->run_off);
    free(s->run_len);
    free(s->run_k);
    free(s->run_uni);
    free(s->pks);
    free(s->pkd);
    free(s->prest);
    free(s->pos);
    free(s->perm);
    s->perm = NULL;
    s->perm_n = 0;
    s->run_lo = s->run_off = s->run_len = NULL;
    s->run_k = s->pos = NULL;
    s->run_uni = NULL;
    s->pks = s->pkd = s->prest = NULL;
    s->nruns = 0;
    s->plan_ok = false;
}

typedef struct plan_item {
    uint64_t key; /* block of lo, offset, lo within the block */
    size_t k;
} plan_item;

static int plan_cmp(const void *p, const void *q)
{
    const plan_item *a = p, *b = q;
    if (a->key != b->key)
        return a->key < b->key ? -1 : 1;
    return (a->k > b->k) - (a->k < b->k);
}

/* Sets of at least this many springs may be given an internal order
 * (psys__springs_plan); smaller ones stay in cache whatever their order. */
#define SPRING_ORDER_MIN 4096

/* Mean |slot(a) - slot(b)| over the springs (slot NULL: the identity). */
static double mean_offset(const springs *s, const uint32_t *slot)
{
    double sum = 0;
    for (size_t k = 0; k < s->n; k++) {
        const size_t a = slot ? slot[s->a[k]] : s->a[k], b = slot ? slot[s->b[k]] : s->b[k];
        sum += (double)(a > b ? a - b : b - a);
    }
    return s->n ? sum / (double)s->n : 0.0;
}

/* Breadth-first search from r over the graph (xadj, adj), marking with
 * `mark` and appending to q from *qn; returns the number of levels and
 * leaves the last level's first entry in *last. */
static size_t bfs_levels(const size_t *xadj, const uint32_t *adj, uint32_t *seen, uint32_t mark, uint32_t r,
                         uint32_t *q, size_t *qn, size_t *last)
{
    size_t head = *qn, levels = 0;
    q[(*qn)++] = r;
    seen[r] = mark;
    while (head < *qn) {
        const size_t end = *qn;
        *last = head;
        levels++;
        for (; head < end; head++)
            for (size_t e = xadj[q[head]]; e < xadj[q[head] + 1]; e++)
                if (seen[adj[e]] != mark) {
                    seen[adj[e]] = mark;
                    q[(*qn)++] = adj[e];
                }
    }
    return levels;
}

static int cmp_u64(const void *p, const void *q)
{
    const uint64_t a = *(const uint64_t *)p, b = *(const uint64_t *)q;
    return (a > b) - (a < b);
}

/* Cuthill–McKee order of particles [0, m) over the spring graph: component
 * by component (in order of their lowest particle), breadth first from a
 * pseudo-peripheral particle (George and Liu: the far level's particle of
 * least degree, while the depth grows), each particle's unvisited
 * neighbours by increasing degree then index; particles with no spring
 * last. Neighbours end up close in the order (a grid's rows become its
 * diagonals): the spring loops touch a narrow band of memory. Depends only
 * on the springs' ends. perm[slot] = particle; NULL when out of memory. */
static uint32_t *cuthill_mckee(const springs *s, size_t m)
{
    size_t *xadj = psys__calloc(m + 1, sizeof *xadj);
    uint32_t *adj = psys__calloc(2 * s->n + 1, sizeof *adj), *seen = psys__calloc(m, sizeof *seen);
    uint32_t *perm = psys__calloc(m, sizeof *perm), *q = psys__calloc(m, sizeof *q);
    if (!xadj || !adj || !seen || !perm || !q) {
        free(xadj), free(adj), free(seen), free(perm), free(q);
        return NULL;
    }
    for (size_t k = 0; k < s->n; k++) {
        xadj[s->a[k] + 1]++;
        xadj[s->b[k] + 1]++;
    }
    for (size_t i = 0; i < m; i++)
        xadj[i + 1] += xadj[i];
    {
        size_t *fill = xadj; /* each start advanced to its end, then shifted back */
        for (size_t k = 0; k < s->n; k++) {
            adj[fill[s->a[k]]++] = s->b[k];
            adj[fill[s->b[k]]++] = s->a[k];
        }
        for (size_t i = m; i > 0; i--)
            xadj[i] = xadj[i - 1];
        xadj[0] = 0;
    }
    /* each list by increasing degree, then index: (degree, index) keys */
    size_t most = 0;
    for (size_t i = 0; i < m; i++)
        most = xadj[i + 1] - xadj[i] > most ? xadj[i + 1] - xadj[i] : most;
    uint64_t *key = psys__calloc(most ? most : 1, sizeof *key);
    if (!key) {
        free(xadj), free(adj), free(seen), free(perm), free(q);
        return NULL;
    }
    for (size_t i = 0; i < m; i++) {
        const size_t len = xadj[i + 1] - xadj[i];
        for (size_t t = 0; t < len; t++) {
            const uint32_t v = adj[xadj[i] + t];
            key[t] = (uint64_t)(xadj[v + 1] - xadj[v]) << 32 | v;
        }
        qsort(key, len, sizeof *key, cmp_u64);
        for (size_t t = 0; t < len; t++)
            adj[xadj[i] + t] = (uint32_t)key[t];
    }
    free(key);
    size_t n = 0;
    uint32_t mark = 0;
    for (size_t i = 0; i < m; i++) {
        if (seen[i] != 0 || xadj[i + 1] == xadj[i])
            continue;
        /* a pseudo-peripheral start, found with scratch searches at the end of q */
        uint32_t r = (uint32_t)i;
        size_t depth = 0;
        for (int it = 0; it < 8; it++) {
            size_t qn = n, last = n;
            const size_t lv = bfs_levels(xadj, adj, seen, ++mark, r, q, &qn, &last);
            if (it > 0 && lv <= depth)
                break;
            depth = lv;
            uint32_t best = q[last];
            for (size_t t = last; t < qn; t++) {
                const uint32_t c = q[t];
                const size_t dc = xadj[c + 1] - xadj[c], db = xadj[best + 1] - xadj[best];
                if (dc < db || (dc == db && c < best))
                    best = c;
            }
            r = best;
        }
        /* the component in order, kept (its marks stay: never 0) */
        size_t last = n;
        bfs_levels(xadj, adj, seen, ++mark, r, q, &n, &last);
    }
    for (size_t i = 0; i < m; i++)
        if (xadj[i + 1] == xadj[i])
            q[n++] = (uint32_t)i;
    memcpy(perm, q, m * sizeof *perm);
    free(xadj), free(adj), free(seen), free(q);
    return perm;
}

/* The plan of s's springs with particle i in slot[i] (slot NULL: in slot
 * i) into p's plan fields (allocated here; psys__springs_plan_free(p) on failure). */
static psys_status plan_build(const springs *s, const uint32_t *slot, springs *p)
{
    const size_t S = s->n, cap = S ? S : 1;
    plan_item *it = psys__calloc(cap, sizeof *it);
    p->run_lo = psys__calloc(cap, sizeof *p->run_lo);
    p->run_off = psys__calloc(cap, sizeof *p->run_off);
    p->run_len = psys__calloc(cap, sizeof *p->run_len);
    p->run_k = psys__calloc(cap, sizeof *p->run_k);
    p->run_uni = psys__calloc(cap, sizeof *p->run_uni);
    p->pks = psys__calloc(cap, sizeof *p->pks);
    p->pkd = psys__calloc(cap, sizeof *p->pkd);
    p->prest = psys__calloc(cap, sizeof *p->prest);
    p->pos = psys__calloc(cap, sizeof *p->pos);
    if (!it || !p->run_lo || !p->run_off || !p->run_len || !p->run_k || !p->run_uni || !p->pks || !p->pkd
        || !p->prest || !p->pos) {
        free(it);
        psys__springs_plan_free(p);
        return PSYS_ERR_NOMEM;
    }
#define SLOT_OF(i) (slot ? slot[i] : (i))
    for (size_t k = 0; k < S; k++) {
        uint64_t a = SLOT_OF(s->a[k]), b = SLOT_OF(s->b[k]), lo = a < b ? a : b, off = a < b ? b - a : a - b;
        it[k].key = (lo >> 8) << 40 | off << 8 | (lo & 255);
        it[k].k = k;
    }
    qsort(it, S, sizeof *it, plan_cmp);
    size_t nr = 0;
    p->max_off = 0;
    for (size_t i = 0; i < S; i++) {
        size_t k = it[i].k;
        uint32_t a = SLOT_OF(s->a[k]), b = SLOT_OF(s->b[k]), lo = a < b ? a : b, off = a < b ? b - a : a - b;
        if (nr == 0 || off != p->run_off[nr - 1] || lo != p->run_lo[nr - 1] + p->run_len[nr - 1]
            || p->run_len[nr - 1] == SPRING_BLOCK) {
            p->run_lo[nr] = lo;
            p->run_off[nr] = off;
            p->run_len[nr] = 0;
            p->run_k[nr] = i;
            p->run_uni[nr] = 1;
            nr++;
        } else if (memcmp(&s->ks[k], &p->pks[p->run_k[nr - 1]], sizeof(double))
                   || memcmp(&s->kd[k], &p->pkd[p->run_k[nr - 1]], sizeof(double))) {
            p->run_uni[nr - 1] = 0; /* not all the run's springs share ks and kd */
        }
        p->run_len[nr - 1]++;
        if (off > p->max_off)
            p->max_off = off;
        p->pks[i] = s->ks[k];
        p->pkd[i] = s->kd[k];
        p->prest[i] = s->rest[k];
        p->pos[k] = i;
    }
#undef SLOT_OF
    free(it);
    p->nruns = nr;
    return PSYS_OK;
}

/* Build the plan for the current spring set (allocates; called before a
 * step through psys__springs_prepare, so failure is an error status). */
psys_status psys__springs_plan(springs *s)
{
    if (s->plan_ok && s->plan_version == s->version)
        return PSYS_OK;
    const size_t S = s->n;
    springs p = {0};
    psys_status st = plan_build(s, NULL, &p);
    if (st != PSYS_OK)
        return st;
    /* The internal order: the particles' own, unless it leaves the springs
     * in runs shorter than SPRING_SHORT on average (no rows to stream: a
     * mesh numbered out of order) and the Cuthill–McKee order brings them
     * at least twice as close on average (bench/README.md).
     * PSYS_SPRING_ORDER=0 in the environment keeps the particles' own
     * (benchmarks compare the two). */
    const bool own_order = s->owner && s->owner->sw.spring_order_off;
    if (S >= SPRING_ORDER_MIN && p.nruns * SPRING_SHORT > S && !own_order) {
        size_t m = 0;
        for (size_t k = 0; k < S; k++) {
            m = s->a[k] + (size_t)1 > m ? s->a[k] + (size_t)1 : m;
            m = s->b[k] + (size_t)1 > m ? s->b[k] + (size_t)1 : m;
        }
        uint32_t *perm = cuthill_mckee(s, m), *slot = perm ? psys__calloc(m, sizeof *slot) : NULL;
        springs q = {0};
        if (!slot) {
            free(perm);
            psys__springs_plan_free(&p);
            return PSYS_ERR_NOMEM;
        }
        for (size_t i = 0; i < m; i++)
            slot[perm[i]] = (uint32_t)i;
        if (2 * mean_offset(s, slot) < mean_offset(s, NULL)) {
            st = plan_build(s, slot, &q);
            if (st != PSYS_OK) {
                free(perm);
                free(slot);
                psys__springs_plan_free(&p);
                return st;
            }
            psys__springs_plan_free(&p);
            p = q;
            p.perm = perm;
            p.perm_n = m;
        } else {
            free(perm);
        }
        free(slot);
    }
    psys__springs_plan_free(s);
    s->perm = p.perm;
    s->perm_n = p.perm_n;
    s->run_lo = p.run_lo;
    s->run_off = p.run_off;
    s->run_len = p.run_len;
    s->run_k = p.run_k;
    s->run_uni = p.run_uni;
    s->pks = p.pks;
    s->pkd = p.pkd;
    s->prest = p.prest;
    s->pos = p.pos;
    s->nruns = p.nruns;
    s->max_off = p.max_off;
    s->plan_ok = true;
    s->plan_version = s->version;
    s->part_t = 0;
    return PSYS_OK;
}

/* The internal order extended to np particles (slot = particle beyond the
 * springs' largest index). */
static psys_status springs_cover(springs *s, size_t np)
{
    if (!s->perm || s->perm_n >= np)
        return PSYS_OK;
    if (np > UINT32_MAX)
        return PSYS_ERR_NOMEM;
    uint32_t *p = psys__realloc(s->perm, np, sizeof *p);
    if (!p)
        return PSYS_ERR_NOMEM;
    for (size_t i = s->perm_n; i < np; i++)
        p[i] = (uint32_t)i;
    s->perm = p;
    s->perm_n = np;
    return PSYS_OK;
}

/* The plan, and SoA scratch for the owner's particles (9 doubles each). */
psys_status psys__springs_prepare_fused(springs *s, size_t np, int *T)
{
    psys_status st = psys__springs_plan(s);
    if (st != PSYS_OK)
        return st;
    if (*T > 1) {
        psys__springs_partition(s, np, *T);
        if (!s->part_ok)
            *T = 1;
    }
    return psys__springs_prepare_rings(s, np, *T);
}

psys_status psys__springs_prepare_rings(springs *s, size_t np, int T)
{
    psys_status st = psys__springs_plan(s);
    if (st == PSYS_OK)
        st = springs_cover(s, np);
    if (st != PSYS_OK)
        return st;
    /* A window holds a block of first particles, its runs' length and the
     * largest offset (see fast/fused.c); never more than all particles. */
    size_t need = s->max_off + 2 * SPRING_BLOCK, W = 1;
    while (W < need && W < np)
        W *= 2;
    if (W > s->ring_w || T > s->ring_t) {
        size_t w = W > s->ring_w ? W : s->ring_w;
        int t = T > s->ring_t ? T : s->ring_t;
        /* on cache lines: the fused loops read and write whole lines at
         * slots that are multiples of 8 (fast/fused_kernels.h, run_pair) */
        double *ring = psys__calloc_lines((size_t)t * 9, psys__springs_ring_stride(w) * sizeof(double));
        if (!ring)
            return PSYS_ERR_NOMEM;
        free(s->ring);
        s->ring = ring;
        s->ring_w = w;
        s->ring_t = t;
    }
    return PSYS_OK;
}

psys_status psys__springs_prepare_stage(springs *s, size_t len)
{
    if (len <= s->stage_len)
        return PSYS_OK;
    double *p = psys__calloc_lines(1, len * sizeof(double));
    if (!p)
        return PSYS_ERR_NOMEM;
    free(s->stage);
    s->stage = p;
    s->stage_len = len;
    return PSYS_OK;
}

psys_status psys__springs_prepare(void *set)
{
    springs *s = set;
    size_t np = s->owner ? s->owner->n : 0;
    psys_status st = psys__springs_plan(s);
    if (st == PSYS_OK)
        st = springs_cover(s, np);
    if (st != PSYS_OK)
        return st;
    if (np > s->soa_cap) {
        size_t cap = (np + np / 8 + 7) & ~(size_t)7; /* rows on cache lines (run_forces_d) */
        if (cap > SIZE_MAX / (9 * sizeof(double)))
            return PSYS_ERR_NOMEM;
        double *soa = psys__calloc_lines(cap * 9, sizeof(double));
        if (!soa)
            return PSYS_ERR_NOMEM;
        free(s->soa);
        s->soa = soa;
        s->soa_cap = cap;
    }
    return PSYS_OK;
}

/* The order in which springs_apply adds each particle's spring forces:
 * run by run, in a run the first ends before the second (any thread count).
 * Row i of (rowptr, ent) lists particle i's contributions in that order,
 * entry 2k for spring k's lower-index end (which gets -F) and 2k + 1 for its
 * higher one (+F). rowptr: np + 1 entries, ent: 2·count; seq (2·count)
 * gets each entry's place in the whole sequence of additions. */
psys_status psys__springs_order(void *set, size_t np, size_t *rowptr, uint32_t *ent, uint64_t *seq)
{
    springs *s = set;
    psys_status st = psys__springs_plan(s);
    if (st != PSYS_OK)
        return st;
    size_t *k_of = psys__calloc(s->n ? s->n : 1, sizeof *k_of); /* plan slot -> spring */
    if (!k_of)
        return PSYS_ERR_NOMEM;
    for (size_t k = 0; k < s->n; k++)
        k_of[s->pos[k]] = k;
    memset(rowptr, 0, (np + 1) * sizeof *rowptr);
    for (size_t k = 0; k < s->n; k++) {
        if (s->a[k] >= np || s->b[k] >= np) {
            free(k_of);
            return PSYS_ERR_INVALID;
        }
        rowptr[s->a[k] + 1]++;
        rowptr[s->b[k] + 1]++;
    }
    for (size_t i = 0; i < np; i++)
        rowptr[i + 1] += rowptr[i];
    uint64_t place = 0;
    for (size_t r = 0; r < s->nruns; r++) {
        const size_t lo = s->run_lo[r], hi = lo + s->run_off[r], len = s->run_len[r], k = s->run_k[r];
        for (int end = 0; end < 2; end++)
            for (size_t j = 0; j < len; j++) {
                /* the entry's parity names the end by particle index (in an
                 * internal order the lower slot may hold the higher index) */
                const size_t kk = k_of[k + j], p = psys__springs_particle(s, (end ? hi : lo) + j);
                const size_t e = 2 * kk + (p == (s->a[kk] > s->b[kk] ? s->a[kk] : s->b[kk]));
                ent[rowptr[p]++] = (uint32_t)e;
                seq[e] = place++;
            }
    }
    for (size_t i = np; i > 0; i--) /* the fill advanced each row start to the next row's */
        rowptr[i] = rowptr[i - 1];
    rowptr[0] = 0;
    free(k_of);
    return PSYS_OK;
}

/* Thread owning particle p (p >= psys__part_first(np, T, t) exactly when t <= this). */
static int part_owner(size_t p, size_t np, int T) { return (int)((uint64_t)p * (uint64_t)T / (uint64_t)np); }

/* Thread t walks the runs rlo[t]..rhi[t]-1: all the runs with an end in its
 * share of the particles. Each particle's force is written by its owner
 * only, with its contributions in plan order: results do not depend on T. */
void psys__springs_partition(springs *s, size_t np, int T)
{
    if (s->part_t == T && s->part_version == s->plan_version && s->part_np == np)
        return;
    for (int t = 0; t < T; t++) {
        s->rlo[t] = SIZE_MAX;
        s->rhi[t] = 0;
    }
    for (size_t r = 0; r < s->nruns; r++) {
        size_t ends[2] = {s->run_lo[r], (size_t)s->run_lo[r] + s->run_off[r]};
        for (int z = 0; z < 2; z++) {
            int t0 = part_owner(ends[z], np, T), t1 = part_owner(ends[z] + s->run_len[r] - 1, np, T);
            for (int t = t0; t <= t1; t++) {
                if (r < s->rlo[t])
                    s->rlo[t] = r;
                if (r + 1 > s->rhi[t])
                    s->rhi[t] = r + 1;
            }
        }
    }
    size_t walked = 0;
    for (int t = 0; t < T; t++) {
        if (s->rlo[t] > s->rhi[t])
            s->rlo[t] = s->rhi[t] = 0;
        walked += s->rhi[t] - s->rlo[t];
    }
    s->part_ok = walked <= s->nruns + s->nruns / 4; /* overlaps cost at most a quarter more */
    s->part_t = T;
    s->part_version = s->plan_version;
    s->part_np = np;
}
