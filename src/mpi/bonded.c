/* Bonded forces across the ranks of a domain decomposition (docs/mpi.md
 * "Bonded forces"): springs and behaviour functions whose particles sit on
 * different ranks. Compiled only with -DPSYS_MPI=ON.
 *
 * A term is one spring or one behaviour. Owner rule: each term is computed
 * once, by the rank that owns its particle of lowest global index; that
 * rank holds the term's other particles as ghosts (the ghost range covers
 * the longest term) and sends the forces on the particles other ranks own
 * to those ranks (the reverse exchange, after the halo exchange, before the
 * force objects run). Every rank then adds to each particle it owns the
 * contributions of its terms in the order the serial force loop adds them
 * (psys__springs_order; a behaviour's particles in turn), at the place of
 * the bonded force object among the others. The term forces are the same
 * bits as the serial ones (the same operations), and so are the sums.
 *
 * Speed: the springs a rank computes are grouped into runs of consecutive
 * local particles at both ends (a cloth's rows), so their loop vectorises
 * with contiguous loads; the additions follow the serial loop's sequence,
 * so they walk the force array in long runs too.
 *
 * The tables of the whole system (terms, and each particle's contributions
 * in serial order) are built once, from the scene every rank loaded; the
 * local ones at every redistribution. */
#include "mpi/bonded.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define BOND_TAG 7302
#define MAXQ (PSYS_BEHAVIOR_MAX_PARTICLES * 3)

typedef struct bond_obj {
    const psys_force_class *cls; /* the whole system's object's class */
    psys__terms_kind kind;
    size_t g_index; /* its index among the whole system's force objects */
    void *data;     /* this rank's copy: a spring set or a behaviour */
    size_t term0;   /* its first term */
} bond_obj;

struct psys__bonds {
    int dim;
    size_t n; /* particles of the whole system */
    size_t nobj;
    bond_obj *obj;
    /* terms of the whole system: term t has the slots end0[t]..end0[t+1]-1,
     * slot s for particle ends[s] (a spring's lower index first) */
    size_t nterm, nslot;
    size_t *end0, *ends, *slot_term;
    uint32_t *term_obj;
    unsigned char *lead; /* the slot, within term t, of its lowest-index particle */
    /* each particle's slots in the order the serial run adds them, and each
     * slot's place in its object's whole sequence of additions */
    size_t *prow, *pslot;
    uint64_t *seqpos;
    /* this rank's terms, after psys__bonds_localize */
    bool local_ok;
    size_t nlt, ltcap, *lterm; /* increasing global index */
    size_t lccap;
    unsigned char *lcomp;      /* 1: this rank computes term u */
    size_t l0cap, *lslot0;     /* nlt + 1: local slots of term u */
    size_t nls, lscap, *lpart; /* local particle of each local slot */
    size_t Ccap;
    double *C; /* nls·dim: the force of each local slot */
    size_t ncomp;
    /* the springs this rank computes, in term order: ends (local), first
     * local slot, parameters; muscles' rest lengths updated per evaluation */
    size_t nsp, spcap;
    uint32_t *sp_a, *sp_b; /* spring j's slots are 2j and 2j + 1 */
    /* runs of springs whose ends are consecutive particles here: springs
     * j0 + i join a0 + i and b0 + i, i < len (contiguous loads, so the loop
     * vectorises without gathers) */
    size_t nrun, runcap;
    uint32_t *run_j, *run_a, *run_b, *run_len;
    double *sp_ks, *sp_kd, *sp_rest;
    size_t nmus, muscap, *mus_j, *mus_k, *mus_o;
    size_t nbh, bhcap, *bh_u; /* the behaviours it computes (local terms) */
    /* object o adds C[gslot[j]] to particle gpart[j], j in gptr[o]..gptr[o+1]-1 */
    size_t *gptr, gcap, gscap;
    uint32_t *gpart, *gslot;
    struct gather_entry *gent; /* scratch for sorting them */
    size_t gecap;
    /* reverse exchange: local slots sent to, received from each rank */
    int size;
    int *scount, *rcount;
    size_t *soff, *roff;
    size_t sscap, rscap, *sslot, *rslot;
    size_t sbcap, rbcap;
    double *sbuf, *rbuf;
    MPI_Request *req;
    MPI_Status *stat;
};

/* One addition of the gather lists, with its place in the serial sequence. */
struct gather_entry {
    uint64_t obj, seq;
    size_t part, slot;
};

/* The local system's force object standing for bonded object `obj`. */
typedef struct bond_force {
    const psys__bonds *B;
    size_t obj;
} bond_force;

bool psys__bonds_takes(const psys_force_class *c)
{
    return (c->traits & PSYS_FORCE_BONDED) && c->terms && c->clone && c->destroy;
}

void psys__bonds_free(psys__bonds *B)
{
    if (!B)
        return;
    for (size_t o = 0; o < B->nobj; o++)
        if (B->obj[o].data)
            B->obj[o].cls->destroy(B->obj[o].data);
    free(B->obj);
    free(B->end0);
    free(B->ends);
    free(B->slot_term);
    free(B->term_obj);
    free(B->lead);
    free(B->prow);
    free(B->pslot);
    free(B->seqpos);
    free(B->gent);
    free(B->lterm);
    free(B->lcomp);
    free(B->lslot0);
    free(B->lpart);
    free(B->sp_a);
    free(B->sp_b);
    free(B->sp_ks);
    free(B->sp_kd);
    free(B->sp_rest);
    free(B->run_j);
    free(B->run_a);
    free(B->run_b);
    free(B->run_len);
    free(B->mus_j);
    free(B->mus_k);
    free(B->mus_o);
    free(B->bh_u);
    free(B->C);
    free(B->gptr);
    free(B->gpart);
    free(B->gslot);
    free(B->scount);
    free(B->rcount);
    free(B->soff);
    free(B->roff);
    free(B->sslot);
    free(B->rslot);
    free(B->sbuf);
    free(B->rbuf);
    free(B->req);
    free(B->stat);
    free(B);
}

/* The terms of every bonded object, and each particle's slots in the
 * serial order (object by object, in each as the serial loop adds them). */
static psys_status build_tables(psys__bonds *B, const psys_system *g)
{
    size_t t = 0, sl = 0, oi = 0;
    for (size_t k = 0; k < g->nforces; k++) {
        const psys_force_class *c = g->forces[k].cls;
        if (!psys__bonds_takes(c))
            continue;
        bond_obj *o = &B->obj[oi];
        o->g_index = k;
        o->term0 = t;
        o->cls = c;
        o->kind = c->terms->kind;
        if (!(o->data = c->clone(g->forces[k].data)))
            return PSYS_ERR_NOMEM;
        if (o->kind == PSYS__TERMS_SPRINGS) {
            for (size_t q = 0; q < psys__springs_count(o->data); q++, t++) {
                size_t a, b;
                psys__springs_get(o->data, q, &a, &b, NULL, NULL, NULL);
                B->end0[t] = sl;
                B->ends[sl] = a < b ? a : b;
                B->ends[sl + 1] = a < b ? b : a;
                B->slot_term[sl] = B->slot_term[sl + 1] = t;
                B->term_obj[t] = (uint32_t)oi;
                B->lead[t] = 0;
                sl += 2;
            }
        } else {
            int cnt = psys__behavior_count(o->data), lead = 0;
            B->end0[t] = sl;
            for (int i = 0; i < cnt; i++) {
                B->ends[sl + (size_t)i] = psys__behavior_particle(o->data, i);
                B->slot_term[sl + (size_t)i] = t;
                if (B->ends[sl + (size_t)i] < B->ends[sl + (size_t)lead])
                    lead = i;
            }
            B->term_obj[t] = (uint32_t)oi;
            B->lead[t] = (unsigned char)lead;
            sl += (size_t)cnt;
            t++;
        }
        oi++;
    }
    B->end0[t] = sl;
    /* rows: counted, then filled object by object */
    const size_t n = B->n;
    for (size_t s = 0; s < B->nslot; s++)
        B->prow[B->ends[s] + 1]++;
    for (size_t i = 0; i < n; i++)
        B->prow[i + 1] += B->prow[i];
    size_t *fill = psys__calloc(n + 1, sizeof *fill), *rowptr = NULL;
    uint32_t *ent = NULL;
    uint64_t *seq = NULL;
    if (!fill)
        return PSYS_ERR_NOMEM;
    memcpy(fill, B->prow, (n + 1) * sizeof *fill);
    psys_status st = PSYS_OK;
    for (size_t o = 0; o < B->nobj && st == PSYS_OK; o++) {
        const bond_obj *ob = &B->obj[o];
        if (ob->kind == PSYS__TERMS_BEHAVIOR) {
            const size_t t0 = ob->term0;
            for (size_t s = B->end0[t0]; s < B->end0[t0 + 1]; s++) {
                B->pslot[fill[B->ends[s]]++] = s;
                B->seqpos[s] = s - B->end0[t0];
            }
            continue;
        }
        const size_t S = psys__springs_count(ob->data);
        free(rowptr);
        free(ent);
        free(seq);
        rowptr = psys__calloc(n + 1, sizeof *rowptr);
        ent = psys__calloc(2 * S + 1, sizeof *ent);
        seq = psys__calloc(2 * S + 1, sizeof *seq);
        if (!rowptr || !ent || !seq) {
            st = PSYS_ERR_NOMEM;
            break;
        }
        st = psys__springs_order(ob->data, n, rowptr, ent, seq);
        for (size_t e = 0; e < 2 * S && st == PSYS_OK; e++)
            B->seqpos[B->end0[ob->term0 + (e >> 1)] + (e & 1)] = seq[e];
        for (size_t i = 0; i < n && st == PSYS_OK; i++)
            for (size_t e = rowptr[i]; e < rowptr[i + 1]; e++)
                B->pslot[fill[i]++] = B->end0[ob->term0 + (ent[e] >> 1)] + (ent[e] & 1);
    }
    free(fill);
    free(rowptr);
    free(ent);
    free(seq);
    return st;
}

psys_status psys__bonds_create(const psys_system *g, psys__bonds **out)
{
    *out = NULL;
    size_t nobj = 0, nterm = 0, nslot = 0;
    for (size_t k = 0; k < g->nforces; k++) {
        const psys_force_class *c = g->forces[k].cls;
        if (!psys__bonds_takes(c))
            continue;
        nobj++;
        if (c->terms->kind == PSYS__TERMS_SPRINGS) {
            size_t S = psys__springs_count(g->forces[k].data);
            nterm += S;
            nslot += 2 * S;
        } else {
            nterm++;
            nslot += (size_t)psys__behavior_count(g->forces[k].data);
        }
    }
    if (!nobj)
        return PSYS_OK;
    psys__bonds *B = calloc(1, sizeof *B);
    if (!B)
        return PSYS_ERR_NOMEM;
    B->dim = g->dim;
    B->n = g->n;
    B->nobj = nobj;
    B->nterm = nterm;
    B->nslot = nslot;
    B->obj = psys__calloc(nobj, sizeof *B->obj);
    B->end0 = psys__calloc(nterm + 1, sizeof *B->end0);
    B->ends = psys__calloc(nslot + 1, sizeof *B->ends);
    B->slot_term = psys__calloc(nslot + 1, sizeof *B->slot_term);
    B->term_obj = psys__calloc(nterm + 1, sizeof *B->term_obj);
    B->lead = psys__calloc(nterm + 1, 1);
    B->prow = psys__calloc(g->n + 1, sizeof *B->prow);
    B->pslot = psys__calloc(nslot + 1, sizeof *B->pslot);
    B->seqpos = psys__calloc(nslot + 1, sizeof *B->seqpos);
    B->gptr = psys__calloc(nobj + 1, sizeof *B->gptr);
    if (!B->obj || !B->end0 || !B->ends || !B->slot_term || !B->term_obj || !B->lead || !B->prow || !B->pslot
        || !B->seqpos || !B->gptr || build_tables(B, g) != PSYS_OK) {
        psys__bonds_free(B);
        return PSYS_ERR_NOMEM;
    }
    *out = B;
    return PSYS_OK;
}

/* ---- the local force objects ---- */

/* Each owned particle gets its contributions of this object, in serial order. */
static inline void bond_apply_d(const psys__bonds *B, size_t obj, double *restrict f, const int d)
{
    const uint32_t *restrict part = B->gpart, *restrict slot = B->gslot;
    const double *restrict C = B->C;
    for (size_t j = B->gptr[obj]; j < B->gptr[obj + 1]; j++) {
        double *fi = f + (size_t)part[j] * (size_t)d;
        const double *c = C + (size_t)slot[j] * (size_t)d;
        fi[0] += c[0];
        fi[1] += c[1];
        if (d == 3)
            fi[2] += c[2];
    }
}

static void bond_apply(void *data, const psys_force_eval *e, double *f)
{
    const bond_force *bf = data;
    if (!bf->B->local_ok)
        return;
    if (e->dim == 2)
        bond_apply_d(bf->B, bf->obj, f, 2);
    else
        bond_apply_d(bf->B, bf->obj, f, 3);
}

static const psys_force_class bond_class = {.name = "bonded-mpi", .apply = bond_apply, .destroy = free};

psys_status psys__bonds_add_force(psys__bonds *B, psys_system *local, size_t k)
{
    for (size_t o = 0; o < B->nobj; o++) {
        if (B->obj[o].g_index != k)
            continue;
        bond_force *bf = malloc(sizeof *bf);
        if (!bf)
            return PSYS_ERR_NOMEM;
        bf->B = B;
        bf->obj = o;
        return psys_system_add_force(local, &bond_class, bf); /* frees bf on failure */
    }
    return PSYS_ERR_INVALID;
}

/* Particles of term t. */
static size_t arity(const psys__bonds *B, size_t t) { return B->end0[t + 1] - B->end0[t]; }

/* ---- extents ---- */

/* Largest extent along any axis of the particles part[s0..s1) index into x. */
static double slots_extent(int d, const double *x, const size_t *part, size_t s0, size_t s1)
{
    double ext = 0;
    for (int q = 0; q < d; q++) {
        double lo = INFINITY, hi = -INFINITY;
        for (size_t s = s0; s < s1; s++) {
            double c = x[part[s] * (size_t)d + (size_t)q];
            lo = c < lo ? c : lo;
            hi = c > hi ? c : hi;
        }
        if (hi - lo > ext)
            ext = hi - lo;
    }
    return ext;
}

double psys__bonds_extent_all(const psys__bonds *B, const double *x)
{
    double ext = 0;
    for (size_t t = 0; t < B->nterm; t++) {
        double e = slots_extent(B->dim, x, B->ends, B->end0[t], B->end0[t + 1]);
        ext = e > ext || e != e ? e : ext; /* NaN stays: every particle a ghost */
    }
    return ext;
}

double psys__bonds_extent(const psys__bonds *B, const double *x)
{
    double ext = 0;
    if (!B->local_ok)
        return 0;
    for (size_t u = 0; u < B->nlt; u++)
        if (B->lcomp[u]) {
            double e = slots_extent(B->dim, x, B->lpart, B->lslot0[u], B->lslot0[u] + arity(B, B->lterm[u]));
            ext = e > ext || e != e ? e : ext;
        }
    return ext;
}

/* ---- the local terms ---- */

static int cmp_size(const void *a, const void *b)
{
    size_t x = *(const size_t *)a, y = *(const size_t *)b;
    return x < y ? -1 : x > y;
}

static int by_sequence(const void *a, const void *b)
{
    const struct gather_entry *x = a, *y = b;
    if (x->obj != y->obj)
        return x->obj < y->obj ? -1 : 1;
    return (x->seq > y->seq) - (x->seq < y->seq);
}

/* Index of v in the increasing a[0..n), or n. */
static size_t find(const size_t *a, size_t n, size_t v)
{
    size_t lo = 0, hi = n;
    while (lo < hi) {
        size_t mid = lo + (hi - lo) / 2;
        if (a[mid] < v)
            lo = mid + 1;
        else
            hi = mid;
    }
    return lo < n && a[lo] == v ? lo : n;
}

#define GROW(field, cap, want)                                                  \
    do {                                                                        \
        void *grown_ = psys__grow(B->field, &(cap), (want), sizeof *B->field);        \
        if (!grown_)                                                            \
            return -1;                                                          \
        B->field = grown_;                                                      \
    } while (0)

int psys__bonds_localize(psys__bonds *B, size_t nloc, const size_t *gid, const unsigned char *own, const int *owner,
                         int rank, int size)
{
    const size_t d = (size_t)B->dim;
    B->local_ok = false;
    if (nloc > UINT32_MAX || B->nslot > UINT32_MAX)
        return -1; /* the loops' indices are 32-bit */
    if (B->size != size) {
        free(B->scount);
        free(B->rcount);
        free(B->soff);
        free(B->roff);
        free(B->req);
        free(B->stat);
        B->size = size;
        B->scount = psys__calloc((size_t)size, sizeof *B->scount);
        B->rcount = psys__calloc((size_t)size, sizeof *B->rcount);
        B->soff = psys__calloc((size_t)size + 1, sizeof *B->soff);
        B->roff = psys__calloc((size_t)size + 1, sizeof *B->roff);
        B->req = psys__calloc(2 * (size_t)size, sizeof *B->req);
        B->stat = psys__calloc(2 * (size_t)size, sizeof *B->stat);
        if (!B->scount || !B->rcount || !B->soff || !B->roff || !B->req || !B->stat) {
            B->size = 0;
            return -1;
        }
    }
    /* the terms with an owned particle */
    size_t cnt = 0;
    for (size_t i = 0; i < nloc; i++)
        if (own[i])
            cnt += B->prow[gid[i] + 1] - B->prow[gid[i]];
    GROW(lterm, B->ltcap, cnt + 1);
    GROW(gpart, B->gcap, cnt + 1);
    GROW(gslot, B->gscap, cnt + 1);
    size_t m = 0;
    for (size_t i = 0; i < nloc; i++)
        if (own[i])
            for (size_t e = B->prow[gid[i]]; e < B->prow[gid[i] + 1]; e++)
                B->lterm[m++] = B->slot_term[B->pslot[e]];
    qsort(B->lterm, m, sizeof *B->lterm, cmp_size);
    size_t nlt = 0;
    for (size_t j = 0; j < m; j++)
        if (nlt == 0 || B->lterm[nlt - 1] != B->lterm[j])
            B->lterm[nlt++] = B->lterm[j];
    B->nlt = nlt;
    /* their slots and particles here */
    size_t nls = 0;
    for (size_t u = 0; u < nlt; u++)
        nls += B->end0[B->lterm[u] + 1] - B->end0[B->lterm[u]];
    GROW(lslot0, B->l0cap, nlt + 1);
    GROW(lcomp, B->lccap, nlt + 1);
    GROW(lpart, B->lscap, nls + 1);
    GROW(C, B->Ccap, (nls + 1) * d);
    B->nls = nls;
    /* which terms this rank computes; then their slots: the springs it
     * computes first (spring j at slots 2j, 2j + 1, so the spring loop
     * writes C in order), then the behaviours it computes, then the rest */
    B->ncomp = 0;
    for (size_t u = 0; u < nlt; u++) {
        const size_t t = B->lterm[u], li = find(gid, nloc, B->ends[B->end0[t] + B->lead[t]]);
        if (li == nloc)
            return 0; /* a particle of the term is not on this rank */
        B->lcomp[u] = owner[li] == rank;
        B->ncomp += B->lcomp[u];
    }
    size_t ls = 0;
    for (int group = 0; group < 3; group++)
        for (size_t u = 0; u < nlt; u++) {
            const size_t t = B->lterm[u];
            const bool spring = B->obj[B->term_obj[t]].kind == PSYS__TERMS_SPRINGS;
            if (group != (!B->lcomp[u] ? 2 : spring ? 0 : 1))
                continue;
            B->lslot0[u] = ls;
            for (size_t s = B->end0[t]; s < B->end0[t + 1]; s++) {
                size_t li = find(gid, nloc, B->ends[s]);
                if (li == nloc)
                    return 0;
                B->lpart[ls++] = li;
            }
        }
    /* the terms this rank computes, as flat lists */
    size_t cs = 0, cb = 0, cm = 0;
    for (size_t u = 0; u < nlt; u++)
        if (B->lcomp[u]) {
            const bond_obj *o = &B->obj[B->term_obj[B->lterm[u]]];
            if (o->kind == PSYS__TERMS_BEHAVIOR)
                cb++;
            else {
                cs++;
                cm += psys__springs_muscle(o->data, B->lterm[u] - o->term0, NULL, NULL, NULL);
            }
        }
    /* arrays sharing one capacity: each grows from the old one to the same
     * new one, which is stored only once all have grown */
    size_t cap = B->spcap;
    GROW(sp_a, cap, cs + 1);
    cap = B->spcap;
    GROW(sp_b, cap, cs + 1);
    cap = B->spcap;
    GROW(sp_ks, cap, cs + 1);
    cap = B->spcap;
    GROW(sp_kd, cap, cs + 1);
    cap = B->spcap;
    GROW(sp_rest, cap, cs + 1);
    B->spcap = cap;
    cap = B->muscap;
    GROW(mus_j, cap, cm + 1);
    cap = B->muscap;
    GROW(mus_k, cap, cm + 1);
    cap = B->muscap;
    GROW(mus_o, cap, cm + 1);
    B->muscap = cap;
    GROW(bh_u, B->bhcap, cb + 1);
    B->nsp = B->nmus = B->nbh = 0;
    for (size_t u = 0; u < nlt; u++) {
        if (!B->lcomp[u])
            continue;
        const size_t t = B->lterm[u], s0 = B->lslot0[u];
        const bond_obj *o = &B->obj[B->term_obj[t]];
        if (o->kind == PSYS__TERMS_BEHAVIOR) {
            B->bh_u[B->nbh++] = u;
            continue;
        }
        const size_t k = t - o->term0, j = B->nsp++;
        B->sp_a[j] = (uint32_t)B->lpart[s0];
        B->sp_b[j] = (uint32_t)B->lpart[s0 + 1];
        psys__springs_get(o->data, k, NULL, NULL, &B->sp_ks[j], &B->sp_kd[j], &B->sp_rest[j]);
        if (psys__springs_muscle(o->data, k, NULL, NULL, NULL)) {
            B->mus_j[B->nmus] = j;
            B->mus_k[B->nmus] = k;
            B->mus_o[B->nmus++] = B->term_obj[t];
        }
    }
    size_t nr = 0;
    for (size_t j = 0; j < B->nsp; j++)
        nr += j == 0 || B->sp_a[j] != B->sp_a[j - 1] + 1 || B->sp_b[j] != B->sp_b[j - 1] + 1;
    cap = B->runcap;
    GROW(run_j, cap, nr + 1);
    cap = B->runcap;
    GROW(run_a, cap, nr + 1);
    cap = B->runcap;
    GROW(run_b, cap, nr + 1);
    cap = B->runcap;
    GROW(run_len, cap, nr + 1);
    B->runcap = cap;
    B->nrun = 0;
    for (size_t j = 0; j < B->nsp; j++) {
        if (j == 0 || B->sp_a[j] != B->sp_a[j - 1] + 1 || B->sp_b[j] != B->sp_b[j - 1] + 1) {
            B->run_j[B->nrun] = (uint32_t)j;
            B->run_a[B->nrun] = B->sp_a[j];
            B->run_b[B->nrun] = B->sp_b[j];
            B->run_len[B->nrun++] = 0;
        }
        B->run_len[B->nrun - 1]++;
    }
    /* the gather lists, object by object, in the serial loop's sequence of
     * additions (so each particle gets its contributions in serial order,
     * and the lists walk C and f in long runs, as the serial loop does) */
    GROW(gent, B->gecap, cnt + 1);
    size_t ng = 0;
    for (size_t i = 0; i < nloc; i++)
        if (own[i])
            for (size_t e = B->prow[gid[i]]; e < B->prow[gid[i] + 1]; e++) {
                const size_t s = B->pslot[e], t = B->slot_term[s], u = find(B->lterm, nlt, t);
                struct gather_entry *g = &B->gent[ng++];
                g->obj = B->term_obj[t];
                g->seq = B->seqpos[s];
                g->part = i;
                g->slot = B->lslot0[u] + (s - B->end0[t]);
            }
    qsort(B->gent, ng, sizeof *B->gent, by_sequence);
    memset(B->gptr, 0, (B->nobj + 1) * sizeof *B->gptr);
    for (size_t j = 0; j < ng; j++) {
        B->gptr[B->gent[j].obj + 1]++;
        B->gpart[j] = (uint32_t)B->gent[j].part;
        B->gslot[j] = (uint32_t)B->gent[j].slot;
    }
    for (size_t o = 0; o < B->nobj; o++)
        B->gptr[o + 1] += B->gptr[o];
    /* the reverse exchange: both sides walk the terms in increasing global
     * index and their slots in order */
    for (int r = 0; r < size; r++)
        B->scount[r] = B->rcount[r] = 0;
    for (int pass = 0; pass < 2; pass++) {
        if (pass == 1) {
            B->soff[0] = B->roff[0] = 0;
            for (int r = 0; r < size; r++) {
                B->soff[r + 1] = B->soff[r] + (size_t)B->scount[r];
                B->roff[r + 1] = B->roff[r] + (size_t)B->rcount[r];
                B->scount[r] = B->rcount[r] = 0;
            }
            GROW(sslot, B->sscap, B->soff[size] + 1);
            GROW(rslot, B->rscap, B->roff[size] + 1);
            GROW(sbuf, B->sbcap, (B->soff[size] + 1) * d);
            GROW(rbuf, B->rbcap, (B->roff[size] + 1) * d);
        }
        for (size_t u = 0; u < nlt; u++) {
            const size_t s0 = B->lslot0[u], s1 = s0 + arity(B, B->lterm[u]);
            const int by = owner[B->lpart[s0 + B->lead[B->lterm[u]]]];
            for (size_t s = s0; s < s1; s++) {
                const size_t p = B->lpart[s];
                if (B->lcomp[u] && owner[p] != rank) {
                    if (pass == 1)
                        B->sslot[B->soff[owner[p]] + (size_t)B->scount[owner[p]]] = s;
                    B->scount[owner[p]]++;
                } else if (!B->lcomp[u] && own[p]) {
                    if (pass == 1)
                        B->rslot[B->roff[by] + (size_t)B->rcount[by]] = s;
                    B->rcount[by]++;
                }
            }
        }
    }
    B->local_ok = true;
    return 1;
}

/* The springs this rank computes into C, run by run: -F on the first
 * (lower-index) end's slot, F on the second, F = mag·l with l = x_a - x_b
 * (the serial loop's operations in its order, psys__spring_mag). */
static inline void springs_batch_d(const psys__bonds *B, const double *restrict x, const double *restrict v,
                                   double *restrict C, const int d)
{
    for (size_t r = 0; r < B->nrun; r++) {
        const size_t j0 = B->run_j[r], n = B->run_len[r];
        const double *restrict xa = x + (size_t)B->run_a[r] * (size_t)d, *restrict xb = x + (size_t)B->run_b[r] * (size_t)d;
        const double *restrict va = v + (size_t)B->run_a[r] * (size_t)d, *restrict vb = v + (size_t)B->run_b[r] * (size_t)d;
        const double *restrict ks = B->sp_ks + j0, *restrict kd = B->sp_kd + j0, *restrict rest = B->sp_rest + j0;
        double *restrict c = C + 2 * j0 * (size_t)d;
        for (size_t i = 0; i < n; i++) {
            const size_t p = i * (size_t)d;
            double l0 = xa[p] - xb[p], l1 = xa[p + 1] - xb[p + 1], l2 = 0;
            double d0 = va[p] - vb[p], d1 = va[p + 1] - vb[p + 1];
            double len2 = l0 * l0 + l1 * l1, dot = d0 * l0 + d1 * l1;
            if (d == 3) {
                l2 = xa[p + 2] - xb[p + 2];
                double d2 = va[p + 2] - vb[p + 2];
                len2 = len2 + l2 * l2;
                dot = dot + d2 * l2;
            }
            double mag = psys__spring_mag(ks[i], kd[i], rest[i], len2, dot);
            double *ci = c + 2 * p; /* f + (-F): the same bits as the serial f - F */
            ci[0] = -(mag * l0);
            ci[1] = -(mag * l1);
            ci[d] = mag * l0;
            ci[d + 1] = mag * l1;
            if (d == 3) {
                ci[2] = -(mag * l2);
                ci[5] = mag * l2;
            }
        }
    }
}

#if defined(__GNUC__) && !defined(__clang__) && defined(__x86_64__) && defined(__linux__)
__attribute__((target_clones("avx512f", "avx2", "default")))
#endif
static void springs_batch(const psys__bonds *B, const double *x, const double *v, double *C)
{
    if (B->dim == 2)
        springs_batch_d(B, x, v, C, 2);
    else
        springs_batch_d(B, x, v, C, 3);
}

int psys__bonds_evaluate(psys__bonds *B, MPI_Comm comm, double t, const double *y, size_t nloc)
{
    if (!B->local_ok)
        return -1;
    const int d = B->dim;
    const size_t ud = (size_t)d;
    const double *x = y, *v = y + nloc * ud;
    for (size_t m = 0; m < B->nmus; m++)
        B->sp_rest[B->mus_j[m]] = psys__springs_rest_at(B->obj[B->mus_o[m]].data, B->mus_k[m], t);
    springs_batch(B, x, v, B->C);
    for (size_t q = 0; q < B->nbh; q++) {
        const size_t u = B->bh_u[q], T = B->lterm[u], s0 = B->lslot0[u];
        const bond_obj *o = &B->obj[B->term_obj[T]];
        double xs[MAXQ], vs[MAXQ];
        const size_t k = arity(B, T);
        for (size_t i = 0; i < k; i++) {
            memcpy(xs + i * ud, x + B->lpart[s0 + i] * ud, ud * sizeof(double));
            memcpy(vs + i * ud, v + B->lpart[s0 + i] * ud, ud * sizeof(double));
        }
        psys__behavior_forces(o->data, xs, vs, B->C + s0 * ud);
    }
    int nreq = 0;
    for (int r = 0; r < B->size; r++)
        if (B->rcount[r] > 0
            && MPI_Irecv(B->rbuf + B->roff[r] * ud, B->rcount[r] * d, MPI_DOUBLE, r, BOND_TAG, comm, &B->req[nreq++])
                   != MPI_SUCCESS)
            return -1;
    for (int r = 0; r < B->size; r++) {
        if (B->scount[r] == 0)
            continue;
        for (size_t j = B->soff[r]; j < B->soff[r + 1]; j++)
            memcpy(B->sbuf + j * ud, B->C + B->sslot[j] * ud, ud * sizeof(double));
        if (MPI_Isend(B->sbuf + B->soff[r] * ud, B->scount[r] * d, MPI_DOUBLE, r, BOND_TAG, comm, &B->req[nreq++])
            != MPI_SUCCESS)
            return -1;
    }
    if (nreq && MPI_Waitall(nreq, B->req, B->stat) != MPI_SUCCESS)
        return -1;
    for (size_t j = 0; j < B->roff[B->size]; j++)
        memcpy(B->C + B->rslot[j] * ud, B->rbuf + j * ud, ud * sizeof(double));
    return 0;
}

size_t psys__bonds_owned_terms(const psys__bonds *B) { return B ? B->ncomp : 0; }
size_t psys__bonds_sent(const psys__bonds *B) { return B && B->size ? B->soff[B->size] : 0; }
